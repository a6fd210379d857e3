// The deferred sun lighting pass: Lambert on a cone, a moving sun against fresh renders, thread
// count, sky and bad depths, the slow twin, the haze recomposed, per-level mean normals.
#include "ig/lighting_pass.hpp"
#include "common/cone_map.hpp"
#include "ig/appearance.hpp"
#include "ig/caster.hpp"
#include "ig/cli.hpp"
#include "ig/error.hpp"
#include "ig/frame_stream.hpp"
#include "ig/image_compare.hpp"
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

TerrainMap cone(int n, double slope, double peak, ig::Rgb8 color) {
    return vig_test::coneMap(n, slope, peak, color);
}

std::shared_ptr<ig::SunLighting> lightingOf(const TerrainMap& map, const ig::Sun& sun,
                                            double azimuthRate = 0.0) {
    auto l = std::make_shared<ig::SunLighting>();
    l->normals = std::make_shared<const ig::TerrainNormals>(map);
    l->clock.sun = sun;
    l->clock.azimuthRate = azimuthRate;
    return l;
}

glm::dvec3 hitPoint(const ig::Camera& camera, const ig::RenderedFrame& f, std::size_t i) {
    const int w = f.width();
    const glm::dvec3 dir = glm::normalize(
        camera.rayDirection(static_cast<double>(i % w) + 0.5, static_cast<double>(i / w) + 0.5));
    return camera.pose().position + dir * static_cast<double>(f.depth[i]);
}

TEST(LightingPass, ConeMatchesLambertAndItsBrightSideFacesTheSun) {
    const int n = 201;
    const double slope = 0.5, peak = 60.0, c = 0.5 * (n - 1);
    const TerrainMap map = cone(n, slope, peak, ig::Rgb8{200, 200, 200});
    const ig::Sun sun{ig::degToRad(70.0), ig::degToRad(35.0)};
    const glm::dvec3 s = ig::sunDirection(sun);
    const double ambient = 0.3;
    ig::RenderOptions options;
    options.lighting = lightingOf(map, sun);
    const ig::Pose pose{{c, c, 400.0}, 0.0, ig::degToRad(-90.0), 0.0};
    const ig::Intrinsics in = ig::Intrinsics::fromFov(96, 96, ig::degToRad(30.0));
    const ig::Camera camera(pose, in);
    for (const auto kind : {ig::CasterKind::Reference, ig::CasterKind::Fast}) {
        SCOPED_TRACE(std::string(ig::casterName(kind)));
        const auto caster = ig::makeCaster(kind, map, options);
        const ig::RenderedFrame f = ig::renderFrame(*caster, map, pose, in);
        int checked = 0;
        std::size_t best = f.color.size();
        for (std::size_t i = 0; i < f.color.size(); ++i) {
            if (!std::isfinite(f.depth[i])) continue;
            if (best == f.color.size() || f.color[i].r > f.color[best].r) best = i;
            const glm::dvec3 p = hitPoint(camera, f, i);
            const double dx = p.x - c, dy = p.y - c, r = std::hypot(dx, dy);
            // On the flank, away from the apex and the foot (where the normals straddle a kink).
            if (r < 5.0 || r > peak / slope - 5.0) continue;
            const glm::dvec3 normal =
                glm::normalize(glm::dvec3{slope * dx / r, slope * dy / r, 1.0});
            const double light = ambient + (1.0 - ambient) * std::max(0.0, glm::dot(normal, s));
            EXPECT_NEAR(f.color[i].r / 200.0, light, 0.01 * light) << "at " << p.x << ", " << p.y;
            ++checked;
        }
        EXPECT_GT(checked, 1500);
        ASSERT_LT(best, f.color.size());
        const glm::dvec3 p = hitPoint(camera, f, best);
        const glm::dvec2 outward = glm::normalize(glm::dvec2{p.x - c, p.y - c});
        const glm::dvec2 toSun = glm::normalize(glm::dvec2{s.x, s.y});
        EXPECT_GT(glm::dot(outward, toSun), 0.95) << "brightest at " << p.x << ", " << p.y;
    }
}

