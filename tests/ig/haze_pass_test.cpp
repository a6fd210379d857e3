// Haze with a height fall-off, applied over the finished frame: the closed-form optical depth
// against quadrature (level rays included), a flat plane at known heights and distances in every
// caster, the slow twin, thread count, sky and bad depths, lighting, the stereo second pass.
#include "ig/haze_pass.hpp"
#include "ig/caster.hpp"
#include "ig/frame_stream.hpp"
#include "ig/lighting_pass.hpp"
#include "ig/stereo.hpp"
#include "ig/synthetic.hpp"

#include <gtest/gtest.h>
#include <glm/geometric.hpp>

#include <cmath>
#include <limits>
#include <memory>
#include <string>

namespace {

using ig::TerrainMap;

ig::SkyModel hazeSky(double distance, double falloff) {
    ig::SkyModel sky;
    sky.horizon = ig::Rgb8{255, 255, 255};
    sky.hazeDistance = distance;
    sky.hazeFalloff = falloff;
    return sky;
}

// A flat plane of one colour at height `z`, `n` x `n` samples.
TerrainMap flatPlane(int n, double spacing, double z, ig::Rgb8 color) {
    TerrainMap map(n, n, spacing, spacing, 1.0, z);
    for (int iy = 0; iy < n; ++iy)
        for (int ix = 0; ix < n; ++ix)
            map.setColor(ix, iy, color);
    map.updateRange();
    return map;
}

TEST(HazeFalloff, ClosedFormMatchesQuadratureAndTheLevelRayLimit) {
    for (const double h : {60.0, 400.0, 3000.0}) {
        const ig::SkyModel sky = hazeSky(1500.0, h);
        for (const double eyeZ : {-40.0, 0.0, 350.0, 2500.0}) {
            for (const double rise : {-2000.0, -300.0, -1.0, -1e-6, 0.0, 1e-6, 0.5, 150.0, 900.0}) {
                for (const double d : {3.0, 800.0, 6000.0}) {
                    if (std::abs(rise) > d) continue;
                    const double exact = ig::hazeOpticalDepth(sky, d, eyeZ, rise);
                    const double numeric = ig::hazeOpticalDepthNumeric(sky, d, eyeZ, rise, 4096);
                    ASSERT_TRUE(std::isfinite(exact));
                    ASSERT_NEAR(exact, numeric, 1e-9 + 1e-6 * numeric)
                        << "H " << h << " eye " << eyeZ << " rise " << rise << " d " << d;
                    const double f = ig::hazeFraction(sky, d, eyeZ, rise);
                    ASSERT_NEAR(f, 1.0 - std::exp(-numeric), 1e-4);
                }
            }
            // A level ray: exp(-z / H) d / D.
            EXPECT_NEAR(ig::hazeOpticalDepth(sky, 1000.0, eyeZ, 0.0),
                        std::exp(-eyeZ / h) * 1000.0 / 1500.0, 1e-12);
        }
    }
    // Where the series hands over to expm1 (|u| = 1e-4) both agree to rounding.
    for (const double u : {-1.01e-4, -0.99e-4, -1e-9, 1e-9, 0.99e-4, 1.01e-4}) {
        EXPECT_NEAR(ig::hazeRiseFactor(u), -std::expm1(-u) / u, 1e-13) << u;
        EXPECT_NEAR(ig::hazeRiseFactor(u), 1.0 - u / 2.0 + u * u / 6.0, 1e-13) << u;
    }
    EXPECT_EQ(ig::hazeRiseFactor(0.0), 1.0);
    // A scale height far above the scene is the plain distance haze; absurd heights stay
    // finite or +inf, never NaN.
    const ig::SkyModel thin = hazeSky(1500.0, 1e9);
    EXPECT_NEAR(ig::hazeFraction(thin, 1200.0, 300.0, -250.0), 1.0 - std::exp(-0.8), 1e-6);
    const ig::SkyModel steep = hazeSky(1500.0, 1.0);
    EXPECT_EQ(ig::hazeFraction(steep, 1e5, -1e5, 0.0), 1.0);
    EXPECT_FALSE(std::isnan(ig::hazeFraction(steep, 1e5, 1e5, -2e5)));
    EXPECT_EQ(ig::hazeFraction(steep, 0.0, 1e5, 0.0), 0.0);
}

TEST(HazeFalloff, FlatPlaneAtKnownHeightsBlendsToTheAnalyticFraction) {
    // Black ground at height zp, white horizon, eye at 600 m: the ray of direction (.., dz)
    // meets the plane at d = (ze - zp) / -dz and its optical depth is
    // H / (D (-dz)) (exp(-zp / H) - exp(-ze / H)).
    const double d0 = 1500.0, h = 400.0, ze = 600.0;
    const ig::SkyModel sky = hazeSky(d0, h);
    for (const double zp : {0.0, 250.0}) {
        const TerrainMap map = flatPlane(257, 20.0, zp, ig::Rgb8{0, 0, 0});
        ig::RenderOptions options;
        options.sky = sky;
        ig::Pose pose;
        pose.position = {2560.0, 1000.0, ze};
        pose.pitch = ig::degToRad(-25.0);
        const ig::Intrinsics in = ig::Intrinsics::fromFov(64, 48, ig::degToRad(60.0));
        const ig::Camera camera(pose, in);
        struct Case {
            ig::CasterKind kind;
            int levels;
        };
        for (const Case c :
             {Case{ig::CasterKind::Reference, 0}, Case{ig::CasterKind::Naive, 0},
              Case{ig::CasterKind::Fast, 0}, Case{ig::CasterKind::Fast, ig::kLevelsAuto}}) {
            ig::RenderOptions o = options;
            o.levels = c.levels;
            const auto caster = ig::makeCaster(c.kind, map, o);
            const ig::RenderedFrame f = ig::renderFrame(*caster, map, pose, in);
            SCOPED_TRACE(std::string(ig::casterName(c.kind)) + " levels " +
                         std::to_string(c.levels) + " plane at " + std::to_string(zp));
            int terrain = 0;
            double nearest = 1e30, farthest = 0.0;
            for (std::size_t i = 0; i < f.color.size(); ++i) {
                if (!std::isfinite(f.depth[i])) continue;
                const int x = static_cast<int>(i % 64), y = static_cast<int>(i / 64);
                const glm::dvec3 dir = glm::normalize(camera.rayDirection(x + 0.5, y + 0.5));
                ASSERT_LT(dir.z, 0.0);
                const double d = (ze - zp) / -dir.z;
                const double tau = h / (d0 * -dir.z) * (std::exp(-zp / h) - std::exp(-ze / h));
                const double fraction = 1.0 - std::exp(-tau);
                ++terrain;
                nearest = std::min(nearest, d);
                farthest = std::max(farthest, d);
                // The closed form at the plane's distance and height: the analytic fraction.
                ASSERT_NEAR(ig::hazeFraction(sky, d, ze, zp - ze), fraction, 1e-4) << i;
                // The image: one grey level (the 8-bit colour).
                ASSERT_NEAR(f.color[i].r, 255.0 * fraction, 1.0) << "pixel " << i << " at " << d;
                ASSERT_EQ(f.color[i].r, f.color[i].g);
                ASSERT_EQ(f.color[i].r, f.color[i].b);
            }
            EXPECT_GT(terrain, 64 * 24);
            EXPECT_LT(nearest, 0.7 * d0);
            EXPECT_GT(farthest, 2.0 * d0);
        }
    }
    // The lower plane (a valley) is hazier at the same distance: the fall-off's point.
    const double level = 1000.0;
    EXPECT_GT(ig::hazeFraction(sky, level, ze, -ze), ig::hazeFraction(sky, level, ze, 250.0 - ze));
}

struct Scene {
    TerrainMap map = ig::makeSyntheticTerrain(256, 5, 20.0);
    ig::Pose pose;
    ig::Intrinsics in = ig::Intrinsics::fromFov(120, 80, ig::degToRad(60.0));
    Scene() {
        pose.position = {0.3 * map.extentX(), 0.2 * map.extentY(), map.maxHeight() + 150.0};
        pose.yaw = 0.6;
        pose.pitch = ig::degToRad(-8.0);
    }
};

TEST(HazeFalloff, PassIsTheCasterHazeMatchesItsSlowTwinAndIgnoresThreads) {
    const Scene scene;
    ig::RenderOptions plain, hazed;
    plain.sky = hazeSky(0.0, 0.0);  // the same sky colours, no haze
    hazed.sky = hazeSky(1200.0, 150.0);
    const ig::Camera camera(scene.pose, scene.in);
    const auto bare = ig::makeCaster(ig::CasterKind::Fast, scene.map, plain);
    const ig::RenderedFrame unhazed = ig::renderFrame(*bare, scene.map, scene.pose, scene.in);
    for (const int threads : {1, 3}) {
        ig::RenderOptions o = hazed;
        o.threads = threads;
        const auto caster = ig::makeCaster(ig::CasterKind::Fast, scene.map, o);
        const ig::RenderedFrame f = ig::renderFrame(*caster, scene.map, scene.pose, scene.in);
        // The caster draws no haze and the pass adds it: its image is the pass over the
        // unhazed frame, whatever the thread count.
        ig::RenderedFrame pass = unhazed;
        ig::hazeFrame(hazed.sky, camera, pass, threads);
        EXPECT_EQ(f.color, pass.color) << threads << " threads";
        EXPECT_EQ(f.depth, unhazed.depth);
        ig::FrameStream stream(*caster, scene.map, 1);
        stream.submit(scene.pose, scene.in);
        EXPECT_EQ(stream.take().color, f.color);
    }
    ig::RenderedFrame fast = unhazed, slow = unhazed;
    ig::hazeFrame(hazed.sky, camera, fast);
    ig::hazeFrameReference(hazed.sky, camera, slow);
    int changed = 0;
    for (std::size_t i = 0; i < fast.color.size(); ++i) {
        ASSERT_NEAR(fast.color[i].r, slow.color[i].r, 1) << i;
        ASSERT_NEAR(fast.color[i].g, slow.color[i].g, 1) << i;
        ASSERT_NEAR(fast.color[i].b, slow.color[i].b, 1) << i;
        changed += fast.color[i] != unhazed.color[i];
    }
    EXPECT_GT(changed, 1000);
}

TEST(HazeFalloff, SkyAndUnusableDepthsAreLeftAloneAndZeroIsOff) {
    const Scene scene;
    const auto caster = ig::makeCaster(ig::CasterKind::Fast, scene.map, ig::RenderOptions{});
    const ig::RenderedFrame a = ig::renderFrame(*caster, scene.map, scene.pose, scene.in);
    ig::RenderedFrame f = a;
    const float bad[] = {std::numeric_limits<float>::quiet_NaN(), -5.0f,
                         std::numeric_limits<float>::infinity(),
                         -std::numeric_limits<float>::infinity()};
    for (std::size_t k = 0; k < 4; ++k)
        f.depth[k] = bad[k];
    f.depth[4] = std::numeric_limits<float>::max();
    const ig::Camera camera(scene.pose, scene.in);
    ig::hazeFrame(hazeSky(1000.0, 200.0), camera, f);
    int sky = 0;
    for (std::size_t i = 0; i < f.color.size(); ++i) {
        if (i < 4 || (i > 4 && std::isinf(a.depth[i]))) {
            sky += i > 4;
            ASSERT_EQ(f.color[i], a.color[i]) << "pixel " << i;
        }
    }
    EXPECT_GT(sky, 100);
    EXPECT_EQ(f.color[4], (ig::Rgb8{255, 255, 255}));  // an absurd distance: all haze
    // Fall-off 0 (or haze off): no pass, the frame as it was.
    ig::RenderedFrame g = a;
    ig::hazeFrame(hazeSky(1000.0, 0.0), camera, g);
    ig::hazeFrame(hazeSky(0.0, 200.0), camera, g);
    EXPECT_EQ(g.color, a.color);
}

TEST(HazeFalloff, AHighScaleHeightIsThePlainHaze) {
    // The deferred pass with H far above the scene against the casters' own distance haze.
    const Scene scene;
    ig::RenderOptions plain, deferred;
    plain.sky = hazeSky(1200.0, 0.0);
    deferred.sky = hazeSky(1200.0, 1e9);
    for (const auto kind : {ig::CasterKind::Reference, ig::CasterKind::Fast}) {
        const auto a = ig::makeCaster(kind, scene.map, plain);
        const auto b = ig::makeCaster(kind, scene.map, deferred);
        const ig::RenderedFrame fa = ig::renderFrame(*a, scene.map, scene.pose, scene.in);
        const ig::RenderedFrame fb = ig::renderFrame(*b, scene.map, scene.pose, scene.in);
        for (std::size_t i = 0; i < fa.color.size(); ++i) {
            // The caster rounds the albedo, then the pass rounds the blend.
            ASSERT_NEAR(fa.color[i].r, fb.color[i].r, 1) << i;
            ASSERT_NEAR(fa.color[i].g, fb.color[i].g, 1) << i;
            ASSERT_NEAR(fa.color[i].b, fb.color[i].b, 1) << i;
        }
    }
}

TEST(HazeFalloff, LitPlaneIsLitThenHazed) {
    // Albedo 200, sun at 30 degrees, on a plane at 100 m: 255 g + L 200 (1 - g).
    const double zp = 100.0, ze = 500.0;
    const TerrainMap map = flatPlane(257, 20.0, zp, ig::Rgb8{200, 200, 200});
    ig::RenderOptions o;
    o.sky = hazeSky(1500.0, 300.0);
    auto lighting = std::make_shared<ig::SunLighting>();
    lighting->normals = std::make_shared<const ig::TerrainNormals>(map);
    lighting->clock.sun = ig::Sun{1.0, ig::degToRad(30.0)};
    o.lighting = lighting;
    const double light = 0.3 + 0.7 * 0.5;
    ig::Pose pose;
    pose.position = {2560.0, 1000.0, ze};
    pose.pitch = ig::degToRad(-25.0);
    const ig::Intrinsics in = ig::Intrinsics::fromFov(64, 48, ig::degToRad(60.0));
    const ig::Camera camera(pose, in);
    for (const auto kind : {ig::CasterKind::Reference, ig::CasterKind::Fast}) {
        const auto caster = ig::makeCaster(kind, map, o);
        const ig::RenderedFrame f = ig::renderFrame(*caster, map, pose, in);
        int terrain = 0;
        for (std::size_t i = 0; i < f.color.size(); ++i) {
            if (!std::isfinite(f.depth[i])) continue;
            ++terrain;
            const glm::dvec3 dir = glm::normalize(camera.rayDirection(
                static_cast<double>(i % 64) + 0.5, static_cast<double>(i / 64) + 0.5));
            const double g = ig::hazeFraction(o.sky, f.depth[i], ze, f.depth[i] * dir.z);
            // The light's rounding and the haze pass's (a level each).
            ASSERT_NEAR(f.color[i].r, 255.0 * g + light * 200.0 * (1.0 - g), 1.5) << i;
        }
        EXPECT_GT(terrain, 64 * 24);
    }
}

TEST(HazeFalloff, StereoRightEyeHazesThePixelsItCasts) {
    // A wide eye separation, so the second pass casts many pixels: those match a fully cast
    // right eye (hazed by its own pass), as the reprojected ones do.
    const Scene scene;
    ig::RenderOptions o;
    o.sky = hazeSky(900.0, 120.0);
    ig::StereoOptions so;
    so.eyeSeparation = 80.0;
    const ig::StereoFrame pair = ig::renderStereo(scene.map, scene.pose, scene.in, so, o);
    so.method = ig::RightEyeMethod::Raycast;
    const ig::StereoFrame full = ig::renderStereo(scene.map, scene.pose, scene.in, so, o);
    ig::RenderOptions bareOptions;
    bareOptions.sky = hazeSky(0.0, 0.0);
    const ig::StereoFrame bare = ig::renderStereo(scene.map, scene.pose, scene.in, so, bareOptions);
    double sum = 0.0, hazeSum = 0.0;
    int cast = 0;
    for (std::size_t i = 0; i < pair.right.color.size(); ++i) {
        if (pair.source[i] != ig::RightPixelSource::RayCast || !std::isfinite(pair.right.depth[i]))
            continue;
        ++cast;
        const ig::Rgb8 a = pair.right.color[i], b = full.right.color[i], c = bare.right.color[i];
        sum += (std::abs(a.r - b.r) + std::abs(a.g - b.g) + std::abs(a.b - b.b)) / 3.0;
        hazeSum += (std::abs(c.r - b.r) + std::abs(c.g - b.g) + std::abs(c.b - b.b)) / 3.0;
    }
    EXPECT_GT(cast, 100);
    EXPECT_LT(sum / cast, 4.0) << cast << " cast pixels";
    EXPECT_GT(hazeSum / cast, 3.0 * (sum / cast + 1.0)) << "the haze is visible in those pixels";
}

}  // namespace
