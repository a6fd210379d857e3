// The span caster: error against a 4x4 supersampled reference next to the multiresolution
// caster's, depths against the exact reference away from silhouettes, a one-cell needle at
// every pitch, thread independence, temporal stability along a slow flight, and the hand-over
// of steep frames to the fast caster.
#include "ig/caster.hpp"
#include "ig/error.hpp"
#include "ig/frame_stream.hpp"
#include "ig/image_compare.hpp"
#include "ig/pose_sweep.hpp"
#include "ig/shading.hpp"
#include "ig/span_resample.hpp"
#include "ig/synthetic.hpp"
#include "ig/terrain_io.hpp"

#include "common/slow_flight.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <random>
#include <vector>

namespace {

using ig::CasterKind;
using ig::Intrinsics;
using ig::Pose;
using ig::TerrainMap;

const TerrainMap& synthetic512() {
    static const TerrainMap map = ig::makeSyntheticTerrain(512, 7, 10.0);
    return map;
}

const TerrainMap& puget() {
    static const TerrainMap map = ig::loadPugetSound();
    return map;
}

const TerrainMap& goleta() {
    static const TerrainMap map = ig::loadGoleta();
    return map;
}

std::unique_ptr<ig::Caster> makeWith(CasterKind kind, const TerrainMap& map, int levels,
                                     int threads = 0, const ig::SkyModel& sky = {}) {
    ig::RenderOptions o;
    o.levels = levels;
    o.threads = threads;
    o.sky = sky;
    return ig::makeCaster(kind, map, o);
}

// Mean colour error over a pose sweep against a 4x4 supersampled reference: span and the
// multiresolution fast caster on the same poses; and, against the exact reference at the same
// size, the fraction of smooth hit pixels (no silhouette in the 3x3 neighbourhood) whose depth
// is within 1 %.
struct SweepError {
    double span = 0.0, multi = 0.0;
    double depthOk = 1.0;
    int spanFrames = 0;
};

SweepError sweepError(const TerrainMap& map, int poses, int w, int h,
                      const ig::SkyModel& sky = {}) {
    constexpr int kF = 4;
    const auto reference = makeWith(CasterKind::Reference, map, 0, 0, sky);
    const auto span = makeWith(CasterKind::Span, map, ig::kLevelsAuto, 0, sky);
    const auto multi = makeWith(CasterKind::Fast, map, ig::kLevelsAuto, 0, sky);
    const Intrinsics in = Intrinsics::fromFov(w, h, ig::degToRad(60));
    const Intrinsics fine = Intrinsics::fromFov(w * kF, h * kF, ig::degToRad(60));
    SweepError e;
    long smooth = 0, ok = 0;
    for (const Pose& pose : ig::sweepPoses(map, poses)) {
        const auto ref =
            ig::boxDownsample(ig::renderFrame(*reference, map, pose, fine).color, w, h, kF);
        const auto s = ig::renderFrame(*span, map, pose, in);
        if (s.stats.path == "span") ++e.spanFrames;
        e.span += ig::meanAbsErrorPct(s.color, ref) / poses;
        e.multi += ig::meanAbsErrorPct(ig::renderFrame(*multi, map, pose, in).color, ref) / poses;
        const auto exact = ig::renderFrame(*reference, map, pose, in);
        for (int y = 1; y + 1 < h; ++y) {
            for (int x = 1; x + 1 < w; ++x) {
                const float d = exact.depth[y * w + x];
                if (!std::isfinite(d)) continue;
                bool edge = false;
                for (int v = -1; v <= 1 && !edge; ++v)
                    for (int u = -1; u <= 1 && !edge; ++u)
                        edge = !(std::abs(exact.depth[(y + v) * w + x + u] - d) <= 0.02f * d);
                if (edge) continue;
                ++smooth;
                if (std::abs(s.depth[y * w + x] - d) <= 0.01f * d) ++ok;
            }
        }
    }
    e.depthOk = smooth ? static_cast<double>(ok) / smooth : 1.0;
    return e;
}

// Goleta's own error is above 0.5 % for the multires caster too: there, within 10 % of it.
void expectQuality(const char* name, const SweepError& e, double limit = 0.5) {
    std::printf(
        "%s vs 4x4 reference: span MAE %.3f %%, multires %.3f %%; depth within 1 %% on "
        "%.2f %% of smooth pixels; %d span frames\n",
        name, e.span, e.multi, 100.0 * e.depthOk, e.spanFrames);
    EXPECT_LE(e.span, limit);
    EXPECT_LE(e.span, 1.1 * e.multi + 0.02);
    EXPECT_GE(e.depthOk, 0.99);
    EXPECT_GT(e.spanFrames, 0);
}

TEST(SpanCaster, NearTheMultiresCasterAgainstSupersampledReferencePuget) {
    expectQuality("Puget Sound", sweepError(puget(), 12, 64, 40));
}

TEST(SpanCaster, NearTheMultiresCasterAgainstSupersampledReferenceGoleta) {
    const SweepError e = sweepError(goleta(), 12, 64, 40);
    expectQuality("Goleta", e, std::max(0.5, 1.1 * e.multi + 0.02));
}

TEST(SpanCaster, NearTheMultiresCasterAgainstSupersampledReferenceSynthetic) {
    expectQuality("synthetic 512^2", sweepError(synthetic512(), 12, 64, 40));
}

// With the casters' distance haze: the span caster hazes a segment's two ends and interpolates.
TEST(SpanCaster, NearTheMultiresCasterUnderDistanceHaze) {
    ig::SkyModel sky;
    sky.hazeDistance = 2000.0;
    ASSERT_TRUE(ig::hazeInKernel(sky));
    expectQuality("synthetic 512^2, haze 2 km", sweepError(synthetic512(), 12, 64, 40, sky));
}

// A flat green map with one raised red sample: the needle is drawn at every pitch, with the
// camera 400 m from its middle and looking at it, on both paths.
TEST(SpanCaster, OneCellNeedleIsDrawnAtEveryPitch) {
    TerrainMap map(129, 129, 10.0, 10.0, 1.0, 0.0);
    for (int y = 0; y < 129; ++y)
        for (int x = 0; x < 129; ++x)
            map.setColor(x, y, ig::Rgb8{40, 160, 40});
    map.setRaw(64, 64, 200);
    map.setColor(64, 64, ig::Rgb8{255, 0, 0});
    map.updateRange();
    const auto span = makeWith(CasterKind::Span, map, ig::kLevelsAuto);
    const Intrinsics in = Intrinsics::fromFov(96, 64, ig::degToRad(60));
    for (int pitchDeg = 10; pitchDeg >= -89; pitchDeg -= 3) {
        for (int headingDeg : {0, 30, 45, 100}) {
            const double p = ig::degToRad(pitchDeg), yaw = ig::degToRad(headingDeg);
            const double r = 400.0 * std::cos(p);
            Pose pose;
            pose.position = {640.0 - r * std::sin(yaw), 640.0 - r * std::cos(yaw),
                             100.0 - 400.0 * std::sin(p)};
            pose.yaw = yaw;
            pose.pitch = p;
            const auto f = ig::renderFrame(*span, map, pose, in);
            int red = 0;
            for (const ig::Rgb8& c : f.color)
                red += c.r > 2 * c.g;
            EXPECT_GT(red, 0) << "pitch " << pitchDeg << " heading " << headingDeg << " path "
                              << f.stats.path;
        }
    }
}

TEST(SpanCaster, IdenticalImagesForAnyThreadCount) {
    const TerrainMap& map = synthetic512();
    const Intrinsics in = Intrinsics::fromFov(120, 72, ig::degToRad(60), 3);
    const auto one = makeWith(CasterKind::Span, map, ig::kLevelsAuto, 1);
    for (const Pose& pose : ig::sweepPoses(map, 8)) {
        const auto a = ig::renderFrame(*one, map, pose, in);
        for (int threads : {2, 4}) {
            const auto many = makeWith(CasterKind::Span, map, ig::kLevelsAuto, threads);
            const auto b = ig::renderFrame(*many, map, pose, in);
            ASSERT_TRUE(a.color == b.color) << threads << " threads";
            ASSERT_EQ(0, std::memcmp(a.depth.data(), b.depth.data(), a.depth.size() * 4));
            EXPECT_EQ(a.stats.steps, b.stats.steps);
            EXPECT_EQ(a.stats.path, b.stats.path);
        }
    }
}

TEST(SpanCaster, NoSpikesAlongASlowFlight) {
    const TerrainMap& map = synthetic512();
    std::vector<double> span =
        vig_test::slowFlightDifferences(*makeWith(CasterKind::Span, map, ig::kLevelsAuto), map, 30);
    std::vector<double> multi =
        vig_test::slowFlightDifferences(*makeWith(CasterKind::Fast, map, ig::kLevelsAuto), map, 30);
    const double mSpan = vig_test::median(span), mMulti = vig_test::median(multi);
    const double worst = *std::max_element(span.begin(), span.end());
    std::printf("slow flight: span median %.3f %% worst %.3f %%; multires median %.3f %%\n", mSpan,
                worst, mMulti);
    ASSERT_GT(mSpan, 0.0);
    EXPECT_LE(worst, 2.0 * mSpan);
    EXPECT_LE(mSpan, 1.1 * mMulti);
}

TEST(SpanCaster, SteepFramesGoToTheFastCaster) {
    const TerrainMap& map = synthetic512();
    const Intrinsics in = Intrinsics::fromFov(96, 64, ig::degToRad(60));
    const auto span = makeWith(CasterKind::Span, map, ig::kLevelsAuto);
    const auto multi = makeWith(CasterKind::Fast, map, ig::kLevelsAuto);
    Pose pose;
    pose.position = {2500.0, 2500.0, map.surfaceHeight(2500.0, 2500.0) + 300.0};
    pose.yaw = 0.3;
    for (double deg : {0.0, -10.0, -30.0, -60.0, -85.0}) {
        pose.pitch = ig::degToRad(deg);
        const ig::Camera camera(pose, in);
        const double stretch = ig::spanStretch(camera);
        const auto s = ig::renderFrame(*span, map, pose, in);
        if (deg == 0.0) {
            EXPECT_DOUBLE_EQ(stretch, 1.0);
        }
        if (stretch <= 2.0) {
            EXPECT_EQ(s.stats.path, "span") << deg;
        } else {
            EXPECT_EQ(s.stats.path, "fast") << deg;
            const auto m = ig::renderFrame(*multi, map, pose, in);
            EXPECT_TRUE(s.color == m.color) << deg;
            EXPECT_EQ(0, std::memcmp(s.depth.data(), m.depth.data(), s.depth.size() * 4));
        }
    }
    // Straight down the vertical plane sees nothing of the window.
    pose.pitch = ig::degToRad(-90.0);
    EXPECT_TRUE(std::isinf(ig::spanStretch(ig::Camera(pose, in))));
}

// Overlapped frames (FrameStream, one unit a frame) are renderFrame's, on both paths.
TEST(SpanCaster, FrameStreamGivesRenderFramesImages) {
    const TerrainMap& map = synthetic512();
    const Intrinsics in = Intrinsics::fromFov(80, 48, ig::degToRad(60));
    const auto span = makeWith(CasterKind::Span, map, ig::kLevelsAuto, 2);
    std::vector<Pose> poses = ig::sweepPoses(map, 6);
    ig::FrameStream stream(*span, map, 2);
    stream.submit(poses[0], in);
    for (std::size_t i = 0; i < poses.size(); ++i) {
        stream.help();
        if (i + 1 < poses.size()) stream.submit(poses[i + 1], in);
        const ig::RenderedFrame got = stream.take();
        const ig::RenderedFrame want = ig::renderFrame(*span, map, poses[i], in);
        EXPECT_TRUE(got.color == want.color) << "pose " << i;
        EXPECT_EQ(0, std::memcmp(got.depth.data(), want.depth.data(), got.depth.size() * 4));
        EXPECT_EQ(got.stats.path, want.stats.path);
    }
    Pose rolled = poses[0];
    rolled.roll = 0.1;
    EXPECT_THROW(stream.submit(rolled, in), ig::InputError);
}

// The resample's blocked transpose is the plain loop's, for any block shape and offsets.
TEST(SpanResample, TransposeIsThePlainLoops) {
    constexpr int kH = 37, kCols = 23;
    std::vector<std::uint32_t> plane(kH * kCols);
    for (std::size_t i = 0; i < plane.size(); ++i)
        plane[i] = static_cast<std::uint32_t>(i * 2654435761u);
    for (int j0 : {0, 1, 5})
        for (int j1 : {j0 + 1, j0 + 4, j0 + 7, kCols})
            for (int y0 : {0, 3, 16})
                for (int y1 : {y0 + 1, y0 + 4, y0 + 13, kH}) {
                    const int stride = j1 - j0 + 2;
                    std::vector<std::uint32_t> a((y1 - y0) * stride, 7u), b = a;
                    ig::spanTranspose(plane.data(), kH, j0, j1, y0, y1, a.data(), stride);
                    ig::spanTransposeReference(plane.data(), kH, j0, j1, y0, y1, b.data(), stride);
                    ASSERT_EQ(a, b) << j0 << " " << j1 << " " << y0 << " " << y1;
                }
}

// The resample row (fixed-point positions, two channels per word, the copy at stretch 1) is
// the per-channel loop's, over stretches from 1 to 2 and offsets, on smooth depths, edges and
// sky; the copy is the plane row itself.
TEST(SpanResample, RowIsThePerChannelLoops) {
    constexpr int kCols = 640, kW = 300;  // 7.7 + 299 * 2 + 2 columns read at most
    std::mt19937 rng(5);
    std::vector<std::uint32_t> color(kCols);
    std::vector<float> depth(kCols);
    for (int j = 0; j < kCols; ++j) {
        color[j] = rng() & 0xffffffu;
        depth[j] = j % 17 == 0  ? ig::kSkyDepth
                   : j % 5 == 0 ? 100.0f + static_cast<float>(rng() % 100)
                                : 100.0f + 0.01f * static_cast<float>(rng() % 100);
    }
    for (double stretch : {1.0, 1.0 + 1.0 / 3.0, 1.08, 1.42, 2.0}) {
        for (double first : {0.0, 3.0, 0.25, 7.7}) {
            const ig::SpanRowMap map = ig::spanRowMap(first, stretch);
            std::vector<ig::Rgb8> a(kW), b(kW);
            std::vector<float> da(kW), db(kW);
            ig::spanResampleRow(color.data(), depth.data(), map, kW, a.data(), da.data());
            ig::spanResampleRowReference(color.data(), depth.data(), map, kW, b.data(), db.data());
            ASSERT_TRUE(a == b) << stretch << " " << first;
            ASSERT_EQ(0, std::memcmp(da.data(), db.data(), kW * sizeof(float)));
            if (stretch == 1.0 && first == 3.0) {
                for (int x = 0; x < kW; ++x) {
                    ASSERT_EQ(a[x].r, color[x + 3] & 255u);
                    ASSERT_EQ(a[x].b, color[x + 3] >> 16 & 255u);
                    ASSERT_EQ(da[x], depth[x + 3]);
                }
            }
        }
    }
}

TEST(SpanCaster, RefusesWhatItCannotDraw) {
    const TerrainMap& map = synthetic512();
    ig::RenderOptions o;
    o.supersample = 2;
    EXPECT_THROW(ig::makeCaster(CasterKind::Span, map, o), ig::InputError);
    o.supersample = 1;
    o.spanMaxStretch = 0.5;
    EXPECT_THROW(ig::makeCaster(CasterKind::Span, map, o), ig::InputError);
    EXPECT_EQ(ig::parseCasterKind("span"), CasterKind::Span);
    EXPECT_EQ(ig::casterName(CasterKind::Span), "span");
}

}  // namespace
