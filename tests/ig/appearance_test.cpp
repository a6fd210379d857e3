// Appearance: distance haze in every caster, sun lighting (Lambert on a cone), the sun's
// position, supersampling chosen from the pitch, and the shared flags.
#include "ig/appearance.hpp"
#include "common/cone_map.hpp"
#include "ig/caster.hpp"
#include "ig/cli.hpp"
#include "ig/error.hpp"
#include "ig/image_compare.hpp"
#include "ig/synthetic.hpp"

#include <gtest/gtest.h>
#include <glm/geometric.hpp>

#include <cmath>
#include <limits>
#include <numbers>
#include <string>
#include <vector>

namespace {

using ig::TerrainMap;

// A flat plane at height 0, one colour, `n` x `n` samples.
TerrainMap flatPlane(int n, double spacing, ig::Rgb8 color) {
    TerrainMap map(n, n, spacing, spacing, 1.0, 0.0);
    for (int iy = 0; iy < n; ++iy)
        for (int ix = 0; ix < n; ++ix)
            map.setColor(ix, iy, color);
    map.updateRange();
    return map;
}

TEST(Haze, FlatPlaneBlendsToTheStatedFractionInEveryCaster) {
    // Black ground, white horizon: a pixel at distance d shows 255 * (1 - exp(-d / D)).
    const TerrainMap map = flatPlane(257, 20.0, ig::Rgb8{0, 0, 0});
    ig::RenderOptions options;
    options.sky.horizon = ig::Rgb8{255, 255, 255};
    options.sky.hazeDistance = 1500.0;
    ig::Pose pose;
    pose.position = {2560.0, 1000.0, 400.0};
    pose.pitch = ig::degToRad(-25.0);
    const ig::Intrinsics in = ig::Intrinsics::fromFov(64, 48, ig::degToRad(60.0));
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
        SCOPED_TRACE(std::string(ig::casterName(c.kind)) + " levels " + std::to_string(c.levels));
        int terrain = 0;
        double nearest = 1e30, farthest = 0.0;
        for (std::size_t i = 0; i < f.color.size(); ++i) {
            const double d = f.depth[i];
            if (!std::isfinite(d)) continue;
            ++terrain;
            nearest = std::min(nearest, d);
            farthest = std::max(farthest, d);
            const double expected = 255.0 * (1.0 - std::exp(-d / options.sky.hazeDistance));
            ASSERT_NEAR(f.color[i].r, expected, 1.0) << "pixel " << i << " at " << d << " m";
            ASSERT_EQ(f.color[i].r, f.color[i].g);
            ASSERT_EQ(f.color[i].r, f.color[i].b);
        }
        EXPECT_GT(terrain, 64 * 24);
        // The view spans distances on both sides of the haze distance.
        EXPECT_LT(nearest, 0.7 * options.sky.hazeDistance);
        EXPECT_GT(farthest, 1.5 * options.sky.hazeDistance);
    }
}

TEST(Haze, AtTheHazeDistanceTheBlendIs63Percent) {
    // Straight down from 1000 m with the haze distance 1000 m: the centre shows 1 - 1/e.
    const TerrainMap map = flatPlane(65, 10.0, ig::Rgb8{0, 0, 0});
    ig::RenderOptions o;
    o.sky.horizon = ig::Rgb8{255, 255, 255};
    o.sky.hazeDistance = 1000.0;
    ig::Pose pose;
    pose.position = {320.0, 320.0, 1000.0};
    pose.pitch = ig::degToRad(-90.0);
    const ig::Intrinsics in = ig::Intrinsics::fromFov(8, 8, ig::degToRad(1.0));
    for (const auto kind : {ig::CasterKind::Reference, ig::CasterKind::Fast}) {
        const auto caster = ig::makeCaster(kind, map, o);
        const ig::RenderedFrame f = ig::renderFrame(*caster, map, pose, in);
        EXPECT_NEAR(f.color[4 * 8 + 4].r, 255.0 * (1.0 - std::exp(-1.0)), 1.0);
    }
    // Off: the plane's own colour.
    o.sky.hazeDistance = 0.0;
    const auto caster = ig::makeCaster(ig::CasterKind::Fast, map, o);
    EXPECT_EQ(ig::renderFrame(*caster, map, pose, in).color[4 * 8 + 4], (ig::Rgb8{0, 0, 0}));
}

TerrainMap cone(int n, double slope, double peak) {
    return vig_test::coneMap(n, slope, peak);
}

