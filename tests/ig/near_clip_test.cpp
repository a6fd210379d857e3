// The near clipping plane (ig/near_clip.hpp): the entry beyond the plane against a fine march
// of the ray, every caster's frame against the same frame without the plane (bit for bit
// wherever the plane cuts nothing), nothing nearer than the plane in any caster, objects cut
// away by it, and control points beyond it.
#include "ig/near_clip.hpp"

#include "ig/caster.hpp"
#include "ig/error.hpp"
#include "ig/object_trace.hpp"
#include "ig/stereo.hpp"
#include "ig/sticks.hpp"
#include "ig/surface_hit.hpp"
#include "ig/synthetic.hpp"
#include "ig/terrain_io.hpp"

#include "common/objects_in_view.hpp"

#include <gtest/gtest.h>
#include <glm/geometric.hpp>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <random>
#include <string>
#include <utility>
#include <vector>

namespace {

using namespace ig;

constexpr double kDeg = std::numbers::pi / 180.0;
constexpr double kInf = std::numeric_limits<double>::infinity();

const TerrainMap& synthetic() {
    static const TerrainMap map = makeSyntheticTerrain(256, 7, 10.0);
    return map;
}
const TerrainMap& puget() {
    static const TerrainMap map = loadPugetSound();
    return map;
}

// The slow twin of entryBeyond: the ray sampled every `step` metres from ta, through the part
// inside the solid, to the first sample on or under the surface after one above it, then
// bisected to 1e-9 m. Negative when no sample within `length` is.
double marchedEntry(const TerrainMap& map, const TerrainRay& ray, double ta, double length,
                    double step) {
    bool above = heightAboveSurface(map, ray, ta) > 0.0;
    for (double t = ta + step; t <= ta + length; t += step) {
        const bool now = heightAboveSurface(map, ray, t) > 0.0;
        if (above && !now) {
            double lo = t - step, hi = t;
            while (hi - lo > 1e-9) {
                const double mid = 0.5 * (lo + hi);
                (heightAboveSurface(map, ray, mid) > 0.0 ? lo : hi) = mid;
            }
            return hi;
        }
        above = now;
    }
    return -1.0;
}

// Rays from eyes a few metres above the ground, nearly level, with planes a little beyond where
// they first meet the ground (so they start under a slope and come out of it again): the exact
// entry beyond each plane equals the one a 2 cm march finds.
TEST(NearClip, EntryBeyondThePlaneMatchesAFineMarch) {
    for (const TerrainMap* map : {&synthetic(), &puget()}) {
        std::mt19937 rng(11);
        std::uniform_real_distribution<double> u(0.0, 1.0);
        int compared = 0, cutOpen = 0;
        for (int k = 0; k < 640; ++k) {
            const double x = (0.2 + 0.6 * u(rng)) * map->extentX();
            const double y = (0.2 + 0.6 * u(rng)) * map->extentY();
            const glm::dvec3 eye{x, y, map->surfaceHeight(x, y) + 1.0 + 30.0 * u(rng)};
            const double yaw = 2.0 * std::numbers::pi * u(rng);
            const double pitch = -(0.2 + 4.0 * u(rng)) * kDeg;
            const glm::dvec3 dir{std::cos(pitch) * std::sin(yaw), std::cos(pitch) * std::cos(yaw),
                                 std::sin(pitch)};
            const TerrainRay ray(*map, eye, dir);
            const double first = exactHitInRange(*map, ray, 0.0, kInf);
            if (first < 0.0) continue;
            // A plane a little beyond the first hit: the ray goes on under the ground from there.
            const double ta = first + (0.2 + 3.0 * u(rng)) * map->spacingX();
            const double got = entryBeyond(*map, ray, ta, kInf);
            const double length =
                std::min(1500.0, got > 0.0 ? got - ta + 3.0 * map->spacingX() : 1500.0);
            const double want = marchedEntry(*map, ray, ta, length, 0.02);
            cutOpen += heightAboveSurface(*map, ray, ta) <= 0.0;
            if (want < 0.0) {
                EXPECT_TRUE(got < 0.0 || got > ta + length - 0.02)
                    << "ray " << k << ": exact " << got << " m, the march finds none";
                continue;
            }
            ASSERT_GE(got, ta) << "ray " << k;
            EXPECT_NEAR(got, want, 1e-6 * std::max(1.0, want)) << "ray " << k << " from " << ta;
            ++compared;
        }
        EXPECT_GT(compared, 25);
        EXPECT_GT(cutOpen, 100);  // planes that really start under the ground
    }
}

// Above the ground at the plane, the entry is the exact first hit from there, to the bit; a ray
// that never comes out of the ground before it leaves the map meets nothing.
TEST(NearClip, EntryAboveTheGroundIsTheExactHit) {
    const TerrainMap& map = synthetic();
    const double x = 0.5 * map.extentX(), y = 0.5 * map.extentY();
    const glm::dvec3 eye{x, y, map.surfaceHeight(x, y) + 50.0};
    const TerrainRay level(map, eye, {0.3, 0.9, -0.2});
    EXPECT_EQ(entryBeyond(map, level, 5.0, kInf), exactHitInRange(map, level, 5.0, kInf));
    const TerrainRay down(map, eye, {0.0, 0.0, -1.0});
    EXPECT_EQ(entryBeyond(map, down, 80.0, kInf), -1.0);  // straight down: never out again
    EXPECT_EQ(exitSolidInRange(map, down, 80.0, kInf), -1.0);
    const TerrainRay outside(map, {-100.0, -100.0, 5000.0}, {-1.0, 0.0, 0.0});
    EXPECT_LT(entryBeyond(map, outside, 1.0, kInf), 0.0);
}

RenderedFrame render(const TerrainMap& map, CasterKind kind, int levels, const Pose& pose,
                     const Intrinsics& in, double nearM, const ObjectLayer* layer = nullptr) {
    RenderOptions options;
    options.levels = levels;
    options.threads = 2;
    if (layer != nullptr) options.objects = {layer};
    const auto caster = makeCaster(kind, map, options);
    return renderFrame(*caster, map, pose, in, 0.0, 0, nearM);
}

// Distance of a pixel's depth ahead along the view axis.
double aheadOf(const Camera& camera, int x, int y, float depth) {
    const glm::dvec3 d = glm::normalize(camera.rayDirection(x + 0.5, y + 0.5));
    return depth * glm::dot(d, camera.basis().forward);
}

struct CasterCase {
    CasterKind kind;
    int levels;
};
const CasterCase kCasters[] = {{CasterKind::Reference, 0},
                               {CasterKind::Naive, 0},
                               {CasterKind::Fast, 0},
                               {CasterKind::Fast, kLevelsAuto},
                               {CasterKind::Span, kLevelsAuto}};

// Low over the ground looking down: every caster's frame with a plane is its frame without it
// wherever the surface lies beyond the plane (bit for bit), and nothing nearer than the plane
// shows; the pixels it cut open show what the reference shows there beyond the plane.
TEST(NearClip, EveryCasterKeepsWhatLiesBeyondAndShowsNothingNearer) {
    const TerrainMap& map = puget();
    const Intrinsics in = Intrinsics::fromFov(160, 120, 70.0 * kDeg, 8);
    for (const double pitch : {-10.0, -35.0, -80.0}) {
        Pose pose;
        pose.position = {0.5 * map.extentX(), 0.45 * map.extentY(), 0.0};
        pose.position.z = map.surfaceHeight(pose.position.x, pose.position.y) + 6.0;
        pose.yaw = 0.6;
        pose.pitch = pitch * kDeg;
        const Camera camera(pose, in);
        const double nearM = 25.0;
        const RenderedFrame reference = render(map, CasterKind::Reference, 0, pose, in, nearM);
        for (const CasterCase& c : kCasters) {
            const std::string what = std::string(casterName(c.kind)) + " levels " +
                                     std::to_string(c.levels) + ", pitch " + std::to_string(pitch);
            const RenderedFrame open = render(map, c.kind, c.levels, pose, in, 0.0);
            const RenderedFrame cut = render(map, c.kind, c.levels, pose, in, nearM);
            EXPECT_EQ(cut.nearM, nearM);
            std::size_t kept = 0, redrawn = 0, sameAsReference = 0;
            for (int y = 0; y < in.height; ++y) {
                for (int x = 0; x < in.width; ++x) {
                    const std::size_t i = static_cast<std::size_t>(y) * in.width + x;
                    if (cut.depth[i] != kSkyDepth) {
                        ASSERT_GE(aheadOf(camera, x, y, cut.depth[i]), nearM * (1.0 - 1e-6))
                            << what << " at " << x << "," << y;
                    }
                    // (Within a millionth of the plane either answer is right.)
                    const double ahead =
                        open.depth[i] == kSkyDepth ? kInf : aheadOf(camera, x, y, open.depth[i]);
                    if (ahead >= nearM * (1.0 + 1e-6)) {
                        ++kept;
                        ASSERT_EQ(cut.depth[i], open.depth[i]) << what;
                        ASSERT_EQ(cut.color[i], open.color[i]) << what;
                    } else if (ahead < nearM * (1.0 - 1e-6)) {
                        ++redrawn;
                        sameAsReference += cut.depth[i] == reference.depth[i] &&
                                           cut.color[i] == reference.color[i];
                    }
                }
            }
            if (pitch < -30.0) {
                EXPECT_GT(redrawn, 500u) << what;
            }
            if (pitch > -50.0) {
                EXPECT_GT(kept, 500u) << what;  // looking down at -80 the plane cuts it all
            }
            // A pixel the caster drew nearer than the plane is redrawn by the reference's own
            // trace; a caster's own near edge may sit a hair either side of the plane.
            EXPECT_GE(sameAsReference, redrawn - redrawn / 50) << what;
        }
    }
}

// 8 m over the middle of `map`, looking nearly level.
Pose lowOverTheGround(const TerrainMap& map) {
    Pose pose;
    pose.position = {0.5 * map.extentX(), 0.5 * map.extentY(), 0.0};
    pose.position.z = map.surfaceHeight(pose.position.x, pose.position.y) + 8.0;
    pose.yaw = 0.3;
    pose.pitch = -6.0 * kDeg;
    return pose;
}

// A conifer 12 m tall (object id 9), 40 m ahead of `pose` on the ground, into `layer`.
void plantATreeAhead(ObjectLayer& layer, const TerrainMap& map, const Pose& pose) {
    const glm::dvec3 ahead =
        pose.position + 40.0 * glm::dvec3{std::sin(pose.yaw), std::cos(pose.yaw), 0.0};
    const ObjectModel& tree = vig_test::shippedModels()[0];
    layer.place(tree, Placement{9, ahead.x, ahead.y, map.surfaceHeight(ahead.x, ahead.y), 0.0,
                                12.0 / tree.grid.sizeZ});
    layer.finish();
}

// The plane cuts objects too: one standing wholly nearer than the plane leaves the frame as if
// it were not there; one beyond the plane is drawn; no object pixel is nearer than the plane.
TEST(NearClip, ObjectsNearerThanThePlaneAreCutAway) {
    const TerrainMap& map = puget();
    const Intrinsics in = Intrinsics::fromFov(128, 96, 60.0 * kDeg, 8);
    const Pose pose = lowOverTheGround(map);
    const Camera camera(pose, in);
    ObjectLayer layer(map, 0.25);
    plantATreeAhead(layer, map, pose);
    for (const CasterCase& c : kCasters) {
        const std::string what =
            std::string(casterName(c.kind)) + " levels " + std::to_string(c.levels);
        const RenderedFrame seen = render(map, c.kind, c.levels, pose, in, 20.0, &layer);
        ASSERT_EQ(seen.objectId.size(), seen.depth.size()) << what;
        std::size_t shown = 0;
        for (int y = 0; y < in.height; ++y) {
            for (int x = 0; x < in.width; ++x) {
                const std::size_t i = static_cast<std::size_t>(y) * in.width + x;
                if (seen.objectId[i] == 0) continue;
                ++shown;
                ASSERT_GE(aheadOf(camera, x, y, seen.depth[i]), 20.0 * (1.0 - 1e-6)) << what;
            }
        }
        EXPECT_GT(shown, 100u) << what;
        // A plane beyond the whole tree cuts it away; the reference's frame is then the frame
        // without it, to the bit (each caster redraws those pixels by the reference's trace).
        const RenderedFrame cut = render(map, c.kind, c.levels, pose, in, 60.0, &layer);
        EXPECT_EQ(std::count(cut.objectId.begin(), cut.objectId.end(), std::uint16_t{9}), 0)
            << what;
        if (c.kind == CasterKind::Reference) {
            const RenderedFrame bare = render(map, c.kind, c.levels, pose, in, 60.0);
            EXPECT_EQ(cut.color, bare.color) << what;
            EXPECT_EQ(cut.depth, bare.depth) << what;
        }
    }
}

// A stereo pair with a plane: the right eye (reprojected from the left, its gaps cast) shows
// nothing nearer than the plane either, and the pixels it redraws from beyond the plane are
// those of the right eye fully cast with the plane. (Few are: what the left eye shows lies
// beyond the plane, and so does what is reprojected from it; 40 m up with 10 m between the
// eyes, some sixty cast pixels of a 160 x 120 eye are nearer per view.)
TEST(NearClip, StereoRightEyeShowsNothingNearerAndWhatItsFullCastShows) {
    const TerrainMap& map = puget();
    const Intrinsics in = Intrinsics::fromFov(160, 120, 70.0 * kDeg, 8);
    RenderOptions options;
    options.threads = 2;
    const auto caster = makeCaster(CasterKind::Fast, map, options);
    StereoOptions so;
    so.eyeSeparation = 10.0;
    std::size_t redrawn = 0, sameAsFull = 0;
    for (const double pitch : {-10.0, -20.0, -35.0}) {
        Pose pose;
        pose.position = {0.5 * map.extentX(), 0.45 * map.extentY(), 0.0};
        pose.position.z = map.surfaceHeight(pose.position.x, pose.position.y) + 40.0;
        pose.yaw = 0.6;
        pose.pitch = pitch * kDeg;
        const double nearM = 300.0;
        const std::string what = "pitch " + std::to_string(pitch);
        std::vector<RightPixelSource> source, openSource;
        StereoStats stats;
        const RenderedFrame left = renderFrame(*caster, map, pose, in, 0.0, 0, nearM);
        const RenderedFrame right =
            reprojectRightEye(map, left, so, options, source, stats, caster.get());
        const RenderedFrame open =
            reprojectRightEye(map, renderFrame(*caster, map, pose, in, 0.0, 0, 0.0), so, options,
                              openSource, stats, caster.get());
        const RenderedFrame full =
            renderFrame(*caster, map, rightEyePose(pose, so.eyeSeparation), in, 0.0, 0, nearM);
        EXPECT_EQ(right.nearM, nearM) << what;
        const Camera camera(right.pose, in);
        for (int y = 0; y < in.height; ++y) {
            for (int x = 0; x < in.width; ++x) {
                const std::size_t i = static_cast<std::size_t>(y) * in.width + x;
                if (right.depth[i] != kSkyDepth) {
                    ASSERT_GE(aheadOf(camera, x, y, right.depth[i]), nearM * (1.0 - 1e-6))
                        << what << " at " << x << "," << y;
                }
                // Cast in the right eye without the plane, and nearer than it there.
                if (source[i] == RightPixelSource::RayCast && open.depth[i] != kSkyDepth &&
                    aheadOf(camera, x, y, open.depth[i]) < nearM * (1.0 - 1e-6)) {
                    ++redrawn;
                    sameAsFull +=
                        right.depth[i] == full.depth[i] && right.color[i] == full.color[i];
                }
            }
        }
        {
            std::size_t rc = 0, on = 0;
            for (std::size_t i = 0; i < source.size(); ++i) {
                rc += source[i] == RightPixelSource::RayCast;
                on += openSource[i] == RightPixelSource::RayCast;
            }
            std::printf("DBG %s: rc %zu open rc %zu\n", what.c_str(), rc, on);
        }
        for (const ControlPoint& c : right.controlPoints) {
            if (c.world.w == 0.0) continue;
            const glm::dvec3 d = glm::dvec3(c.world) - right.pose.position;
            EXPECT_GE(glm::dot(d, camera.basis().forward), nearM * (1.0 - 1e-9)) << what;
        }
    }
    EXPECT_GT(redrawn, 100u);
    EXPECT_GE(sameAsFull, redrawn - redrawn / 50);
}

// Objects drawn over a stereo pair (drawStereoObjects) are cut by the plane as in a mono frame:
// none nearer than it in either eye, and one standing wholly nearer leaves both eyes as if it
// were not there, to the bit.
TEST(NearClip, StereoPairsCutObjectsAway) {
    const TerrainMap& map = puget();
    const Intrinsics in = Intrinsics::fromFov(128, 96, 60.0 * kDeg, 8);
    const Pose pose = lowOverTheGround(map);
    ObjectLayer layer(map, 0.25);
    plantATreeAhead(layer, map, pose);
    RenderOptions terrain;
    terrain.threads = 2;
    RenderOptions withTree = terrain;
    withTree.objects = {&layer};
    const auto caster = makeCaster(CasterKind::Fast, map, terrain);
    StereoOptions so;
    so.eyeSeparation = 1.0;
    const auto pair = [&](double nearM, bool objects) {
        std::vector<RightPixelSource> source;
        StereoStats stats;
        RenderedFrame left = renderFrame(*caster, map, pose, in, 0.0, 0, nearM);
        RenderedFrame right =
            reprojectRightEye(map, left, so, terrain, source, stats, caster.get());
        if (objects) drawStereoObjects(withTree, left, right);
        return std::pair<RenderedFrame, RenderedFrame>{std::move(left), std::move(right)};
    };
    const auto [left20, right20] = pair(20.0, true);
    for (const RenderedFrame* eye : {&left20, &right20}) {
        const Camera camera(eye->pose, in);
        std::size_t shown = 0;
        for (int y = 0; y < in.height; ++y) {
            for (int x = 0; x < in.width; ++x) {
                const std::size_t i = static_cast<std::size_t>(y) * in.width + x;
                if (eye->objectId[i] == 0) continue;
                ++shown;
                ASSERT_GE(aheadOf(camera, x, y, eye->depth[i]), 20.0 * (1.0 - 1e-6));
            }
        }
        EXPECT_GT(shown, 100u);
    }
    const auto [left60, right60] = pair(60.0, true);
    const auto [bareLeft, bareRight] = pair(60.0, false);
    EXPECT_EQ(std::count(left60.objectId.begin(), left60.objectId.end(), std::uint16_t{9}), 0);
    EXPECT_EQ(std::count(right60.objectId.begin(), right60.objectId.end(), std::uint16_t{9}), 0);
    EXPECT_EQ(left60.color, bareLeft.color);
    EXPECT_EQ(left60.depth, bareLeft.depth);
    EXPECT_EQ(right60.color, bareRight.color);
    EXPECT_EQ(right60.depth, bareRight.depth);
}

// Control points see what their pixels show: the surface beyond the plane along their ray, or
// the ray's direction where nothing lies beyond it.
TEST(NearClip, ControlPointsLieBeyondThePlane) {
    const TerrainMap& map = puget();
    const Intrinsics in = Intrinsics::fromFov(96, 72, 60.0 * kDeg, 0);
    Pose pose;
    pose.position = {0.4 * map.extentX(), 0.5 * map.extentY(), 0.0};
    pose.position.z = map.surfaceHeight(pose.position.x, pose.position.y) + 5.0;
    pose.pitch = -20.0 * kDeg;
    const Camera camera(pose, in);
    const RenderedFrame open = render(map, CasterKind::Reference, 0, pose, in, 0.0);
    const RenderedFrame cut = render(map, CasterKind::Reference, 0, pose, in, 30.0);
    int moved = 0, points = 0;
    for (int k = 0; k < kControlPointCount; ++k) {
        const ControlPoint& a = open.controlPoints[k];
        const ControlPoint& b = cut.controlPoints[k];
        ASSERT_EQ(a.pixel, b.pixel);
        const glm::dvec3 dir = glm::normalize(camera.rayDirection(b.pixel.x, b.pixel.y));
        if (b.world.w == 0.0) {
            EXPECT_NEAR(glm::length(glm::dvec3(b.world) - dir), 0.0, 1e-12) << k;
        } else {
            ++points;
            const glm::dvec3 p{b.world};
            EXPECT_GE(camera.forwardDepth(p), 30.0 * (1.0 - 1e-9)) << k;
            EXPECT_NEAR(p.z, map.surfaceHeight(p.x, p.y), 1e-6) << k;
            EXPECT_NEAR(glm::length(glm::cross(p - pose.position, dir)), 0.0,
                        1e-9 * glm::length(p - pose.position))
                << k;
        }
        // (A point beyond the plane in the cell the plane crosses is solved from there: the
        // same point to rounding.)
        if (a.world.w != b.world.w ||
            glm::length(glm::dvec3(a.world) - glm::dvec3(b.world)) > 1e-6) {
            ++moved;
            // Only a point nearer than the plane moves.
            EXPECT_TRUE(a.world.w == 1.0 && camera.forwardDepth(glm::dvec3(a.world)) < 30.0) << k;
        }
    }
    EXPECT_GT(moved, 0);
    EXPECT_GT(points, 0);
}

// A plane of 0 changes nothing; a bad one is refused naming it.
TEST(NearClip, NoPlaneChangesNothingAndABadOneIsRefused) {
    const TerrainMap& map = synthetic();
    const Intrinsics in = Intrinsics::fromFov(64, 48, 60.0 * kDeg, 0);
    Pose pose;
    pose.position = {0.5 * map.extentX(), 0.5 * map.extentY(), 0.0};
    pose.position.z = map.surfaceHeight(pose.position.x, pose.position.y) + 3.0;
    pose.pitch = -40.0 * kDeg;
    RenderOptions options;
    const auto caster = makeCaster(CasterKind::Fast, map, options);
    const RenderedFrame a = renderFrame(*caster, map, pose, in);
    const RenderedFrame b = renderFrame(*caster, map, pose, in, 0.0, 0, 0.0);
    EXPECT_EQ(a.color, b.color);
    EXPECT_EQ(a.depth, b.depth);
    for (const double bad : {-1.0, std::nan(""), kInf}) {
        try {
            renderFrame(*caster, map, pose, in, 0.0, 0, bad);
            ADD_FAILURE() << bad << " taken";
        } catch (const InputError& e) {
            EXPECT_NE(std::string(e.what()).find("near plane"), std::string::npos) << e.what();
        }
    }
}

}  // namespace