// A view over a synthetic map with haze and every level, as flythrough renders it.
struct Scene {
    TerrainMap map = ig::makeSyntheticTerrain(256, 7, 30.0);
    ig::Pose pose;
    ig::Intrinsics in = ig::Intrinsics::fromFov(160, 108, ig::degToRad(60.0), 8);
    Scene() {
        pose.position = {1000.0, 900.0, map.maxHeight() + 150.0};
        pose.yaw = ig::degToRad(40.0);
        pose.pitch = ig::degToRad(-12.0);
    }
    ig::RenderOptions options(std::shared_ptr<const ig::SunLighting> lighting) const {
        ig::RenderOptions o;
        o.levels = ig::kLevelsAuto;
        o.sky.hazeDistance = 2500.0;
        o.lighting = std::move(lighting);
        return o;
    }
};

TEST(LightingPass, MovingSunEqualsAFreshRenderWithThatSun) {
    const Scene scene;
    const ig::Sun start{ig::degToRad(100.0), ig::degToRad(25.0)};
    const auto moving = lightingOf(scene.map, start, ig::degToRad(3.0));
    const auto caster = ig::makeCaster(ig::CasterKind::Fast, scene.map, scene.options(moving));
    const ig::RenderedFrame atZero = ig::renderFrame(*caster, scene.map, scene.pose, scene.in, 0.0);
    const ig::RenderedFrame later = ig::renderFrame(*caster, scene.map, scene.pose, scene.in, 20.0);
    // The sun turned 60 degrees: a different image from the same caster, nothing rebuilt.
    EXPECT_NE(atZero.color, later.color);
    const ig::Sun turned = moving->clock.at(20.0);
    EXPECT_NEAR(turned.azimuth, ig::degToRad(160.0), 1e-9);
    const auto fixed = lightingOf(scene.map, turned);
    const auto fresh = ig::makeCaster(ig::CasterKind::Fast, scene.map, scene.options(fixed));
    const ig::RenderedFrame again = ig::renderFrame(*fresh, scene.map, scene.pose, scene.in, 0.0);
    EXPECT_EQ(later.color, again.color);
    EXPECT_EQ(later.depth, again.depth);
}

TEST(LightingPass, ImageDoesNotDependOnThreadCountOrFrameStream) {
    const Scene scene;
    const auto lighting = lightingOf(scene.map, ig::Sun{ig::degToRad(200.0), ig::degToRad(15.0)});
    ig::RenderOptions one = scene.options(lighting), two = one;
    one.threads = 1;
    two.threads = 2;
    const auto a = ig::makeCaster(ig::CasterKind::Fast, scene.map, one);
    const auto b = ig::makeCaster(ig::CasterKind::Fast, scene.map, two);
    const ig::RenderedFrame fa = ig::renderFrame(*a, scene.map, scene.pose, scene.in);
    const ig::RenderedFrame fb = ig::renderFrame(*b, scene.map, scene.pose, scene.in);
    EXPECT_EQ(fa.color, fb.color);
    // Units rendered by the stream, the pass once they are done: the same frame.
    ig::FrameStream stream(*b, scene.map, 1);
    stream.submit(scene.pose, scene.in);
    EXPECT_EQ(stream.take().color, fa.color);
}

