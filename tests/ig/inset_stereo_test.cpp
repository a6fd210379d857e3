// Stereo pairs over a terrain with an inset: the right eye reprojected from the left, its gaps
// cast on the nested surface, against the right eye fully cast by the nested caster (the slow,
// obviously correct twin), unlit and lit by the sun (each map by its own normals).
#include "ig/stereo.hpp"

#include "ig/error.hpp"
#include "ig/image_compare.hpp"
#include "ig/inset.hpp"
#include "ig/lighting_pass.hpp"
#include "ig/synthetic.hpp"

#include <gtest/gtest.h>
#include <glm/geometric.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>
#include <vector>

namespace ig {
namespace {

constexpr std::uint64_t kSeed = 7;
constexpr double kSpacing = 8.0;

// A 512² synthetic map at 8 m with a 64 x 48-cell inset four times finer (2 m) at cell (200, 210).
const NestedTerrain& shared() {
    static const NestedTerrain t = [] {
        std::vector<InsetSource> sources;
        sources.push_back(syntheticInset(kSeed, kSpacing, 200, 210, 64, 48, 4));
        return NestedTerrain(makeSyntheticTerrain(512, kSeed, kSpacing), std::move(sources), 16);
    }();
    return t;
}

// `range` metres from the inset's centre, looking at it.
Pose lookingAtTheInset(double yawDeg, double pitchDeg, double range, double up) {
    const Inset& in = shared().insets()[0];
    const glm::dvec2 c = 0.5 * (in.coverMin + in.coverMax);
    Pose p;
    p.yaw = degToRad(yawDeg);
    p.pitch = degToRad(pitchDeg);
    p.position = {c.x - range * std::sin(p.yaw), c.y - range * std::cos(p.yaw), 0.0};
    p.position.z = shared().surfaceHeight(p.position.x, p.position.y) + up;
    return p;
}

// Whether pixel i of `frame` shows the inset's surface, `edge` metres or more inside its square.
bool showsTheInset(const RenderedFrame& frame, std::size_t i, double edge) {
    if (!std::isfinite(frame.depth[i])) return false;
    const Inset& in = shared().insets()[0];
    const Camera cam(frame.pose, frame.intrinsics);
    const int x = static_cast<int>(i % static_cast<std::size_t>(frame.width()));
    const int y = static_cast<int>(i / static_cast<std::size_t>(frame.width()));
    const glm::dvec3 p =
        frame.pose.position +
        double(frame.depth[i]) * glm::normalize(cam.rayDirection(x + 0.5, y + 0.5));
    return p.x >= in.coverMin.x + edge && p.y >= in.coverMin.y + edge &&
           p.x <= in.coverMax.x - edge && p.y <= in.coverMax.y - edge;
}

struct Views {
    double yaw, pitch, range, up;
};
constexpr Views kViews[] = {
    {0, -25, 500, 150}, {70, -40, 300, 220}, {200, -12, 900, 120}, {315, -60, 150, 400}};

// The cast pixels of the reprojected right eye are the nested caster's, inside the inset as
// elsewhere; the whole eye is near the full cast; the control points are the full cast's.
void checkPairs(const RenderOptions& options, const char* what) {
    const NestedTerrain& t = shared();
    const Intrinsics intr = Intrinsics::fromFov(200, 140, degToRad(55));
    const auto caster = makeNestedCaster(CasterKind::Fast, t, options);
    std::uint64_t cast = 0, same = 0, castInside = 0, sameInside = 0;
    for (const Views& v : kViews) {
        const Pose pose = lookingAtTheInset(v.yaw, v.pitch, v.range, v.up);
        StereoOptions so;
        so.eyeSeparation = 0.05 * v.up;
        const StereoFrame s = renderStereo(t, pose, intr, so, options);
        const RenderedFrame full = renderNestedFrame(*caster, t, s.right.pose, intr);
        for (std::size_t i = 0; i < s.source.size(); ++i) {
            if (s.source[i] != RightPixelSource::RayCast) continue;
            const bool match = s.right.color[i] == full.color[i];
            ++cast;
            same += match;
            if (showsTheInset(full, i, 4.0)) {
                ++castInside;
                sameInside += match;
            }
        }
        const double mae = meanAbsErrorPct(s.right.color, full.color);
        std::printf("%s, yaw %g: right eye MAE %.3f %% against the full cast\n", what, v.yaw, mae);
        EXPECT_LT(mae, 2.0) << what << ", yaw " << v.yaw;
        for (int k = 0; k < kControlPointCount; ++k) {
            const glm::dvec4 p = s.right.controlPoints[k].world;
            ASSERT_EQ(p.w, full.controlPoints[k].world.w);
            if (p.w == 0.0) continue;
            EXPECT_EQ(p, full.controlPoints[k].world);
        }
    }
    std::printf("%s: %llu cast pixels (%llu over the inset), %.2f %% the full cast's (%.2f %%)\n",
                what, static_cast<unsigned long long>(cast),
                static_cast<unsigned long long>(castInside),
                100.0 * same / std::max<double>(cast, 1),
                100.0 * sameInside / std::max<double>(castInside, 1));
    ASSERT_GT(castInside, 200u) << what;
    EXPECT_GE(same, 0.99 * cast) << what;
    EXPECT_GE(sameInside, 0.99 * castInside) << what;
}

TEST(InsetStereo, CastPixelsAreTheNestedCastersOverTheInset) {
    checkPairs(RenderOptions{}, "unlit");
}

TEST(InsetStereo, CastPixelsAreLitByTheirOwnMap) {
    RenderOptions options;
    auto lit = std::make_shared<SunLighting>();
    lit->normals = std::make_shared<const TerrainNormals>(shared().global());
    lit->clock.sun = Sun{degToRad(135.0), degToRad(30.0)};
    options.lighting = lit;
    checkPairs(options, "lit");
}

// A near plane over the nested surface: the right eye shows nothing nearer than the plane, and
// the pixels it redraws from beyond it (over the inset's surface or the global map's, whichever
// the ray enters first) are those of the right eye fully cast by the nested caster with it.
TEST(InsetStereo, TheNearPlaneClipsTheRightEyeAsTheNestedFullCast) {
    const NestedTerrain& t = shared();
    const NestedMaps& maps = t.maps();
    const Intrinsics intr = Intrinsics::fromFov(200, 140, degToRad(55));
    const RenderOptions options;
    const auto caster = makeNestedCaster(CasterKind::Fast, t, options);
    const std::vector<RenderOptions> passes =
        insetPassOptions(maps, std::vector<RenderOptions>(maps.insets.size(), options));
    StereoOptions so;
    so.eyeSeparation = 4.0;
    // 40 m over the ground, 120 m short of the inset's centre, looking down at it.
    const Pose pose = lookingAtTheInset(0, -30, 120, 40);
    const double nearM = 90.0;
    std::vector<RightPixelSource> source, openSource;
    StereoStats stats;
    const RenderedFrame left = renderNestedFrame(*caster, t, pose, intr, 0.0, 0, nearM);
    const RenderedFrame right = reprojectRightEye(maps, passes, left, so, options, source, stats,
                                                  nestedGlobalCaster(*caster));
    const RenderedFrame open =
        reprojectRightEye(maps, passes, renderNestedFrame(*caster, t, pose, intr), so, options,
                          openSource, stats, nestedGlobalCaster(*caster));
    const RenderedFrame full = renderNestedFrame(*caster, t, right.pose, intr, 0.0, 0, nearM);
    const Camera camera(right.pose, intr);
    const auto ahead = [&](std::size_t i, float depth) {
        const int x = static_cast<int>(i % static_cast<std::size_t>(intr.width));
        const int y = static_cast<int>(i / static_cast<std::size_t>(intr.width));
        return depth * glm::dot(glm::normalize(camera.rayDirection(x + 0.5, y + 0.5)),
                                camera.basis().forward);
    };
    std::size_t redrawn = 0, same = 0, inside = 0;
    for (std::size_t i = 0; i < right.depth.size(); ++i) {
        if (std::isfinite(right.depth[i])) {
            ASSERT_GE(ahead(i, right.depth[i]), nearM * (1.0 - 1e-6)) << "pixel " << i;
        }
        if (source[i] != RightPixelSource::RayCast || !std::isfinite(open.depth[i]) ||
            ahead(i, open.depth[i]) >= nearM * (1.0 - 1e-6)) {
            continue;
        }
        ++redrawn;
        same += right.depth[i] == full.depth[i] && right.color[i] == full.color[i];
        inside += showsTheInset(full, i, 4.0);
    }
    std::printf(
        "near plane %g m: %zu right pixels redrawn beyond it (%zu over the inset), "
        "%zu the full cast's\n",
        nearM, redrawn, inside, same);
    EXPECT_GT(redrawn, 100u);
    EXPECT_GT(inside, 20u);
    EXPECT_GE(same, redrawn - redrawn / 50);
}

// Without the inset the gaps over it would show the global map: the reprojected eye over the
// nested terrain is much nearer its full cast than one over the global map alone.
TEST(InsetStereo, TheGapsShowTheInsetNotTheGlobalMap) {
    const NestedTerrain& t = shared();
    const TerrainMap plain = makeSyntheticTerrain(512, kSeed, kSpacing);
    const Intrinsics intr = Intrinsics::fromFov(200, 140, degToRad(55));
    const auto caster = makeNestedCaster(CasterKind::Fast, t, RenderOptions{});
    // Straight down over the inset's centre: the strip only the right eye sees is the inset.
    const Pose pose = lookingAtTheInset(0, -89, 0, 300);
    StereoOptions so;
    so.eyeSeparation = 30.0;
    const StereoFrame s = renderStereo(t, pose, intr, so);
    const RenderedFrame full = renderNestedFrame(*caster, t, s.right.pose, intr);
    // The plain map's gaps over the nested left eye: the right eye's cast pixels from the
    // global map alone.
    std::vector<RightPixelSource> source;
    StereoStats stats;
    const RenderedFrame coarse = reprojectRightEye(plain, s.left, so, {}, source, stats);
    ASSERT_EQ(source, s.source);
    std::vector<Rgb8> a, b, c;
    for (std::size_t i = 0; i < s.source.size(); ++i) {
        if (s.source[i] != RightPixelSource::RayCast || !showsTheInset(full, i, 4.0)) continue;
        a.push_back(s.right.color[i]);
        b.push_back(full.color[i]);
        c.push_back(coarse.color[i]);
    }
    ASSERT_GT(a.size(), 500u);
    // The strip only the right eye sees is cast whole by the global pass, the insets then.
    EXPECT_GT(s.stats.wholeColumns, 0u);
    const double nestedMae = meanAbsErrorPct(a, b), plainMae = meanAbsErrorPct(c, b);
    std::printf("%zu cast pixels over the inset: MAE %.3f %%, from the global map alone %.3f %%\n",
                a.size(), nestedMae, plainMae);
    EXPECT_GE(plainMae, 5.0 * std::max(nestedMae, 0.05));
}

TEST(InsetStereo, TheFullCastMethodIsTheNestedRightEye) {
    const NestedTerrain& t = shared();
    const Intrinsics intr = Intrinsics::fromFov(160, 120, degToRad(55));
    const auto caster = makeNestedCaster(CasterKind::Fast, t, RenderOptions{});
    const Pose pose = lookingAtTheInset(70, -40, 300, 220);
    StereoOptions so;
    so.eyeSeparation = 5.0;
    so.method = RightEyeMethod::Raycast;
    const StereoFrame s = renderStereo(t, pose, intr, so);
    const RenderedFrame full = renderNestedFrame(*caster, t, s.right.pose, intr);
    EXPECT_EQ(s.right.color, full.color);
    EXPECT_EQ(s.right.depth, full.depth);
}

// The right eye is checked against the nested surface: one above the lowered global map but
// under the inset's surface is refused.
TEST(InsetStereo, ARightEyeUnderTheInsetsSurfaceIsRefused) {
    const NestedTerrain& t = shared();
    const Intrinsics intr = Intrinsics::fromFov(64, 48, degToRad(55));
    const auto caster = makeNestedCaster(CasterKind::Fast, t, RenderOptions{});
    const RenderedFrame left =
        renderNestedFrame(*caster, t, lookingAtTheInset(0, -25, 500, 150), intr);
    StereoOptions so;
    so.eyeSeparation = 1.0;
    std::vector<RightPixelSource> source;
    StereoStats stats;
    const NestedMaps& maps = t.maps();
    const std::vector<RenderOptions> own(1);
    EXPECT_NO_THROW(reprojectRightEye(maps, own, left, so, {}, source, stats));
    RenderedFrame under = left;
    const Inset& in = t.insets()[0];
    under.pose.position.x = 0.5 * (in.coverMin.x + in.coverMax.x);
    under.pose.position.y = 0.5 * (in.coverMin.y + in.coverMax.y);
    const glm::dvec3 r = rightEyePose(under.pose, so.eyeSeparation).position;
    under.pose.position.z = t.surfaceHeight(r.x, r.y) - 0.01;
    ASSERT_LT(t.global().surfaceHeight(r.x, r.y), under.pose.position.z);
    EXPECT_THROW(reprojectRightEye(maps, own, under, so, {}, source, stats), InputError);
    EXPECT_NO_THROW(reprojectRightEye(t.global(), under, so, {}, source, stats));
}

}  // namespace
}  // namespace ig
