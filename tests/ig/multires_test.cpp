// Terrain pyramid, hierarchical first hit, and the multiresolution fast caster: bounds,
// agreement with the plain march, thread independence, error against a supersampled reference,
// and temporal stability along a slow flight.
#include "ig/caster.hpp"
#include "ig/error.hpp"
#include "ig/image_compare.hpp"
#include "ig/multires_march.hpp"
#include "ig/pose_sweep.hpp"
#include "ig/pyramid.hpp"
#include "ig/shading.hpp"
#include "ig/synthetic.hpp"
#include "ig/terrain_io.hpp"

#include "common/slow_flight.hpp"

#include <gtest/gtest.h>
#include <glm/geometric.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <random>
#include <string>
#include <vector>

namespace {

using ig::CasterKind;
using ig::Intrinsics;
using ig::Pose;
using ig::TerrainMap;
using ig::TerrainPyramid;

const TerrainMap& synthetic512() {
    static const TerrainMap map = ig::makeSyntheticTerrain(512, 7, 10.0);
    return map;
}

const TerrainMap& synthetic1024() {
    static const TerrainMap map = ig::makeSyntheticTerrain(1024, 7, 10.0);
    return map;
}

const TerrainMap& puget() {
    static const TerrainMap map = ig::loadPugetSound();
    return map;
}

// Bilinear height (raw units) of display level k at level-0 grid coordinates (gx, gy).
double levelRawAt(const ig::PyramidLevel& l, double gx, double gy) {
    const double s = 1.0 / (1 << l.shift);
    const double x = std::clamp(gx * s, 0.0, l.width - 1.0);
    const double y = std::clamp(gy * s, 0.0, l.height - 1.0);
    const int ix = std::min(static_cast<int>(x), l.width - 2);
    const int iy = std::min(static_cast<int>(y), l.height - 2);
    const double fx = x - ix, fy = y - iy;
    return (l.raw(ix, iy) * (1 - fx) + l.raw(ix + 1, iy) * fx) * (1 - fy) +
           (l.raw(ix, iy + 1) * (1 - fx) + l.raw(ix + 1, iy + 1) * fx) * fy;
}

TEST(TerrainPyramid, LevelsHalveAndStayOnGridLines) {
    for (int n : {2, 3, 17, 64, 65, 100}) {
        TerrainMap map(n, n + 7, 10.0, 10.0, 1.0, 0.0);
        map.updateRange();
        const TerrainPyramid pyr(map);
        ASSERT_GE(pyr.levelCount(), 1);
        for (int k = 1; k < pyr.levelCount(); ++k) {
            const ig::PyramidLevel& fine = pyr.level(k - 1);
            const ig::PyramidLevel& l = pyr.level(k);
            EXPECT_EQ(l.shift, k);
            EXPECT_EQ(l.width - 1, (fine.width - 1 + 1) / 2) << "n " << n << " level " << k;
            EXPECT_EQ(l.height - 1, (fine.height - 1 + 1) / 2) << "n " << n << " level " << k;
            // The coarse grid covers the whole map.
            EXPECT_GE((l.width - 1) << k, n - 1);
            EXPECT_GE(l.width - 1, 2);
        }
    }
}

TEST(TerrainPyramid, MeanPreservesPlanesAndConstants) {
    // A plane stays the plane at every level away from the clamped border; a constant colour
    // stays that colour everywhere.
    const int n = 129;
    TerrainMap map(n, n, 5.0, 5.0, 1.0, 0.0);
    for (int iy = 0; iy < n; ++iy) {
        for (int ix = 0; ix < n; ++ix) {
            map.setRaw(ix, iy, static_cast<std::uint16_t>(100 + 3 * ix + 5 * iy));
            map.setColor(ix, iy, ig::Rgb8{40, 90, 200});
        }
    }
    map.updateRange();
    const TerrainPyramid pyr(map);
    ASSERT_GE(pyr.levelCount(), 5);
    for (int k = 1; k < pyr.levelCount(); ++k) {
        const ig::PyramidLevel& l = pyr.level(k);
        for (int j = 0; j < l.height; ++j) {
            for (int i = 0; i < l.width; ++i) {
                EXPECT_EQ(l.colors[l.index(i, j)], (ig::Rgb8{40, 90, 200}));
                const int border = (1 << k);  // samples whose filter support is clamped
                const int x0 = i << k, y0 = j << k;
                if (x0 < border || y0 < border || x0 > n - 1 - border || y0 > n - 1 - border) {
                    continue;
                }
                EXPECT_EQ(l.raw(i, j), 100 + 3 * x0 + 5 * y0) << "level " << k;
            }
        }
    }
}

TEST(TerrainPyramid, NodesBoundEveryLevelsSurface) {
    const TerrainMap& map = synthetic512();
    const TerrainPyramid pyr(map);
    ASSERT_GE(pyr.levelCount(), 6);
    ASSERT_GE(pyr.nodeLevelCount(), 9);
    EXPECT_EQ(pyr.nodesX(pyr.nodeLevelCount() - 1), 1);
    std::mt19937 rng(3);
    std::uniform_real_distribution<double> ux(0.0, map.width() - 1.0), uy(0.0, map.height() - 1.0);
    for (int i = 0; i < 3000; ++i) {
        const double gx = ux(rng), gy = uy(rng);
        const int cx = std::min(static_cast<int>(gx), map.width() - 2);
        const int cy = std::min(static_cast<int>(gy), map.height() - 2);
        for (int k = 0; k < pyr.levelCount(); ++k) {
            const double h = levelRawAt(pyr.level(k), gx, gy);
            for (int j = 1; j < pyr.nodeLevelCount(); ++j) {
                ASSERT_LE(h, pyr.nodeMaxRaw(j, cx >> j, cy >> j) + 1e-9)
                    << "level " << k << " node level " << j << " at " << gx << "," << gy;
            }
            // Each level's own cell maxima bound its surface.
            const ig::PyramidLevel& l = pyr.level(k);
            const double s = 1.0 / (1 << k);
            const int lx = std::min(static_cast<int>(gx * s), l.width - 2);
            const int ly = std::min(static_cast<int>(gy * s), l.height - 2);
            ASSERT_LE(h, l.cellMaxRaw(lx, ly) + 1e-9);
        }
    }
    // Coarse means stay within the map's range.
    const ig::PyramidLevel& top = pyr.level(pyr.levelCount() - 1);
    for (int j = 0; j < top.height; ++j) {
        for (int i = 0; i < top.width; ++i) {
            const double z = top.raw(i, j) * map.heightScale() + map.heightOffset();
            EXPECT_GE(z, map.minHeight());
            EXPECT_LE(z, map.maxHeight());
        }
    }
}

// Bottom rays (and a few rows above) of every column: the hierarchical first hit equals the
// plain march, over a pose sweep.
void expectHierarchicalAgrees(const TerrainMap& map, int poses) {
    const TerrainPyramid pyr(map);
    const Intrinsics in = Intrinsics::fromFov(160, 90, ig::degToRad(60));
    int hits = 0, misses = 0;
    for (const Pose& pose : ig::sweepPoses(map, poses)) {
        const ig::Camera cam(pose, in);
        for (int row : {in.height - 1, in.height / 2, in.height / 4}) {
            for (int x = 0; x < in.width; ++x) {
                const ig::TerrainRay ray(map, pose.position, cam.rayDirection(x + 0.5, row + 0.5));
                double t0, t1;
                if (!ig::clipToMapBox(map, ray, t0, t1)) continue;
                std::uint64_t s0 = 0, s1 = 0;
                const double plain = ig::marchRay(map, ray, t0, t1, s0);
                const double hier = ig::hierarchicalFirstHit(pyr, ray, t0, t1, s1);
                ASSERT_EQ(plain >= 0.0, hier >= 0.0)
                    << "column " << x << " row " << row << " plain " << plain << " hier " << hier;
                if (plain >= 0.0) {
                    ASSERT_NEAR(hier, plain, 1e-9 * plain + 1e-6) << "column " << x;
                    ++hits;
                } else {
                    ++misses;
                }
            }
        }
    }
    EXPECT_GT(hits, 1000);
    EXPECT_GT(misses, 100);
}

TEST(HierarchicalFirstHit, AgreesWithPlainMarchOnSynthetic) {
    expectHierarchicalAgrees(synthetic512(), 24);
}

TEST(HierarchicalFirstHit, AgreesWithPlainMarchOnPugetSound) {
    expectHierarchicalAgrees(puget(), 24);
}

TEST(HierarchicalFirstHit, SkipsEmptySpaceCheaply) {
    // A ray high above a flat map's low plain toward a single peak: the skip takes few nodes.
    const int n = 1025;
    TerrainMap map(n, n, 10.0, 10.0, 1.0, 0.0);
    map.setRaw(900, 512, 500);
    map.updateRange();
    const TerrainPyramid pyr(map);
    const ig::TerrainRay ray(map, {100.0, 5120.0, 400.0}, {1.0, 0.0, -0.04});
    double t0, t1;
    ASSERT_TRUE(ig::clipToMapBox(map, ray, t0, t1));
    std::uint64_t plainSteps = 0, hierSteps = 0;
    const double plain = ig::marchRay(map, ray, t0, t1, plainSteps);
    const double hier = ig::hierarchicalFirstHit(pyr, ray, t0, t1, hierSteps);
    ASSERT_GE(plain, 0.0);
    EXPECT_NEAR(hier, plain, 1e-6);
    EXPECT_LT(hierSteps * 4, plainSteps);
}

ig::RenderedFrame renderWith(const TerrainMap& map, const Pose& pose, const Intrinsics& in,
                             int levels, int threads, int supersample = 1) {
    ig::RenderOptions options;
    options.levels = levels;
    options.threads = threads;
    options.supersample = supersample;
    const auto caster = ig::makeCaster(CasterKind::Fast, map, options);
    return ig::renderFrame(*caster, map, pose, in);
}

TEST(MultiresCaster, IdenticalImagesForAnyThreadCount) {
    const TerrainMap& map = synthetic512();
    const Intrinsics in = Intrinsics::fromFov(200, 120, ig::degToRad(60), 4);
    for (const Pose& pose : ig::sweepPoses(map, 4)) {
        for (int levels : {0, ig::kLevelsAuto}) {
            for (int sub : {1, 2}) {
                const auto one = renderWith(map, pose, in, levels, 1, sub);
                for (int threads : {2, 4}) {
                    const auto many = renderWith(map, pose, in, levels, threads, sub);
                    ASSERT_TRUE(one.color == many.color) << threads << " threads";
                    ASSERT_EQ(0, std::memcmp(one.depth.data(), many.depth.data(),
                                             one.depth.size() * sizeof(float)));
                    EXPECT_EQ(one.stats.steps, many.stats.steps);
                }
            }
        }
    }
}

// The four-column AVX2 kernel against one column at a time: the same image bit for bit, the
// same steps and restarts, over sweeps of real and synthetic terrain on the single level, at a
// width that leaves a partial packet. Skipped where the processor lacks AVX2.
TEST(FastCaster, FourColumnPacketsGiveTheOneColumnImage) {
    const std::string missing = ig::casterKernelMissing(ig::CasterKernel::Avx2);
    if (!missing.empty()) GTEST_SKIP() << "the processor lacks " << missing;
    const TerrainMap puget = ig::loadPugetSound();
    const TerrainMap goleta = ig::loadGoleta();
    const Intrinsics in = Intrinsics::fromFov(203, 117, ig::degToRad(60), 4);
    std::uint64_t pixels = 0;
    for (const TerrainMap* map : {&puget, &goleta, &synthetic512()}) {
        for (const Pose& pose : ig::sweepPoses(*map, 12)) {
            for (int levels : {0}) {
                ig::RenderOptions options;
                options.levels = levels;
                options.threads = 1;
                options.kernel = ig::CasterKernel::Avx2;
                const auto packets = ig::makeCaster(CasterKind::Fast, *map, options);
                options.kernel = ig::CasterKernel::Scalar;
                const auto columns = ig::makeCaster(CasterKind::Fast, *map, options);
                const auto a = ig::renderFrame(*packets, *map, pose, in);
                const auto b = ig::renderFrame(*columns, *map, pose, in);
                ASSERT_EQ(a.stats.kernel, "avx2");
                ASSERT_EQ(b.stats.kernel, "scalar");
                ASSERT_TRUE(a.color == b.color) << "levels " << levels;
                ASSERT_EQ(
                    0, std::memcmp(a.depth.data(), b.depth.data(), a.depth.size() * sizeof(float)));
                EXPECT_EQ(a.stats.steps, b.stats.steps);
                EXPECT_EQ(a.stats.restarts, b.stats.restarts);
                pixels += a.color.size();
            }
        }
    }
    EXPECT_GT(pixels, 0u);
}

// The multiresolution caster's row batches (four lanes with AVX2, eight with AVX-512) against its
// rays one by one: each lane of a batch marches from where the ray below the batch stopped (one
// by one, from the row below's hit) and proves its coherence against that ray, so the two may
// differ only where the proofs differ (a restarted row is then cast exactly); the hits are
// otherwise the same. Both widths where the processor has them; skipped where it has neither.
TEST(MultiresCaster, RowBatchesAgreeWithRowByRow) {
    if (!ig::casterKernelMissing(ig::CasterKernel::Avx2).empty()) {
        GTEST_SKIP() << "the processor lacks " << ig::casterKernelMissing(ig::CasterKernel::Avx2);
    }
    const TerrainMap puget = ig::loadPugetSound();
    const TerrainMap goleta = ig::loadGoleta();
    const Intrinsics in = Intrinsics::fromFov(203, 117, ig::degToRad(60), 4);
    for (const ig::CasterKernel kernel : {ig::CasterKernel::Avx2, ig::CasterKernel::Avx512}) {
        if (!ig::casterKernelMissing(kernel).empty()) continue;  // never a kernel against itself
        std::uint64_t pixels = 0, same = 0, depthClose = 0, depthBits = 0;
        int poses = 0;
        double worst = 0.0;
        for (const TerrainMap* map : {&puget, &goleta, &synthetic512()}) {
            for (const Pose& pose : ig::sweepPoses(*map, 12)) {
                ig::RenderOptions options;
                options.levels = ig::kLevelsAuto;
                options.threads = 1;
                options.kernel = kernel;
                // Two rays per pixel on every third pose: the sub-rays in batches too.
                options.supersample = ++poses % 3 == 0 ? 2 : 1;
                const auto batches = ig::makeCaster(CasterKind::Fast, *map, options);
                options.kernel = ig::CasterKernel::Scalar;
                const auto rows = ig::makeCaster(CasterKind::Fast, *map, options);
                const auto a = ig::renderFrame(*batches, *map, pose, in);
                const auto b = ig::renderFrame(*rows, *map, pose, in);
                worst = std::max(worst, ig::meanAbsErrorPct(a.color, b.color));
                for (std::size_t i = 0; i < a.color.size(); ++i) {
                    same += a.color[i] == b.color[i];
                    const float da = a.depth[i], db = b.depth[i];
                    depthClose += (std::isinf(da) && std::isinf(db)) ||
                                  std::abs(da - db) <= 1e-3f * std::max(da, db);
                    depthBits += std::memcmp(&da, &db, sizeof(float)) == 0;
                }
                pixels += a.color.size();
            }
        }
        std::printf(
            "%s: batches vs rows: %.4f %% identical colours, %.4f %% identical depths, %.4f %% "
            "within 0.1 %%, worst frame MAE %.4f %%\n",
            std::string(ig::casterKernelName(kernel)).c_str(), 100.0 * same / pixels,
            100.0 * depthBits / pixels, 100.0 * depthClose / pixels, worst);
        // Measured: every colour; every depth within 0.1 %, all but 3 of 949 500 to the bit
        // (docs/design/multires.md says where they may differ).
        EXPECT_EQ(same, pixels) << ig::casterKernelName(kernel);
        EXPECT_EQ(depthClose, pixels) << ig::casterKernelName(kernel);
        EXPECT_GE(depthBits, pixels - pixels / 100000) << ig::casterKernelName(kernel);
        EXPECT_EQ(worst, 0.0) << ig::casterKernelName(kernel);
    }
}

// A long march passes the max-height nodes its rays stay above (RenderOptions::skipNodes): the
// image must be bit for bit the one sampling every grid line, in batches (four and eight lanes)
// and one by one; over the sweep poses and over grazing views, where rays pass far over low
// ground before they meet a hill (and where the passes must actually happen: fewer steps).
TEST(MultiresCaster, PassingNodesChangesNoPixel) {
    const TerrainMap goleta = ig::loadGoleta();
    const Intrinsics in = Intrinsics::fromFov(203, 117, ig::degToRad(60), 4);
    // A gently rolling plain (heights in centimetres: long waves of a few metres, 2 m of noise),
    // where grazing rays pass a few metres over the ground for hundreds of cells.
    TerrainMap plain(512, 512, 10.0, 10.0, 0.01, 0.0);
    std::mt19937 rng(5);
    std::uniform_int_distribution<int> noise(0, 200);
    for (int y = 0; y < 512; ++y) {
        for (int x = 0; x < 512; ++x) {
            const double wave = 300.0 * std::sin(x * 0.031) * std::cos(y * 0.023);
            plain.setRaw(x, y, static_cast<std::uint16_t>(1000.0 + wave + noise(rng)));
        }
    }
    plain.updateRange();
    plain.shadeFromHeights();
    std::vector<std::pair<const TerrainMap*, Pose>> views;
    const TerrainMap& flat = plain;
    for (const TerrainMap* map : {&puget(), &goleta, &synthetic512(), &flat}) {
        for (const Pose& pose : ig::sweepPoses(*map, 8))
            views.emplace_back(map, pose);
        // Grazing: 20 m over the lowest ground of a corner, looking level across the map.
        for (const double yawDeg : {20.0, 45.0, 70.0}) {
            Pose pose;
            const double x = 0.1 * map->extentX(), y = 0.1 * map->extentY();
            pose.position = {x, y, map->surfaceHeight(x, y) + 20.0};
            pose.yaw = ig::degToRad(yawDeg);
            pose.pitch = ig::degToRad(-0.5);
            views.emplace_back(map, pose);
        }
    }
    std::uint64_t stepsWith = 0, stepsWithout = 0, pixels = 0;
    for (const auto& [map, pose] : views) {
        for (const ig::CasterKernel kernel :
             {ig::CasterKernel::Avx2, ig::CasterKernel::Avx512, ig::CasterKernel::Scalar}) {
            // Each kernel the processor has, with and without passing nodes.
            if (!ig::casterKernelMissing(kernel).empty()) continue;
            {
                ig::RenderOptions options;
                options.levels = ig::kLevelsAuto;
                options.threads = 1;
                options.kernel = kernel;
                const auto with = ig::makeCaster(CasterKind::Fast, *map, options);
                options.skipNodes = false;
                const auto without = ig::makeCaster(CasterKind::Fast, *map, options);
                const auto a = ig::renderFrame(*with, *map, pose, in);
                const auto b = ig::renderFrame(*without, *map, pose, in);
                ASSERT_TRUE(a.color == b.color) << ig::casterKernelName(kernel);
                ASSERT_EQ(
                    0, std::memcmp(a.depth.data(), b.depth.data(), a.depth.size() * sizeof(float)));
                stepsWith += a.stats.steps;
                stepsWithout += b.stats.steps;
                pixels += a.color.size();
            }
        }
    }
    std::printf("passing nodes: %.2f steps/px against %.2f sampling every line\n",
                static_cast<double>(stepsWith) / pixels,
                static_cast<double>(stepsWithout) / pixels);
    EXPECT_LT(stepsWith, stepsWithout);
}

TEST(MultiresCaster, NearTerrainIsLevelZeroSampledOnGridLines) {
    // Where every hit is nearer than the level-0 distance, auto levels find the level-0 hits
    // between the grid lines the exact caster's lie between: depths within a cell's length
    // along the ray of the exact ones, colours close.
    const TerrainMap& map = synthetic512();
    const Intrinsics in = Intrinsics::fromFov(96, 64, ig::degToRad(60));
    Pose pose;
    pose.position = {2500.0, 2500.0, map.surfaceHeight(2500.0, 2500.0) + 150.0};
    pose.pitch = ig::degToRad(-60.0);
    const auto single = renderWith(map, pose, in, 0, 1);
    const auto multi = renderWith(map, pose, in, ig::kLevelsAuto, 1);
    const double d0 = in.focal * map.spacingX();
    float far = 0.0f;
    double worstRel = 0.0;
    for (std::size_t i = 0; i < single.depth.size(); ++i) {
        far = std::max(far, single.depth[i]);
        worstRel = std::max(worstRel,
                            std::abs(double(multi.depth[i]) - single.depth[i]) / single.depth[i]);
    }
    ASSERT_LT(far, d0);
    const double mae = ig::meanAbsErrorPct(multi.color, single.color);
    std::printf("near terrain: auto vs level 0 worst depth %.4f %%, colour MAE %.4f %%\n",
                100.0 * worstRel, mae);
    EXPECT_LT(worstRel, 0.01);
    EXPECT_LT(mae, 0.2);
}

// The multiresolution caster against the exact single level where every hit is nearer than
// the level-0 distance, in the cases its march treats apart: every heading (both major axes,
// both directions), the eye outside the map looking in, rays leaving through the map's sides,
// cells that are not square, the eye within a cell of the terrain. Depths stay within the
// length of one cell along the ray of the exact ones wherever both hit, and sky stays sky.
TEST(MultiresCaster, NearTerrainAgreesWithLevelZeroInEveryCase) {
    // 257 x 193 samples at 12 x 7 m: hills, so hits are spread over the cells.
    TerrainMap map(257, 193, 12.0, 7.0, 0.05, 100.0);
    for (int y = 0; y < map.height(); ++y) {
        for (int x = 0; x < map.width(); ++x) {
            const double h = 400.0 + 300.0 * std::sin(x * 0.07) * std::cos(y * 0.05) +
                             80.0 * std::sin(x * 0.31 + y * 0.17);
            map.setRaw(x, y, static_cast<std::uint16_t>(std::lround(h / 0.05)));
        }
    }
    map.updateRange();
    const Intrinsics in = Intrinsics::fromFov(160, 120, ig::degToRad(50));
    const double d0 = in.focal * std::max(map.spacingX(), map.spacingY());
    const double cell = std::hypot(map.spacingX(), map.spacingY());
    struct Case {
        double x, y, above, yaw, pitch;
    };
    std::vector<Case> cases;
    for (double yaw : {0.0, 37.0, 90.0, 135.0, 180.0, 225.0, 300.0})
        cases.push_back({1540.0, 670.0, 60.0, yaw, -25.0});
    cases.push_back({-300.0, 670.0, 700.0, 0.0, -15.0});    // outside, looking in along x
    cases.push_back({1540.0, -250.0, 700.0, 90.0, -20.0});  // outside, looking in along y
    cases.push_back({3000.0, 1300.0, 300.0, 10.0, -30.0});  // rays leave through a side
    cases.push_back({1540.0, 670.0, 3.0, 45.0, -10.0});     // the eye within a cell of the terrain
    std::uint64_t both = 0, close = 0, sky = 0, skyAgree = 0, pixels = 0;
    for (const Case& c : cases) {
        Pose pose;
        const double ground = map.surfaceHeight(std::clamp(c.x, 0.0, map.extentX()),
                                                std::clamp(c.y, 0.0, map.extentY()));
        pose.position = {c.x, c.y, ground + c.above};
        pose.yaw = ig::degToRad(c.yaw);
        pose.pitch = ig::degToRad(c.pitch);
        const auto single = renderWith(map, pose, in, 0, 1);
        const auto multi = renderWith(map, pose, in, ig::kLevelsAuto, 1);
        for (std::size_t i = 0; i < single.depth.size(); ++i) {
            const float a = single.depth[i], b = multi.depth[i];
            ++pixels;
            if (std::isinf(a) || std::isinf(b)) {
                ++sky;
                skyAgree += std::isinf(a) && std::isinf(b);
                continue;
            }
            if (!(a < 0.9 * d0)) continue;  // past the level-0 distance: coarser levels
            ++both;
            close += std::abs(double(a) - b) <= cell;
        }
    }
    std::printf(
        "near terrain, %zu cases: %.3f %% of %llu near hits within a cell of level 0's, "
        "%.3f %% of %llu sky pixels sky in both\n",
        cases.size(), 100.0 * close / both, static_cast<unsigned long long>(both),
        100.0 * skyAgree / sky, static_cast<unsigned long long>(sky));
    ASSERT_GT(both, pixels / 2);
    EXPECT_GE(close, both * 995 / 1000);
    EXPECT_GE(skyAgree, sky * 99 / 100);
}

// Where the view's heading crosses 45 degrees, the columns on either side march along different
// axes. The multiresolution caster's hit between two grid lines must not depend on the axis (in
// the step where the ray goes under, it interpolates through the node where the track crosses a
// minor grid line too), or a seam shows down the image where cells span many pixels: no column
// may change more across it than the single level's worst column does.
TEST(MultiresCaster, NoSeamWhereTheMarchAxisChanges) {
    const TerrainMap& map = puget();
    const Intrinsics in = Intrinsics::fromFov(360, 240, ig::degToRad(60));
    Pose pose;
    pose.position = {30000.0, 20000.0, map.surfaceHeight(30000.0, 20000.0) + 150.0};
    pose.yaw = ig::degToRad(45.0);
    pose.pitch = ig::degToRad(-12.0);
    auto worstColumnStep = [&](int levels) {
        const auto f = renderWith(map, pose, in, levels, 1);
        long worst = 0;
        for (int x = 1; x < in.width; ++x) {
            long step = 0;
            for (int y = in.height / 2; y < in.height; ++y) {
                const ig::Rgb8 a = f.color[static_cast<std::size_t>(y) * in.width + x];
                const ig::Rgb8 b = f.color[static_cast<std::size_t>(y) * in.width + x - 1];
                step += std::abs(a.r - b.r) + std::abs(a.g - b.g) + std::abs(a.b - b.b);
            }
            worst = std::max(worst, step);
        }
        return worst;
    };
    const long single = worstColumnStep(0), multi = worstColumnStep(ig::kLevelsAuto);
    std::printf("worst colour step between columns: single level %ld, multires %ld\n", single,
                multi);
    EXPECT_LE(multi, single + single / 4);
}

// Mean colour error of levels 0 and auto against a 4x4-supersampled reference over a sweep.
struct SupersampledError {
    double single = 0.0, multi = 0.0;
};

SupersampledError errorAgainstSupersampled(const TerrainMap& map, int poses, int w, int h) {
    constexpr int kF = 4;
    const auto reference = ig::makeCaster(CasterKind::Reference, map);
    const Intrinsics in = Intrinsics::fromFov(w, h, ig::degToRad(60));
    const Intrinsics fine = Intrinsics::fromFov(w * kF, h * kF, ig::degToRad(60));
    SupersampledError e;
    int k = 0;
    for (const Pose& pose : ig::sweepPoses(map, poses)) {
        const auto ref =
            ig::boxDownsample(ig::renderFrame(*reference, map, pose, fine).color, w, h, kF);
        const double single = ig::meanAbsErrorPct(renderWith(map, pose, in, 0, 0).color, ref);
        const double multi =
            ig::meanAbsErrorPct(renderWith(map, pose, in, ig::kLevelsAuto, 0).color, ref);
        e.single += single / poses;
        e.multi += multi / poses;
        ++k;
    }
    return e;
}

TEST(MultiresCaster, NoWorseThanSingleLevelAgainstSupersampledReferencePuget) {
    const SupersampledError e = errorAgainstSupersampled(puget(), 12, 64, 40);
    std::printf("Puget Sound vs 4x4 reference: single-level MAE %.3f %%, multires %.3f %%\n",
                e.single, e.multi);
    EXPECT_LE(e.multi, e.single);
}

TEST(MultiresCaster, NoWorseThanSingleLevelAgainstSupersampledReferenceSynthetic) {
    const SupersampledError e = errorAgainstSupersampled(synthetic1024(), 12, 64, 40);
    std::printf("synthetic 1024^2 vs 4x4 reference: single-level MAE %.3f %%, multires %.3f %%\n",
                e.single, e.multi);
    EXPECT_LE(e.multi, e.single);
}

// Frame-to-frame differences along the slow flight with `levels` levels.
std::vector<double> flightDifferences(const TerrainMap& map, int levels, int frames) {
    ig::RenderOptions options;
    options.levels = levels;
    return vig_test::slowFlightDifferences(*ig::makeCaster(CasterKind::Fast, map, options), map,
                                           frames);
}

TEST(MultiresCaster, NoSpikesAlongASlowFlight) {
    const TerrainMap& map = synthetic1024();
    std::vector<double> multi = flightDifferences(map, ig::kLevelsAuto, 40);
    std::vector<double> single = flightDifferences(map, 0, 40);
    const double mMulti = vig_test::median(multi), mSingle = vig_test::median(single);
    const double worst = *std::max_element(multi.begin(), multi.end());
    std::printf("slow flight: multires median %.3f %% worst %.3f %%; single-level median %.3f %%\n",
                mMulti, worst, mSingle);
    ASSERT_GT(mMulti, 0.0);
    EXPECT_LE(worst, 2.0 * mMulti);
    // Coarser levels far away do not flicker more than level 0 does.
    EXPECT_LE(mMulti, 1.05 * mSingle);
}

TEST(MultiresCaster, SupersamplingAveragesSubRays) {
    // With two rays per pixel, each pixel is the mean of the exact hits through (x + 0.5,
    // y + 0.25) and (x + 0.5, y + 0.75), and its depth the nearer of the two.
    const TerrainMap& map = synthetic512();
    const Intrinsics in = Intrinsics::fromFov(64, 40, ig::degToRad(60));
    Pose pose;
    pose.position = {2000.0, 2500.0, map.surfaceHeight(2000.0, 2500.0) + 200.0};
    pose.yaw = ig::degToRad(30.0);
    pose.pitch = ig::degToRad(-8.0);
    const auto ss = renderWith(map, pose, in, 0, 1, 2);
    EXPECT_EQ(ss.stats.rays, static_cast<std::uint64_t>(2 * in.width * in.height));
    const ig::Camera cam(pose, in);
    const ig::SkyModel sky;
    int bad = 0, hits = 0;
    for (int y = 0; y < in.height; ++y) {
        for (int x = 0; x < in.width; ++x) {
            int sum[3] = {0, 0, 0};
            float nearest = ig::kSkyDepth;
            for (double sub : {0.25, 0.75}) {
                const glm::dvec3 d = glm::normalize(cam.rayDirection(x + 0.5, y + sub));
                const ig::RayHit hit = ig::intersectTerrain(map, pose.position, d);
                ig::Rgb8 c = ig::skyColor(sky, d.z);
                if (hit.hit) {
                    c = ig::terrainColor(map, sky, hit.point.x, hit.point.y, hit.distance);
                    nearest = std::min(nearest, static_cast<float>(hit.distance));
                }
                sum[0] += c.r;
                sum[1] += c.g;
                sum[2] += c.b;
            }
            const std::size_t i = static_cast<std::size_t>(y) * in.width + x;
            const ig::Rgb8 got = ss.color[i];
            const int diff =
                std::max({std::abs(got.r - (sum[0] + 1) / 2), std::abs(got.g - (sum[1] + 1) / 2),
                          std::abs(got.b - (sum[2] + 1) / 2)});
            if (diff > 1) ++bad;
            if (std::isfinite(nearest)) {
                ++hits;
                EXPECT_NEAR(ss.depth[i], nearest, 1e-4 * nearest) << x << "," << y;
            } else {
                EXPECT_TRUE(std::isinf(ss.depth[i]));
            }
        }
    }
    EXPECT_GT(hits, in.width * in.height / 3);
    EXPECT_LE(bad, in.width * in.height / 200) << "pixels off by more than rounding";
}

TEST(MultiresCaster, SingleLevelMatchesReferenceWhereRaysLeaveThroughTheSides) {
    // Low over a small map near its corner: for every heading some coherent rays leave the map
    // through a side parallel to their major axis (the march's last, partial step) and some
    // through the far end; each pixel's depth must match the reference's to rounding.
    const TerrainMap map = ig::makeSyntheticTerrain(128, 3, 10.0);
    const Intrinsics in = Intrinsics::fromFov(48, 32, ig::degToRad(70));
    const auto reference = ig::makeCaster(CasterKind::Reference, map);
    int hits = 0, sky = 0;
    for (const double corner : {0.1, 0.9}) {
        for (int yawDeg = 0; yawDeg < 360; yawDeg += 30) {
            Pose pose;
            const double x = corner * map.extentX(), y = (1.0 - corner) * map.extentY();
            pose.position = {x, y, map.surfaceHeight(x, y) + 40.0};
            pose.yaw = ig::degToRad(yawDeg + 7.0);
            pose.pitch = ig::degToRad(-4.0);
            const auto ref = ig::renderFrame(*reference, map, pose, in);
            const auto got = renderWith(map, pose, in, 0, 1);
            for (std::size_t i = 0; i < ref.depth.size(); ++i) {
                if (std::isinf(ref.depth[i])) {
                    ++sky;
                    EXPECT_TRUE(std::isinf(got.depth[i])) << "yaw " << yawDeg << " pixel " << i;
                } else {
                    ++hits;
                    EXPECT_NEAR(got.depth[i], ref.depth[i], 1e-3 * ref.depth[i])
                        << "yaw " << yawDeg << " pixel " << i;
                }
            }
        }
    }
    EXPECT_GT(hits, 1000);
    EXPECT_GT(sky, 1000);
}

TEST(MultiresCaster, LevelsParse) {
    EXPECT_EQ(ig::parseLevels("auto"), ig::kLevelsAuto);
    EXPECT_EQ(ig::parseLevels("0"), 0);
    EXPECT_EQ(ig::parseLevels("3"), 3);
    EXPECT_THROW(ig::parseLevels("-1"), ig::InputError);
    EXPECT_THROW(ig::parseLevels("many"), ig::InputError);
    EXPECT_THROW(ig::parseLevels(""), ig::InputError);
    ig::RenderOptions bad;
    bad.supersample = 9;  // (0 is kSupersampleAuto: chosen per frame)
    EXPECT_THROW(ig::makeCaster(CasterKind::Fast, synthetic512(), bad), ig::InputError);
    bad.supersample = -1;
    EXPECT_THROW(ig::makeCaster(CasterKind::Fast, synthetic512(), bad), ig::InputError);
    bad.supersample = ig::kSupersampleAuto;
    bad.supersampleMax = 9;
    EXPECT_THROW(ig::makeCaster(CasterKind::Fast, synthetic512(), bad), ig::InputError);
}

}  // namespace