TEST(LightingPass, SkyAndUnusableDepthsAreLeftAlone) {
    const Scene scene;
    const auto lighting = lightingOf(scene.map, ig::Sun{ig::degToRad(60.0), ig::degToRad(40.0)});
    const auto unlit = ig::makeCaster(ig::CasterKind::Fast, scene.map, scene.options(nullptr));
    const auto lit = ig::makeCaster(ig::CasterKind::Fast, scene.map, scene.options(lighting));
    const ig::RenderedFrame a = ig::renderFrame(*unlit, scene.map, scene.pose, scene.in);
    const ig::RenderedFrame b = ig::renderFrame(*lit, scene.map, scene.pose, scene.in);
    int sky = 0, changed = 0;
    for (std::size_t i = 0; i < a.color.size(); ++i) {
        if (std::isinf(a.depth[i])) {
            ++sky;
            ASSERT_EQ(a.color[i], b.color[i]) << "sky pixel " << i;
        } else {
            changed += a.color[i] != b.color[i];
        }
    }
    EXPECT_GT(sky, 100);
    EXPECT_GT(changed, 1000);

    // NaN, negative and infinite depths keep their colour; absurd finite ones are lit without
    // reading outside the map.
    ig::RenderedFrame f = a;
    const float bad[] = {std::numeric_limits<float>::quiet_NaN(), -5.0f,
                         std::numeric_limits<float>::infinity(),
                         -std::numeric_limits<float>::infinity()};
    for (std::size_t k = 0; k < 4; ++k)
        f.depth[k] = bad[k];
    f.depth[4] = 1e30f;
    f.depth[5] = std::numeric_limits<float>::max();
    const ig::Camera camera(scene.pose, scene.in);
    ig::lightFrame(*lighting, scene.options(nullptr).sky, ig::LevelBands{}, camera, f);
    for (std::size_t k = 0; k < 4; ++k)
        EXPECT_EQ(f.color[k], a.color[k]) << "depth " << bad[k];
}

TEST(LightingPass, MatchesItsSlowTwinAndLevelZeroNormalsNearby) {
    const Scene scene;
    const auto lighting = lightingOf(scene.map, ig::Sun{ig::degToRad(300.0), ig::degToRad(20.0)});
    const ig::RenderOptions o = scene.options(nullptr);
    const auto caster = ig::makeCaster(ig::CasterKind::Fast, scene.map, o);
    const ig::RenderedFrame unlit = ig::renderFrame(*caster, scene.map, scene.pose, scene.in);
    const ig::Camera camera(scene.pose, scene.in);
    const ig::LevelBands bands{scene.in.focal * 30.0, 6};
    ig::RenderedFrame fast = unlit, slow = unlit;
    ig::lightFrame(*lighting, o.sky, bands, camera, fast, 2);
    ig::lightFrameReference(*lighting, o.sky, bands, camera, slow);
    int differ = 0;
    for (std::size_t i = 0; i < fast.color.size(); ++i) {
        ASSERT_NEAR(fast.color[i].r, slow.color[i].r, 1) << i;
        ASSERT_NEAR(fast.color[i].g, slow.color[i].g, 1) << i;
        ASSERT_NEAR(fast.color[i].b, slow.color[i].b, 1) << i;
        differ += fast.color[i] != slow.color[i];
    }
    EXPECT_LT(differ, static_cast<int>(fast.color.size() / 50));
    // Within d0 of the eye the bands are level 0: the same light either way.
    auto zero = std::make_shared<ig::SunLighting>(*lighting);
    zero->levelZeroNormals = true;
    const ig::Sun sun = lighting->clock.at(0.0);
    for (double x = 100.0; x < 7000.0; x += 613.0) {
        EXPECT_EQ(ig::lightFactor(*lighting, bands, sun, x, 2000.0, 0.5 * bands.d0),
                  ig::lightFactor(*zero, bands, sun, x, 2000.0, 5e6));
    }
}