TEST(Sun, ConeMatchesLambertWithinOnePercent) {
    const int n = 201;
    const double slope = 0.5, peak = 60.0, c = 0.5 * (n - 1);
    TerrainMap map = cone(n, slope, peak);
    const ig::Sun sun{ig::degToRad(70.0), ig::degToRad(35.0)};
    const glm::dvec3 s = ig::sunDirection(sun);
    const double ambient = 0.3;
    const ig::TerrainLighting lighting(map, ig::TerrainLighting::Albedo::Photo, ambient);
    lighting.relight(map, sun);
    const double flat = ambient + (1.0 - ambient) * s.z;
    int checked = 0;
    for (int iy = 0; iy < n; iy += 3) {
        for (int ix = 0; ix < n; ix += 3) {
            const double dx = ix - c, dy = iy - c, r = std::hypot(dx, dy);
            // On the flank, away from the apex and the foot (where the stencil straddles a kink).
            if (r < 5.0 || r > peak / slope - 5.0) continue;
            const glm::dvec3 normal =
                glm::normalize(glm::dvec3{slope * dx / r, slope * dy / r, 1.0});
            const double light = ambient + (1.0 - ambient) * std::max(0.0, glm::dot(normal, s));
            EXPECT_NEAR(lighting.light(ix, iy, sun), light, 0.01 * light);
            const double expected = std::min(255.0, 100.0 * light / flat);
            // The lit colour: within 1 % of full scale (8-bit rounding included).
            EXPECT_NEAR(map.colorAt(ix, iy).r, expected, 0.01 * 255.0);
            ++checked;
        }
    }
    EXPECT_GT(checked, 1000);

    // Seen from above by the reference caster: the brightest pixel lies on the flank facing the
    // sun.
    const ig::Pose pose{{c, c, 400.0}, 0.0, ig::degToRad(-90.0), 0.0};
    const ig::Intrinsics in = ig::Intrinsics::fromFov(96, 96, ig::degToRad(30.0));
    const auto caster = ig::makeCaster(ig::CasterKind::Reference, map);
    const ig::RenderedFrame f = ig::renderFrame(*caster, map, pose, in);
    std::size_t best = f.color.size();
    for (std::size_t i = 0; i < f.color.size(); ++i) {
        if (std::isfinite(f.depth[i]) && (best == f.color.size() || f.color[i].r > f.color[best].r))
            best = i;
    }
    ASSERT_LT(best, f.color.size());
    const ig::Camera camera(pose, in);
    const glm::dvec3 dir = glm::normalize(camera.rayDirection(
        static_cast<double>(best % 96) + 0.5, static_cast<double>(best / 96) + 0.5));
    const glm::dvec3 p = pose.position + dir * static_cast<double>(f.depth[best]);
    const glm::dvec2 outward = glm::normalize(glm::dvec2{p.x - c, p.y - c});
    const glm::dvec2 toSun = glm::normalize(glm::dvec2{s.x, s.y});
    EXPECT_GT(glm::dot(outward, toSun), 0.95) << "brightest at " << p.x << ", " << p.y;
}

TEST(Sun, RelightingAgainEqualsLightingAfresh) {
    TerrainMap a = ig::makeSyntheticTerrain(64, 5, 30.0);
    TerrainMap b = a;
    const ig::TerrainLighting lighting(a, ig::TerrainLighting::Albedo::Ramp);
    lighting.relight(a, ig::Sun{1.0, 0.3});
    lighting.relight(a, ig::Sun{4.0, 0.9});
    ig::TerrainLighting(b, ig::TerrainLighting::Albedo::Ramp).relight(b, ig::Sun{4.0, 0.9});
    EXPECT_TRUE(std::equal(a.colors().begin(), a.colors().end(), b.colors().begin()));
    // A different sun gives different colours.
    lighting.relight(b, ig::Sun{1.0, 0.3});
    EXPECT_FALSE(std::equal(a.colors().begin(), a.colors().end(), b.colors().begin()));
}

