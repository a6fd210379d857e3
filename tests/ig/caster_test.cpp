// Casters on analytic scenes: closed-form depth, thin features, control points, bad poses.
#include "ig/caster.hpp"
#include "ig/error.hpp"
#include "ig/image_compare.hpp"

#include <gtest/gtest.h>
#include <glm/geometric.hpp>

#include <cmath>
#include <functional>

namespace {

using ig::CasterKind;
using ig::degToRad;
using ig::Intrinsics;
using ig::Pose;
using ig::TerrainMap;

constexpr CasterKind kAllCasters[] = {CasterKind::Reference, CasterKind::Naive, CasterKind::Fast};

// A map whose raw height at (ix, iy) is raw(ix, iy); colours vary so images are not flat.
TerrainMap makeMap(int n, double spacing, double scale, const std::function<int(int, int)>& raw) {
    TerrainMap map(n, n, spacing, spacing, scale, 0.0);
    for (int iy = 0; iy < n; ++iy) {
        for (int ix = 0; ix < n; ++ix) {
            map.setRaw(ix, iy, static_cast<std::uint16_t>(raw(ix, iy)));
            map.setColor(
                ix, iy,
                ig::Rgb8{static_cast<std::uint8_t>(ix * 7), static_cast<std::uint8_t>(iy * 5),
                         static_cast<std::uint8_t>((ix + iy) * 3)});
        }
    }
    map.updateRange();
    return map;
}

Pose makePose(double x, double y, double z, double yawDeg, double pitchDeg, double rollDeg = 0) {
    Pose p;
    p.position = {x, y, z};
    p.yaw = degToRad(yawDeg);
    p.pitch = degToRad(pitchDeg);
    p.roll = degToRad(rollDeg);
    return p;
}

// Plane z = c0 + cx * x + cy * y sampled exactly (the bilinear surface of a plane is the plane).
struct Plane {
    double c0, cx, cy;
};

void expectPlaneDepth(const TerrainMap& map, const Plane& plane, const Pose& pose,
                      CasterKind kind) {
    const Intrinsics in = Intrinsics::fromFov(96, 72, degToRad(70), 4);
    const auto caster = ig::makeCaster(kind, map);
    const ig::RenderedFrame frame = ig::renderFrame(*caster, map, pose, in);
    const ig::Camera cam(pose, in);
    int checked = 0;
    for (int y = 0; y < in.height; ++y) {
        for (int x = 0; x < in.width; ++x) {
            const glm::dvec3 d = glm::normalize(cam.rayDirection(x + 0.5, y + 0.5));
            const glm::dvec3 o = pose.position;
            const double denom = d.z - plane.cx * d.x - plane.cy * d.y;
            const double t = (plane.c0 + plane.cx * o.x + plane.cy * o.y - o.z) / denom;
            const float got = frame.depth[static_cast<std::size_t>(y) * in.width + x];
            if (!(t > 0.0) || denom >= 0.0) {
                continue;  // the plane is not in front of this ray
            }
            const glm::dvec3 p = o + t * d;
            const double margin = 2.0 * map.spacingX();
            if (p.x < margin || p.y < margin || p.x > map.extentX() - margin ||
                p.y > map.extentY() - margin) {
                continue;  // beyond the map's edge there is no terrain
            }
            ASSERT_NEAR(got, t, 1e-4 * t + 1e-3)
                << ig::casterName(kind) << " pixel " << x << "," << y;
            ++checked;
        }
    }
    EXPECT_GT(checked, 300) << "the plane must fill a good part of the view";
}

TEST(CasterAnalytic, FlatPlaneDepthIsClosedForm) {
    const TerrainMap map = makeMap(128, 10.0, 0.1, [](int, int) { return 1000; });  // z = 100 m
    for (CasterKind kind : kAllCasters) {
        for (double pitch : {-5.0, -30.0, -60.0, -89.0}) {
            expectPlaneDepth(map, {100.0, 0.0, 0.0}, makePose(600, 640, 250, 30, pitch), kind);
        }
    }
}

TEST(CasterAnalytic, TiltedPlaneDepthIsClosedForm) {
    // raw = 500 + 20 ix + 10 iy at 0.1 m per unit, 10 m spacing: z = 50 + 0.2 x + 0.1 y.
    const TerrainMap map =
        makeMap(128, 10.0, 0.1, [](int ix, int iy) { return 500 + 20 * ix + 10 * iy; });
    const Plane plane{50.0, 0.2, 0.1};
    for (CasterKind kind : kAllCasters) {
        for (double yaw : {0.0, 100.0, 225.0}) {
            for (double pitch : {-10.0, -45.0, -80.0}) {
                expectPlaneDepth(map, plane, makePose(640, 600, 600, yaw, pitch), kind);
            }
        }
    }
}

TEST(CasterAnalytic, OneCellSpikeIsNotSkippedAtSteepPitch) {
    // Flat ground at 0 with one sample raised 300 m.
    const TerrainMap map =
        makeMap(64, 10.0, 1.0, [](int ix, int iy) { return ix == 32 && iy == 32 ? 300 : 0; });
    const auto reference = ig::makeCaster(CasterKind::Reference, map);
    const auto fast = ig::makeCaster(CasterKind::Fast, map);
    const Intrinsics in = Intrinsics::fromFov(80, 60, degToRad(60), 0);
    int spikePixels = 0, missed = 0;
    for (double pitch : {-60.0, -75.0, -85.0, -90.0}) {
        for (double yaw : {0.0, 37.0, 135.0, 270.0}) {
            for (double dx : {-40.0, 0.0, 25.0}) {
                const Pose pose = makePose(320 + dx, 300, 500, yaw, pitch);
                const auto ref = ig::renderFrame(*reference, map, pose, in);
                const auto got = ig::renderFrame(*fast, map, pose, in);
                const ig::Camera cam(pose, in);
                for (std::size_t i = 0; i < ref.depth.size(); ++i) {
                    // A pixel sees the spike when it hits above the ground plane.
                    const int x = static_cast<int>(i % in.width),
                              y = static_cast<int>(i / in.width);
                    const glm::dvec3 d = glm::normalize(cam.rayDirection(x + 0.5, y + 0.5));
                    const double hitZ = pose.position.z + ref.depth[i] * d.z;
                    if (!std::isfinite(ref.depth[i]) || hitZ < 1.0) continue;
                    ++spikePixels;
                    if (std::abs(got.depth[i] - ref.depth[i]) > 0.01 * ref.depth[i]) {
                        ++missed;
                        ADD_FAILURE()
                            << "pitch " << pitch << " yaw " << yaw << " dx " << dx << " pixel " << x
                            << "," << y << " ref " << ref.depth[i] << " fast " << got.depth[i];
                    }
                }
            }
        }
    }
    EXPECT_GT(spikePixels, 200);
    EXPECT_EQ(missed, 0) << "of " << spikePixels << " spike pixels";
}

TEST(ControlPoints, WorldPointsReprojectOntoTheirPixels) {
    const TerrainMap map = makeMap(128, 10.0, 0.1, [](int ix, int iy) {
        return static_cast<int>(2000 + 800 * std::sin(ix * 0.1) * std::cos(iy * 0.13));
    });
    const auto caster = ig::makeCaster(CasterKind::Fast, map);
    const Intrinsics in = Intrinsics::fromFov(120, 90, degToRad(60), 10);
    for (double pitch : {5.0, -20.0, -70.0}) {
        const Pose pose = makePose(300, 200, 800, 20, pitch);
        const auto frame = ig::renderFrame(*caster, map, pose, in);
        const ig::Camera cam(pose, in);
        const auto pixels = ig::controlPointPixels(in);
        for (int i = 0; i < ig::kControlPointCount; ++i) {
            const auto& cp = frame.controlPoints[i];
            EXPECT_EQ(cp.pixel, pixels[i]);
            const auto q = cam.project(glm::dvec3(cp.world), cp.world.w);
            ASSERT_TRUE(q.has_value());
            EXPECT_NEAR(q->x, cp.pixel.x, 0.1);
            EXPECT_NEAR(q->y, cp.pixel.y, 0.1);
        }
    }
}

TEST(ControlPoints, SkyPointsAreDirections) {
    const TerrainMap map = makeMap(32, 10.0, 1.0, [](int, int) { return 0; });
    const auto caster = ig::makeCaster(CasterKind::Fast, map);
    const auto frame = ig::renderFrame(*caster, map, makePose(150, 150, 100, 0, 30),
                                       Intrinsics::fromFov(64, 48, degToRad(60)));
    for (int i = 0; i < 3; ++i) {  // the top row looks at the sky
        EXPECT_EQ(frame.controlPoints[i].world.w, 0.0);
        EXPECT_NEAR(glm::length(glm::dvec3(frame.controlPoints[i].world)), 1.0, 1e-12);
        EXPECT_TRUE(std::isinf(frame.depth[0]));
    }
}

TEST(CasterErrors, CameraBelowTheSurfaceIsRejected) {
    const TerrainMap map = makeMap(32, 10.0, 1.0, [](int, int) { return 50; });
    const auto caster = ig::makeCaster(CasterKind::Fast, map);
    const Intrinsics in = Intrinsics::fromFov(32, 24, degToRad(60));
    try {
        ig::renderFrame(*caster, map, makePose(100, 100, 20, 0, 0), in);
        FAIL() << "expected InputError";
    } catch (const ig::InputError& e) {
        EXPECT_NE(std::string(e.what()).find("below the terrain"), std::string::npos) << e.what();
    }
}

TEST(CasterErrors, NonFinitePoseIsRejected) {
    const TerrainMap map = makeMap(32, 10.0, 1.0, [](int, int) { return 0; });
    const auto caster = ig::makeCaster(CasterKind::Reference, map);
    const Intrinsics in = Intrinsics::fromFov(32, 24, degToRad(60));
    Pose bad = makePose(100, 100, 200, 0, 0);
    bad.yaw = std::nan("");
    EXPECT_THROW(ig::renderFrame(*caster, map, bad, in), ig::InputError);
    bad = makePose(100, 100, INFINITY, 0, 0);
    EXPECT_THROW(ig::renderFrame(*caster, map, bad, in), ig::InputError);
}

// A rolled pose reaching the fast caster is a caller's bug (the programs refuse it as input
// first): the caster CHECKs it.
TEST(CasterErrors, FastCasterRefusesRoll) {
    GTEST_FLAG_SET(death_test_style, "threadsafe");
    const TerrainMap map = makeMap(32, 10.0, 1.0, [](int, int) { return 0; });
    const auto caster = ig::makeCaster(CasterKind::Fast, map);
    EXPECT_DEATH(ig::renderFrame(*caster, map, makePose(100, 100, 200, 0, -20, 10),
                                 Intrinsics::fromFov(32, 24, degToRad(60))),
                 "roll = 0");
}

TEST(CasterGeometry, CameraOutsideTheMapSeesTheMap) {
    const TerrainMap map = makeMap(64, 10.0, 1.0, [](int ix, int) { return 20 + ix; });
    for (CasterKind kind : kAllCasters) {
        const auto caster = ig::makeCaster(kind, map);
        // West of the map, looking east and a little down.
        const auto frame = ig::renderFrame(*caster, map, makePose(-300, 320, 150, 90, -15),
                                           Intrinsics::fromFov(64, 48, degToRad(60)));
        int hits = 0;
        for (float d : frame.depth)
            hits += std::isfinite(d) ? 1 : 0;
        EXPECT_GT(hits, 64 * 48 / 5) << ig::casterName(kind);
    }
}

TEST(CasterGeometry, RolledViewRendersTheRotatedScene) {
    // Reference and naive honour roll: a 90 degree roll turns the horizon vertical.
    const TerrainMap map = makeMap(128, 10.0, 1.0, [](int, int) { return 0; });
    for (CasterKind kind : {CasterKind::Reference, CasterKind::Naive}) {
        const auto caster = ig::makeCaster(kind, map);
        const auto frame = ig::renderFrame(*caster, map, makePose(640, 100, 50, 0, 0, 90),
                                           Intrinsics::fromFov(64, 64, degToRad(60)));
        // Right wing down: the ground fills the right half, the sky the left.
        EXPECT_TRUE(std::isinf(frame.depth[32 * 64 + 5]));
        EXPECT_TRUE(std::isfinite(frame.depth[32 * 64 + 58]));
    }
}

TEST(CasterAgreement, FastMatchesNaiveAndReferenceOnRollingHills) {
    const TerrainMap map = makeMap(256, 20.0, 0.1, [](int ix, int iy) {
        return static_cast<int>(3000 + 1500 * std::sin(ix * 0.07) * std::cos(iy * 0.05) +
                                400 * std::sin(ix * 0.31 + iy * 0.23));
    });
    const auto reference = ig::makeCaster(CasterKind::Reference, map);
    const auto naive = ig::makeCaster(CasterKind::Naive, map);
    const auto fast = ig::makeCaster(CasterKind::Fast, map);
    const Intrinsics in = Intrinsics::fromFov(96, 64, degToRad(60), 0);
    for (int i = 0; i < 8; ++i) {
        const Pose pose =
            makePose(1200 + 300 * i, 1500 + 200 * i, 700 + 150 * i, 45.0 * i, 5.0 - 12.0 * i);
        const auto r = ig::renderFrame(*reference, map, pose, in);
        const auto n = ig::renderFrame(*naive, map, pose, in);
        const auto f = ig::renderFrame(*fast, map, pose, in);
        // Both match the reference to rounding (docs/design/ray_casting.md): 0.0000 %.
        EXPECT_LT(ig::meanAbsErrorPct(f.color, r.color), 0.00005) << "pose " << i;
        EXPECT_LT(ig::meanAbsErrorPct(n.color, r.color), 0.00005) << "pose " << i;
        EXPECT_LE(f.stats.steps, n.stats.steps) << "coherence must not add work, pose " << i;
    }
}

}  // namespace