TEST(LightingPass, StereoRightEyeLightsThePixelsItCasts) {
    // A wide eye separation, so the second pass casts many pixels: those match a fully cast
    // (and lit) right eye, as the reprojected ones do.
    const Scene scene;
    const auto lighting = lightingOf(scene.map, ig::Sun{ig::degToRad(250.0), ig::degToRad(20.0)});
    const ig::RenderOptions o = scene.options(lighting);
    ig::StereoOptions so;
    so.eyeSeparation = 80.0;
    const ig::StereoFrame pair = ig::renderStereo(scene.map, scene.pose, scene.in, so, o);
    so.method = ig::RightEyeMethod::Raycast;
    const ig::StereoFrame full = ig::renderStereo(scene.map, scene.pose, scene.in, so, o);
    double sum = 0.0;
    int cast = 0;
    for (std::size_t i = 0; i < pair.right.color.size(); ++i) {
        if (pair.source[i] != ig::RightPixelSource::RayCast || !std::isfinite(pair.right.depth[i]))
            continue;
        ++cast;
        const ig::Rgb8 a = pair.right.color[i], b = full.right.color[i];
        sum += (std::abs(a.r - b.r) + std::abs(a.g - b.g) + std::abs(a.b - b.b)) / 3.0;
    }
    EXPECT_GT(cast, 100);
    EXPECT_LT(sum / cast, 4.0) << cast << " cast pixels";
}

TEST(LightingPass, HazeIsRecomposedExactly) {
    // A flat plane of albedo 200 under a white horizon, sun at 30 degrees: every pixel shows
    // 255 f + L 200 (1 - f), L = ambient + (1 - ambient) sin 30.
    TerrainMap map(257, 257, 20.0, 20.0, 1.0, 0.0);
    for (int iy = 0; iy < 257; ++iy)
        for (int ix = 0; ix < 257; ++ix)
            map.setColor(ix, iy, ig::Rgb8{200, 200, 200});
    map.updateRange();
    ig::RenderOptions o;
    o.sky.horizon = ig::Rgb8{255, 255, 255};
    o.sky.hazeDistance = 1500.0;
    o.lighting = lightingOf(map, ig::Sun{1.0, ig::degToRad(30.0)});
    const double light = 0.3 + 0.7 * 0.5;
    ig::Pose pose;
    pose.position = {2560.0, 1000.0, 400.0};
    pose.pitch = ig::degToRad(-25.0);
    const ig::Intrinsics in = ig::Intrinsics::fromFov(64, 48, ig::degToRad(60.0));
    for (const auto kind : {ig::CasterKind::Reference, ig::CasterKind::Fast}) {
        const auto caster = ig::makeCaster(kind, map, o);
        const ig::RenderedFrame f = ig::renderFrame(*caster, map, pose, in);
        int terrain = 0;
        for (std::size_t i = 0; i < f.color.size(); ++i) {
            const double d = f.depth[i];
            if (!std::isfinite(d)) continue;
            ++terrain;
            const double h = 1.0 - std::exp(-d / o.sky.hazeDistance);
            // The caster's rounding (half a level) scaled by L, and the pass's own.
            ASSERT_NEAR(f.color[i].r, 255.0 * h + light * 200.0 * (1.0 - h), 1.0) << i;
        }
        EXPECT_GT(terrain, 64 * 24);
    }
}