TEST(Sun, RampShowsWaterBlueAndPeaksWhite) {
    TerrainMap map(32, 32, 100.0, 100.0, 1.0, 0.0);
    for (int iy = 0; iy < 32; ++iy)
        for (int ix = 0; ix < 32; ++ix)
            map.setRaw(ix, iy, static_cast<std::uint16_t>(ix < 10 ? 0 : 150 * (ix - 9)));
    map.updateRange();
    const auto albedo = ig::elevationRampAlbedo(map);
    const ig::Rgb8 water = albedo[map.index(3, 16)], snow = albedo[map.index(31, 16)];
    EXPECT_GT(water.b, water.r + 40);
    EXPECT_GT(snow.r, 230);
    EXPECT_GT(snow.b, 230);
    // The first land sample is green, not water.
    const ig::Rgb8 land = albedo[map.index(11, 16)];
    EXPECT_GT(land.g, land.b);
}

TEST(SunPosition, MatchesKnownEphemerides) {
    // Greenwich, 2000-01-01 12:00 UTC: the sun due south at about 90 - 51.48 - 23.0 degrees.
    const ig::Sun noon = ig::sunAt(51.48, 0.0, 0.0);
    EXPECT_NEAR(ig::radToDeg(noon.azimuth), 180.0, 1.5);
    EXPECT_NEAR(ig::radToDeg(noon.elevation), 15.5, 0.3);
    // Equator at the March equinox 2024 (03-20 03:06 UTC), local noon at longitude -133.5
    // (12:00 local solar time = 20:54 UTC) ... near the zenith.
    const double days = ig::parseUtcDateTime("2024-03-20,20:54", "t");
    EXPECT_GT(ig::radToDeg(ig::sunAt(0.0, -133.5, days).elevation), 88.0);
    // Seattle, 2024-06-21 20:00 UTC (13:00 PDT): high in the south, about 64 degrees.
    const ig::Sun summer =
        ig::sunAt(47.6, -122.3, ig::parseUtcDateTime("2024-06-21,20:00:00", "t"));
    EXPECT_NEAR(ig::radToDeg(summer.elevation), 64.0, 2.0);
    EXPECT_GT(ig::radToDeg(summer.azimuth), 150.0);
    EXPECT_LT(ig::radToDeg(summer.azimuth), 215.0);
    // Midnight there: below the horizon.
    EXPECT_LT(ig::sunAt(47.6, -122.3, ig::parseUtcDateTime("2024-06-21,08:00", "t")).elevation,
              0.0);
    for (const char* bad : {"2024-02-30,12:00", "2023-02-29,12:00", "2024-13-01,00:00",
                            "2024-01-01,24:00", "2024-01-01", "yesterday", "2024-01-01,12:00x"}) {
        EXPECT_THROW(ig::parseUtcDateTime(bad, "--sun-time"), ig::InputError) << bad;
    }
}

TEST(AutoSupersample, OneRayAtSteepPitchMoreAtShallow) {
    const ig::Intrinsics in = ig::Intrinsics::fromFov(720, 486, ig::degToRad(60.0));
    auto rays = [&](double pitchDeg) {
        ig::Pose p;
        p.pitch = ig::degToRad(pitchDeg);
        return ig::autoSupersample(p, in, 8);
    };
    EXPECT_EQ(rays(-90.0), 1);
    EXPECT_EQ(rays(-60.0), 1);
    EXPECT_EQ(rays(-40.0), 1);
    EXPECT_GE(rays(-8.0), 2);
    EXPECT_GE(rays(0.0), rays(-8.0));
    // Nothing below the horizon: nothing to supersample.
    EXPECT_EQ(rays(60.0), 1);
    // The bottom row a hair below the horizon: an enormous stretch, capped; a NaN pitch: one.
    ig::Pose grazing;
    grazing.pitch = std::atan(0.5 * in.height / in.focal) - 1e-12;
    EXPECT_EQ(ig::autoSupersample(grazing, in, 8), 8);
    grazing.pitch = std::numeric_limits<double>::quiet_NaN();
    EXPECT_EQ(ig::autoSupersample(grazing, in, 8), 1);
    // Never more than asked.
    ig::Pose low;
    low.pitch = ig::degToRad(-1.0);
    EXPECT_EQ(ig::autoSupersample(low, in, 2), 2);
    // The stretch falls as the view steepens.
    double last = 1e30;
    for (double pitch = 0.0; pitch >= -90.0; pitch -= 5.0) {
        ig::Pose p;
        p.pitch = ig::degToRad(pitch);
        const double stretch = ig::footprintStretch(p, in);
        EXPECT_LE(stretch, last + 1e-9) << pitch;
        last = stretch;
    }
}

// Colour error (% of full scale) of the fast caster with `options` against a 4x4 supersampled
// render (the exact single level at 4x the size, box filtered) at the same pose.
double errorAgainst4x4(const TerrainMap& map, const ig::Pose& pose, ig::RenderOptions options,
                       std::uint64_t* rays) {
    const int w = 120, h = 80;
    const auto caster = ig::makeCaster(ig::CasterKind::Fast, map, options);
    const ig::RenderedFrame f =
        ig::renderFrame(*caster, map, pose, ig::Intrinsics::fromFov(w, h, ig::degToRad(60.0)));
    *rays = f.stats.rays;
    const auto refCaster = ig::makeCaster(ig::CasterKind::Fast, map);
    const ig::RenderedFrame r = ig::renderFrame(
        *refCaster, map, pose, ig::Intrinsics::fromFov(4 * w, 4 * h, ig::degToRad(60.0)));
    return ig::meanAbsErrorPct(f.color, ig::boxDownsample(r.color, w, h, 4));
}

TEST(AutoSupersample, BeatsOneRayAtShallowPitchAndCastsOneWhenSteep) {
    const TerrainMap map = ig::makeSyntheticTerrain(512, 11, 10.0);
    ig::Pose shallow = ig::defaultViewPose(map);
    shallow.pitch = ig::degToRad(-6.0);
    ig::RenderOptions one, autoRays;
    autoRays.supersample = ig::kSupersampleAuto;
    std::uint64_t raysOne = 0, raysAuto = 0;
    const double eOne = errorAgainst4x4(map, shallow, one, &raysOne);
    const double eAuto = errorAgainst4x4(map, shallow, autoRays, &raysAuto);
    std::printf("shallow pitch: 1 ray %.3f %%, auto (%.1f rays/pixel) %.3f %%\n", eOne,
                static_cast<double>(raysAuto) / (120 * 80), eAuto);
    EXPECT_GT(raysAuto, raysOne);
    EXPECT_LT(eAuto, eOne);

    ig::Pose steep = shallow;
    steep.pitch = ig::degToRad(-70.0);
    const double eSteep = errorAgainst4x4(map, steep, autoRays, &raysAuto);
    (void)eSteep;
    EXPECT_EQ(raysAuto, 120u * 80u);
}

TEST(AppearanceFlags, ParseAndRefuse) {
    const TerrainMap map = ig::makeSyntheticTerrain(64, 1, 100.0);
    ig::TerrainOptions terrain;
    terrain.synthetic = "64:1";
    auto parse = [&](ig::AppearanceOptions o) { return ig::parseAppearance(o, terrain, map); };
    ig::AppearanceOptions o;
    EXPECT_EQ(parse(o).hazeDistance, 0.0);
    EXPECT_EQ(parse(o).supersample, 1);
    EXPECT_FALSE(parse(o).sun.has_value());
    o.haze = "auto";
    EXPECT_DOUBLE_EQ(parse(o).hazeDistance, 0.25 * map.extentX());
    o.supersample = "auto:3";
    EXPECT_EQ(parse(o).supersample, ig::kSupersampleAuto);
    EXPECT_EQ(parse(o).supersampleMax, 3);
    o.sun = "90,30";
    const ig::Appearance lit = parse(o);
    ASSERT_TRUE(lit.sun.has_value());
    EXPECT_NEAR(lit.sun->azimuth, std::numbers::pi / 2, 1e-12);
    EXPECT_TRUE(lit.ramp);  // no colour image: the ramp
    for (const auto& [flag, value] :
         std::vector<std::pair<std::string, std::string>>{{"haze", "-1"},
                                                          {"haze", "far"},
                                                          {"supersample", "9"},
                                                          {"supersample", "auto:0"},
                                                          {"supersample", "autox"},
                                                          {"sun", "90"},
                                                          {"sun", "90,100"},
                                                          {"sun", "a,b"},
                                                          {"colors", "photo"},
                                                          {"sunTime", "2024-06-21,12:00"}}) {
        ig::AppearanceOptions bad;
        if (flag == "haze") bad.haze = value;
        if (flag == "supersample") bad.supersample = value;
        if (flag == "sun") bad.sun = value;
        if (flag == "colors") bad.colors = value;
        if (flag == "sunTime") bad.sunTime = value;  // this map's position is unknown
        EXPECT_THROW(parse(bad), ig::InputError) << flag << " " << value;
    }
    ig::AppearanceOptions shade;
    shade.shade = true;
    shade.sun = "90,30";
    EXPECT_THROW(parse(shade), ig::InputError);  // nothing to shade: no colour image
}

}  // namespace