TEST(TerrainNormals, CoarseLevelsAreMeansOfTheFinerOnes) {
    const TerrainMap map = ig::makeSyntheticTerrain(64, 3, 25.0);
    const ig::TerrainNormals normals(map);
    ASSERT_GE(normals.levelCount(), 4);
    // Level 0: unit normals pointing up.
    for (int i = 0; i < 64 * 64; ++i) {
        const float* n = normals.samples(0) + 3 * i;
        ASSERT_NEAR(n[0] * n[0] + n[1] * n[1] + n[2] * n[2], 1.0, 1e-5);
        ASSERT_GT(n[2], 0.0f);
    }
    for (int k = 1; k < normals.levelCount(); ++k) {
        const int fw = normals.width(k - 1), fh = normals.height(k - 1);
        EXPECT_EQ(normals.width(k), (fw - 1 + 1) / 2 + 1);
        for (int j = 0; j < normals.height(k); j += 3) {
            for (int i = 0; i < normals.width(k); i += 3) {
                double m[3] = {0, 0, 0};
                for (int b = -1; b <= 1; ++b) {
                    for (int a = -1; a <= 1; ++a) {
                        const int x = std::clamp(2 * i + a, 0, fw - 1);
                        const int y = std::clamp(2 * j + b, 0, fh - 1);
                        const double wgt = (a == 0 ? 2.0 : 1.0) * (b == 0 ? 2.0 : 1.0) / 16.0;
                        for (int c = 0; c < 3; ++c)
                            m[c] += wgt * normals.samples(k - 1)[3 * (y * fw + x) + c];
                    }
                }
                const float* n = normals.samples(k) + 3 * (j * normals.width(k) + i);
                for (int c = 0; c < 3; ++c)
                    ASSERT_NEAR(n[c], m[c], 1e-5) << "level " << k;
                // A mean of unit vectors: no longer than one.
                ASSERT_LE(n[0] * n[0] + n[1] * n[1] + n[2] * n[2], 1.0 + 1e-5);
            }
        }
    }
}

TEST(SunRate, FlagsMoveTheSunWithTimeAndLightAtRenderTime) {
    TerrainMap map = ig::makeSyntheticTerrain(64, 1, 100.0);
    ig::TerrainOptions terrain;
    terrain.synthetic = "64:1";
    auto parse = [&](ig::AppearanceOptions o) { return ig::parseAppearance(o, terrain, map); };
    ig::AppearanceOptions o;
    o.sun = "90,30";
    o.sunRate = "2";
    const ig::Appearance a = parse(o);
    EXPECT_NEAR(a.sunClock.at(10.0).azimuth, ig::degToRad(110.0), 1e-12);
    EXPECT_NEAR(a.sunClock.at(10.0).elevation, ig::degToRad(30.0), 1e-12);
    EXPECT_NEAR(a.sunClock.at(-50.0).azimuth, ig::degToRad(350.0), 1e-12);
    // The almanac's clock: 15 degrees per second is an hour per second.
    ig::AppearanceOptions t;
    t.sunTime = "2024-06-21,16:00,46.88,-122.36";
    t.sunRate = "15";
    const ig::Appearance b = parse(t);
    const ig::Sun later = b.sunClock.at(2.0);
    const ig::Sun direct = ig::sunAt(46.88, -122.36, b.sunClock.days + 2.0 / 24.0);
    EXPECT_NEAR(later.azimuth, direct.azimuth, 1e-9);
    EXPECT_NEAR(later.elevation, direct.elevation, 1e-9);
    // Without --sun-rate the almanac runs in real time.
    t.sunRate.clear();
    EXPECT_DOUBLE_EQ(parse(t).sunClock.speed, 1.0);
    for (const std::string bad : {"x", "400", "nan"}) {
        ig::AppearanceOptions r = o;
        r.sunRate = bad;
        EXPECT_THROW(parse(r), ig::InputError) << bad;
    }
    ig::AppearanceOptions noSun;
    noSun.sunRate = "1";
    EXPECT_THROW(parse(noSun), ig::InputError);
    // Applied: the map holds the ramp's albedo and the options the lighting.
    ig::RenderOptions render;
    ig::applyAppearance(a, map, render);
    ASSERT_TRUE(render.lighting != nullptr);
    EXPECT_EQ(render.lighting->clock.azimuthRate, a.sunClock.azimuthRate);
    const auto ramp = ig::elevationRampAlbedo(map);
    EXPECT_TRUE(std::equal(ramp.begin(), ramp.end(), map.colors().begin()));
    // No lighting flag: no lighting.
    ig::RenderOptions plain;
    ig::applyAppearance(parse(ig::AppearanceOptions{}), map, plain);
    EXPECT_TRUE(plain.lighting == nullptr);
}

}  // namespace
