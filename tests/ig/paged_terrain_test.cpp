#include "ig/paged_terrain.hpp"

#include <gtest/gtest.h>
#include <unistd.h>

#include <glm/geometric.hpp>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "common/small_terrain_db.hpp"
#include "ig/caster.hpp"
#include "ig/pyramid.hpp"
#include "ig/synthetic.hpp"
#include "ig/terrain_db_build.hpp"

namespace ig {
namespace {

// A 1025 x 1025 synthetic map (10 m) in tiles of 16: 4096 level-0 tiles, 7.3 MB of them, paged
// through a cache of 1 MB.
struct PagedFixture {
    TerrainMap map;
    std::string path;
    PagedFixture() : map(makeSyntheticTerrain(1024, 3)) {
        path = vig_test::testTmpPath("paged_terrain", "map_" + std::to_string(::getpid()) + ".db");
        auto source = mapRowSource(map);
        DbBuildOptions o;
        o.tileSize = 16;
        buildTerrainDb(*source, path, o);
    }
    ~PagedFixture() { std::filesystem::remove(path); }
};

const PagedFixture& fixture() {
    static const PagedFixture f;
    return f;
}

PagedTerrain::Options smallBudget() {
    PagedTerrain::Options o;
    o.cache.budgetBytes = std::size_t{1} << 20;
    return o;
}

const Intrinsics kView = Intrinsics::fromFov(64, 40, 50.0 * M_PI / 180.0);

// Low poses over the map, looking down 22..47 degrees (the top of the image below the horizon) in
// every direction: a frame's footprint is a few hundred tiles, the sweep's union most of the map.
std::vector<Pose> lowSweep(const TerrainMap& map, int count) {
    std::vector<Pose> poses;
    for (int i = 0; i < count; ++i) {
        const double f = (i + 0.5) / count;
        Pose p;
        p.position.x = map.extentX() * (0.15 + 0.7 * std::fmod(f * 3.7, 1.0));
        p.position.y = map.extentY() * (0.15 + 0.7 * f);
        p.position.z = map.surfaceHeight(p.position.x, p.position.y) + 30.0 + 400.0 * f;
        p.yaw = 2.0 * M_PI * std::fmod(f * 5.3, 1.0);
        p.pitch = -(22.0 + 25.0 * std::fmod(f * 2.9, 1.0)) * M_PI / 180.0;
        poses.push_back(p);
    }
    return poses;
}

void expectSameImage(const RenderedFrame& a, const RenderedFrame& b, const std::string& what) {
    ASSERT_EQ(a.color.size(), b.color.size());
    std::size_t diff = 0;
    for (std::size_t i = 0; i < a.color.size(); ++i)
        diff += !(a.color[i] == b.color[i]) || a.depth[i] != b.depth[i];
    EXPECT_EQ(diff, 0u) << what << ": pixels differ";
    for (std::size_t i = 0; i < a.controlPoints.size(); ++i) {
        EXPECT_EQ(a.controlPoints[i].world, b.controlPoints[i].world)
            << what << ": control point " << i;
    }
}

// Pixels whose colour differs between two frames, and the sum over the frame of the mean
// absolute difference of their channels (levels of 255).
std::pair<std::size_t, double> colourDifference(const RenderedFrame& a, const RenderedFrame& b) {
    std::size_t differ = 0;
    double sum = 0.0;
    for (std::size_t i = 0; i < a.color.size(); ++i) {
        const int d = std::abs(a.color[i].r - b.color[i].r) +
                      std::abs(a.color[i].g - b.color[i].g) + std::abs(a.color[i].b - b.color[i].b);
        differ += d > 0;
        sum += d / 3.0;
    }
    return {differ, sum};
}

// The fast caster with every level over the map in memory and over `paged`'s map and pyramid.
struct FastTwins {
    std::unique_ptr<Caster> inMemory, fromCache;
    FastTwins(const TerrainMap& map, const PagedTerrain& paged) {
        RenderOptions o;
        o.levels = kLevelsAuto;
        inMemory = makeCaster(CasterKind::Fast, map, o);
        o.pyramid = paged.pyramid();
        o.slopes = paged.slopes();
        fromCache = makeCaster(CasterKind::Fast, paged.map(), o);
    }
};

TEST(PagedTerrain, EqualsTheInMemoryRenderBitForBitOverASweep) {
    const PagedFixture& f = fixture();
    const TerrainDb db = TerrainDb::open(f.path);
    PagedTerrain paged(db, smallBudget());
    EXPECT_EQ(paged.map().maxHeight(), f.map.maxHeight());
    EXPECT_EQ(paged.map().minHeight(), f.map.minHeight());
    for (const CasterKind kind : {CasterKind::Reference, CasterKind::Naive}) {
        const auto inMemory = makeCaster(kind, f.map);
        const auto fromCache = makeCaster(kind, paged.map());
        int pose = 0;
        for (const Pose& p : lowSweep(f.map, 24)) {
            const Camera camera(p, kView);
            const PagedFrameStats st = paged.prepare(camera, true);
            EXPECT_GT(st.required, 0u);
            EXPECT_EQ(st.substituted, 0u) << "pose " << pose << " of " << st.required << " tiles";
            const RenderedFrame a = renderFrame(*inMemory, f.map, p, kView);
            const RenderedFrame b = renderFrame(*fromCache, paged.map(), p, kView);
            expectSameImage(a, b, std::string(casterName(kind)) + " pose " + std::to_string(pose));
            // Only the frame's tiles stay placed, and the map's memory follows them.
            EXPECT_EQ(paged.placedTiles(), st.required);
            EXPECT_LE(paged.residentMapBytes(), paged.placedBytes());
            EXPECT_GT(paged.residentMapBytes(), 0u);
            ++pose;
        }
    }
    // The map's arrays take 7 bytes a sample, 7.4 MB: the pages of one frame's tiles stay.
    const std::size_t wholeMap = static_cast<std::size_t>(f.map.width()) * f.map.height() * 7;
    std::printf("map pages resident after the sweep: %zu bytes for %zu tiles (whole map %zu)\n",
                paged.residentMapBytes(), paged.placedTiles(), wholeMap);
    EXPECT_LT(paged.residentMapBytes(), wholeMap / 4)
        << paged.residentMapBytes() << " bytes resident";
    const TileCacheStats s = paged.cache().stats();
    EXPECT_GT(s.evictions, 0u) << "the sweep must page";
    EXPECT_GT(s.bytesRead, paged.cache().budgetBytes());
    EXPECT_LE(paged.cache().residentBytes(), paged.cache().budgetBytes());
    EXPECT_EQ(s.failures, 0u);
}

// The placing tells its progress in order, step by step, and gives back and backs pages a few at
// a time when asked to (a renderer process's signs of life: thousands of tiles can take the
// kernel a second): each frame's steps run Footprint .. StandIns without going back, frames
// call Released and Backed more than once, and the map is the in-memory one to the bit all the
// same.
TEST(PagedTerrain, PlacingReportsItsStepsInOrderAndAdvisesPagesAFewAtATime) {
    const PagedFixture& f = fixture();
    const TerrainDb db = TerrainDb::open(f.path);
    PagedTerrain::Options o = smallBudget();
    o.mapBudgetBytes = std::size_t{256} << 10;  // pages given back every few frames
    o.progressPages = 4;
    std::vector<PlacingStep> steps;
    o.progress = [&steps](PlacingStep s) { steps.push_back(s); };
    PagedTerrain paged(db, o);
    const auto inMemory = makeCaster(CasterKind::Reference, f.map);
    const auto fromCache = makeCaster(CasterKind::Reference, paged.map());
    int pose = 0, released = 0, backed = 0, manyReleased = 0, manyBacked = 0;
    for (const Pose& p : lowSweep(f.map, 16)) {
        steps.clear();
        paged.prepare(Camera(p, kView), true);
        ASSERT_GE(steps.size(), 4u) << "pose " << pose;
        EXPECT_EQ(steps.front(), PlacingStep::Footprint) << "pose " << pose;
        EXPECT_EQ(steps[1], PlacingStep::Requested) << "pose " << pose;
        EXPECT_EQ(steps.back(), PlacingStep::StandIns) << "pose " << pose;
        EXPECT_TRUE(std::is_sorted(steps.begin(), steps.end())) << "pose " << pose;
        const auto count = [&steps](PlacingStep s) {
            return static_cast<int>(std::count(steps.begin(), steps.end(), s));
        };
        EXPECT_GE(count(PlacingStep::StandIns), 1) << "pose " << pose;
        EXPECT_GE(count(PlacingStep::Decided), 1) << "pose " << pose;
        released += count(PlacingStep::Released);
        backed += count(PlacingStep::Backed);
        manyReleased += count(PlacingStep::Released) > 1;
        manyBacked += count(PlacingStep::Backed) > 1;
        expectSameImage(renderFrame(*inMemory, f.map, p, kView),
                        renderFrame(*fromCache, paged.map(), p, kView),
                        "pose " + std::to_string(pose));
        ++pose;
    }
    std::printf("progress: %d calls after pages given back, %d after pages backed\n", released,
                backed);
    EXPECT_GT(manyReleased, 0) << "no frame gave back more than 4 pages";
    EXPECT_GT(manyBacked, 0) << "no frame backed more than 4 pages";
}

// The fast caster over the paged map and the sparse pyramid the paging fills, at every level
// setting and with its kernels, through a cache far smaller than the map and its pyramid: with
// all levels (the default) or level 0 alone, each frame of the sweep is the in-memory render to
// the bit (colour and depth). With a few coarser levels the in-memory pyramid's nodes bound only
// the levels kept, the database's every level (looser): the marches skip elsewhere, and a hit
// found by interpolation between grid lines from another start may round differently (one
// pixel of the sweep, 5 cm at 1.5 km); colours stay equal and depths within 1e-4 of range.
TEST(PagedTerrain, FastCasterEqualsTheInMemoryRenderBitForBitOverASweep) {
    const PagedFixture& f = fixture();
    const TerrainDb db = TerrainDb::open(f.path);
    struct Case {
        int levels;
        CasterKernel kernel;
        int supersample;
    };
    for (const Case c :
         {Case{kLevelsAuto, CasterKernel::Auto, 1}, Case{0, CasterKernel::Auto, 1},
          Case{2, CasterKernel::Scalar, 1}, Case{kLevelsAuto, CasterKernel::Scalar, 3},
          Case{kLevelsAuto, CasterKernel::Auto, kSupersampleAuto}}) {
        SCOPED_TRACE("levels " + std::to_string(c.levels) + " kernel " +
                     std::string(casterKernelName(c.kernel)) + " supersample " +
                     std::to_string(c.supersample));
        PagedTerrain::Options po = smallBudget();
        po.cache.budgetBytes = std::size_t{5} << 18;  // 1.25 MB
        po.pyramid = true;
        po.levels = c.levels;
        PagedTerrain paged(db, po);
        ASSERT_TRUE(paged.pyramid());
        RenderOptions o;
        o.levels = c.levels;
        o.kernel = c.kernel;
        o.supersample = c.supersample;
        const auto inMemory = makeCaster(CasterKind::Fast, f.map, o);
        o.pyramid = paged.pyramid();
        o.slopes = paged.slopes();
        const auto fromCache = makeCaster(CasterKind::Fast, paged.map(), o);
        EXPECT_EQ(paged.pyramid()->levelCount(), TerrainPyramid(f.map, c.levels).levelCount());
        int pose = 0;
        std::size_t coarse = 0;
        for (const Pose& p : lowSweep(f.map, 24)) {
            const Camera camera(p, kView);
            const PagedFrameStats st = paged.prepare(camera, true);
            EXPECT_EQ(st.substituted, 0u) << "pose " << pose << " of " << st.required << " tiles";
            EXPECT_EQ(st.nodesMissing, 0u) << "pose " << pose;
            EXPECT_GT(st.nodesRequired, 0u);
            coarse += st.requiredCoarse;
            const RenderedFrame a = renderFrame(*inMemory, f.map, p, kView);
            const RenderedFrame b = renderFrame(*fromCache, paged.map(), p, kView);
            if (c.levels == kLevelsAuto || c.levels == 0) {
                expectSameImage(a, b, "fast pose " + std::to_string(pose));
            } else {
                std::size_t colour = 0, depth = 0;
                for (std::size_t i = 0; i < a.color.size(); ++i) {
                    colour += !(a.color[i] == b.color[i]);
                    depth += !(std::abs(a.depth[i] - b.depth[i]) <= 1e-4 * std::abs(a.depth[i]));
                }
                EXPECT_EQ(colour + depth, 0u) << "pose " << pose;
            }
            // With every level the nodes are the in-memory pyramid's, so the marches are too.
            // With fewer, the database's nodes also bound the levels the caster leaves out
            // (looser): other skips, the same image.
            if (c.levels == kLevelsAuto) {
                EXPECT_EQ(a.stats.steps, b.stats.steps) << "pose " << pose;
            }
            ++pose;
        }
        // The map and its pyramid take about 9.3 bytes a sample; the pages written stay under
        // the budget's bound (the fast caster also reads pages never written, nodes of no
        // bound, which map the shared zero page: mincore counts them, the memory does not).
        const std::size_t whole = static_cast<std::size_t>(f.map.width()) * f.map.height() * 9;
        std::printf(
            "pages written and held after the sweep: %zu bytes (whole map and pyramid "
            "%zu)\n",
            paged.placedBytes(), whole);
        EXPECT_LT(paged.placedBytes(), whole / 2);
        const TileCacheStats s = paged.cache().stats();
        EXPECT_GT(s.evictions, 0u) << "the sweep must page";
        EXPECT_EQ(s.failures, 0u);
        if (c.levels != 0) {
            EXPECT_GT(coarse, 0u) << "coarser levels paged";
        } else {
            EXPECT_EQ(coarse, 0u);
        }
    }
}

// Node tiles that never come leave their nodes reading "no bound" (nodes are stored complemented
// in the sparse pyramid): the fast caster then looks closer where it would have skipped, and
// draws the same image, to the bit.
TEST(PagedTerrain, MissingNodeTilesLeaveTheFastCastersImageUnchanged) {
    const PagedFixture& f = fixture();
    const TerrainDb db = TerrainDb::open(f.path);
    PagedTerrain::Options po;
    po.cache.budgetBytes = std::size_t{4} << 20;
    po.pyramid = true;
    po.levels = kLevelsAuto;
    PagedTerrain paged(db, po);
    EXPECT_EQ(paged.pyramid()->nodeMaxRaw(1, 0, 0), 65535) << "a node never placed";
    // Every node tile below the cache's pinned levels (those are loaded at construction).
    paged.cache().setWithheld([](const TileKey& k) { return k.kind == TileKind::Nodes; });
    const FastTwins twins(f.map, paged);
    const Caster* inMemory = twins.inMemory.get();
    const Caster* fromCache = twins.fromCache.get();
    std::uint64_t stepsWhole = 0, stepsPaged = 0;
    std::size_t missing = 0;
    int pose = 0;
    for (const Pose& p : lowSweep(f.map, 8)) {
        const Camera camera(p, kView);
        const PagedFrameStats st = paged.prepare(camera, true);
        EXPECT_EQ(st.substituted, 0u);
        missing += st.nodesMissing;
        const RenderedFrame a = renderFrame(*inMemory, f.map, p, kView);
        const RenderedFrame b = renderFrame(*fromCache, paged.map(), p, kView);
        expectSameImage(a, b, "no nodes, pose " + std::to_string(pose));
        stepsWhole += a.stats.steps;
        stepsPaged += b.stats.steps;
        ++pose;
    }
    std::printf("without node tiles: %zu node tiles missing, %llu steps against %llu\n", missing,
                static_cast<unsigned long long>(stepsPaged),
                static_cast<unsigned long long>(stepsWhole));
    EXPECT_GT(missing, 0u);
}

// The slow twin of a stand-in: level-0 tile (tx, ty) of `map` replaced by the bilinear
// upsampling of pyramid level k (global sample positions), its edge samples shared with
// `exactAround` tiles left as they are.
TerrainMap withStandIn(const TerrainMap& map, const TerrainPyramid& pyr, int k, int tx, int ty,
                       int tile) {
    TerrainMap out = map;
    const PyramidLevel& lv = pyr.level(k);
    const int x0 = tx * tile, y0 = ty * tile;
    const int x1 = std::min(x0 + tile, map.width() - 1), y1 = std::min(y0 + tile, map.height() - 1);
    for (int y = y0; y <= y1; ++y) {
        for (int x = x0; x <= x1; ++x) {
            if (x == x0 || y == y0 || x == x1 || y == y1) continue;  // shared with neighbours
            const double u = std::ldexp(static_cast<double>(x), -k);
            const double v = std::ldexp(static_cast<double>(y), -k);
            const int i = std::min(static_cast<int>(u), lv.width - 2);
            const int j = std::min(static_cast<int>(v), lv.height - 2);
            const double fu = u - i, fv = v - j;
            auto at = [&](int a, int b) { return lv.raw(a, b); };
            const double h = (at(i, j) * (1 - fu) + at(i + 1, j) * fu) * (1 - fv) +
                             (at(i, j + 1) * (1 - fu) + at(i + 1, j + 1) * fu) * fv;
            out.setRaw(x, y, static_cast<std::uint16_t>(std::lround(h)));
            const Rgb8 c00 = lv.colors[lv.index(i, j)], c10 = lv.colors[lv.index(i + 1, j)];
            const Rgb8 c01 = lv.colors[lv.index(i, j + 1)];
            const Rgb8 c11 = lv.colors[lv.index(i + 1, j + 1)];
            auto ch = [&](double a, double b, double c, double d) {
                return static_cast<std::uint8_t>(
                    std::lround((a * (1 - fu) + b * fu) * (1 - fv) + (c * (1 - fu) + d * fu) * fv));
            };
            out.setColor(x, y,
                         Rgb8{ch(c00.r, c10.r, c01.r, c11.r), ch(c00.g, c10.g, c01.g, c11.g),
                              ch(c00.b, c10.b, c01.b, c11.b)});
        }
    }
    out.updateRange();
    return out;
}

// The level-0 tile under the image's centre.
std::pair<int, int> centreTile(const RenderedFrame& frame, const Camera& camera, int tile,
                               const TerrainMap& map) {
    const Intrinsics& in = camera.intrinsics();
    const std::size_t c = static_cast<std::size_t>(in.height / 2) * in.width + in.width / 2;
    const glm::dvec3 d =
        glm::normalize(camera.rayDirection(in.width / 2 + 0.5, in.height / 2 + 0.5));
    const glm::dvec3 p = camera.pose().position + static_cast<double>(frame.depth[c]) * d;
    return {static_cast<int>(p.x / map.spacingX()) / tile,
            static_cast<int>(p.y / map.spacingY()) / tile};
}

Pose lookingDown(const TerrainMap& map) {
    Pose p;
    p.position = {0.45 * map.extentX(), 0.4 * map.extentY(), 0.0};
    p.position.z = map.surfaceHeight(p.position.x, p.position.y) + 250.0;
    p.yaw = 0.3;
    p.pitch = -40.0 * M_PI / 180.0;
    return p;
}

TEST(PagedTerrain, WithheldTileGivesTheCoarserLevelsImageWithoutStalling) {
    const PagedFixture& f = fixture();
    const TerrainDb db = TerrainDb::open(f.path);
    const Pose pose = lookingDown(f.map);
    const Camera camera(pose, kView);
    const auto inMemory = makeCaster(CasterKind::Reference, f.map);
    const RenderedFrame full = renderFrame(*inMemory, f.map, pose, kView);
    const auto [tx, ty] = centreTile(full, camera, 16, f.map);

    PagedTerrain paged(db, smallBudget());
    const TileKey withheld{TileKind::Display, 0, tx, ty};
    paged.cache().setWithheld([&](const TileKey& k) { return k == withheld; });
    const PagedFrameStats st = paged.prepare(camera, true);  // returns: the tile never comes
    EXPECT_EQ(st.substituted, 1u);
    EXPECT_EQ(st.failed, 0u);
    EXPECT_EQ(paged.substitutedTiles(), 1u);
    const auto sub = paged.cache().findOrCoarser(withheld);
    ASSERT_TRUE(sub);
    const int k = sub->key.level;
    EXPECT_GT(k, 0);
    const RenderedFrame got =
        renderFrame(*makeCaster(CasterKind::Reference, paged.map()), paged.map(), pose, kView);

    // Exactly the image of the map with that tile taken from level k.
    const TerrainPyramid pyr(f.map);
    const TerrainMap twin = withStandIn(f.map, pyr, k, tx, ty, 16);
    const RenderedFrame expected =
        renderFrame(*makeCaster(CasterKind::Reference, twin), twin, pose, kView);
    expectSameImage(got, expected, "stand-in");

    // And near the full image: the tile shows, coarser, and the rest is unchanged.
    const auto [differ, sum] = colourDifference(full, got);
    std::printf(
        "withheld tile (%d, %d) from level %d: %zu of %zu pixels differ, mean colour "
        "error %.3f levels\n",
        tx, ty, k, differ, full.color.size(), sum / full.color.size());
    EXPECT_GT(differ, 0u) << "the withheld tile is in view";
    EXPECT_LT(sum / full.color.size(), 4.0) << "mean colour error over the frame, levels";

    // The tile arrives: the next frame is the full image again.
    paged.cache().setWithheld(nullptr);
    const PagedFrameStats again = paged.prepare(camera, true);
    EXPECT_EQ(again.substituted, 0u);
    EXPECT_EQ(again.copied, 1u) << "only the stand-in is replaced";
    const RenderedFrame back =
        renderFrame(*makeCaster(CasterKind::Reference, paged.map()), paged.map(), pose, kView);
    expectSameImage(back, full, "after the tile arrived");
}

// The map's budget counts the pages of the frame's new tiles too: flying from one view to a
// distant one, the tiles left behind give their pages back in the frame that places the new
// ones, so the pages held stay within the budget (not the budget and a frame's worth besides).
TEST(PagedTerrain, TheMapBudgetHoldsWithTheFramesNewPagesCounted) {
    const PagedFixture& f = fixture();
    const TerrainDb db = TerrainDb::open(f.path);
    const std::vector<Pose> sweep = lowSweep(f.map, 16);
    const Pose& a = sweep[1];
    const Pose& b = sweep[13];
    const auto alone = [&](const Pose& p) {
        PagedTerrain::Options o = smallBudget();
        o.mapBudgetBytes = std::size_t{1} << 30;
        PagedTerrain paged(db, o);
        paged.prepare(Camera(p, kView), true);
        return paged.placedBytes();
    };
    const std::size_t bytesA = alone(a), bytesB = alone(b);
    PagedTerrain::Options o = smallBudget();
    o.mapBudgetBytes = std::max(bytesA, bytesB) * 6 / 5;
    PagedTerrain paged(db, o);
    paged.prepare(Camera(a, kView), true);
    EXPECT_EQ(paged.placedBytes(), bytesA) << "under the budget, nothing given back";
    const PagedFrameStats st = paged.prepare(Camera(b, kView), true);
    std::printf("pages held: view A %zu bytes, view B %zu, budget %zu, after A then B %zu\n",
                bytesA, bytesB, o.mapBudgetBytes, paged.placedBytes());
    EXPECT_GT(st.released, 0u) << "the tiles of view A gave their pages back";
    EXPECT_LE(paged.placedBytes(), o.mapBudgetBytes);
    // And the frame is whole.
    const auto caster = makeCaster(CasterKind::Reference, f.map);
    expectSameImage(
        renderFrame(*caster, f.map, b, kView),
        renderFrame(*makeCaster(CasterKind::Reference, paged.map()), paged.map(), b, kView),
        "view B");
}

// A stand-in's cell maxima (the bounds the marches skip by) follow its samples over a sweep in
// which a third of the tiles never come: its own written from the coarser level, and its edges
// replaced by exact neighbours placed in later frames. Each frame only the stand-ins written or
// beside a tile written are made again; every stand-in's cells must agree with its samples.
TEST(PagedTerrain, StandInsCellMaximaFollowTheirSamplesAsNeighboursArrive) {
    const PagedFixture& f = fixture();
    const TerrainDb db = TerrainDb::open(f.path);
    PagedTerrain paged(db, smallBudget());
    paged.cache().setWithheld([](const TileKey& k) {
        return k.kind == TileKind::Display && k.level == 0 && (k.tx * 7 + k.ty * 3) % 3 == 0;
    });
    const TerrainMap& m = paged.map();
    const auto raw = [&m](int x, int y) {
        return m.rawHeights()[static_cast<std::size_t>(y) * m.width() + x];
    };
    std::size_t checked = 0;
    // A slow turn and drift: tiles enter the footprint a few at a time beside stand-ins placed
    // in earlier frames.
    Pose p = lowSweep(f.map, 1)[0];
    for (int pose = 0; pose < 36; ++pose) {
        p.yaw += 4.0 * M_PI / 180.0;
        p.position.x += 15.0;
        paged.prepare(Camera(p, kView), true);
        std::size_t wrong = 0;
        for (const TileKey& key : paged.standIns()) {
            if (key.level != 0) continue;
            int x0, y0, tw, th;
            db.layout().tileExtent(key, x0, y0, tw, th);
            for (int cy = y0; cy + 1 < y0 + th; ++cy) {
                for (int cx = x0; cx + 1 < x0 + tw; ++cx) {
                    const std::uint16_t expected = std::max(
                        {raw(cx, cy), raw(cx + 1, cy), raw(cx, cy + 1), raw(cx + 1, cy + 1)});
                    wrong += m.cellMaxRaw(cx, cy) != expected;
                }
            }
            ++checked;
        }
        EXPECT_EQ(wrong, 0u) << "pose " << pose << ": cells whose maximum is not their samples'";
    }
    EXPECT_GT(checked, 100u) << "stand-ins checked over the sweep";
}

// The fast caster with a level-0 tile and a coarser-level tile withheld: neither stalls the
// frame, each is drawn from a coarser resident level, the image stays near the full one, and
// when the tiles arrive the next frame is the full image again, to the bit.
TEST(PagedTerrain, FastCasterWithheldTilesComeFromCoarserLevels) {
    const PagedFixture& f = fixture();
    const TerrainDb db = TerrainDb::open(f.path);
    Pose pose = lookingDown(f.map);
    pose.pitch = -12.0 * M_PI / 180.0;  // far enough to read the coarser levels
    const Camera camera(pose, kView);
    RenderOptions o;
    o.levels = kLevelsAuto;
    const RenderedFrame full =
        renderFrame(*makeCaster(CasterKind::Fast, f.map, o), f.map, pose, kView);
    const auto [tx, ty] = centreTile(full, camera, 16, f.map);
    // A level-2 tile of the frame's footprint.
    const Footprint fp = frameFootprint(camera, db.layout(), db.info(),
                                        LevelSelection::forCamera(kView, db.info(), kLevelsAuto));
    std::vector<TileKey> level2;
    for (const TileKey& k : fp.tiles)
        if (k.kind == TileKind::Display && k.level == 2) level2.push_back(k);
    ASSERT_FALSE(level2.empty());
    const TileKey coarse = level2[level2.size() / 2];
    const TileKey fine{TileKind::Display, 0, tx, ty};

    PagedTerrain::Options po;
    po.cache.budgetBytes = std::size_t{4} << 20;
    po.pyramid = true;
    po.levels = kLevelsAuto;
    PagedTerrain paged(db, po);
    paged.cache().setWithheld([&](const TileKey& k) { return k == fine || k == coarse; });
    o.pyramid = paged.pyramid();
    o.slopes = paged.slopes();
    const auto caster = makeCaster(CasterKind::Fast, paged.map(), o);
    const PagedFrameStats st = paged.prepare(camera, true);  // returns: the tiles never come
    EXPECT_EQ(st.substituted, 2u);
    EXPECT_EQ(paged.substitutedTiles(), 2u);
    const RenderedFrame got = renderFrame(*caster, paged.map(), pose, kView);
    const auto [differ, sum] = colourDifference(full, got);
    std::printf("fast, withheld %s and %s: %zu of %zu pixels differ, mean colour error %.3f\n",
                describeTile(fine).c_str(), describeTile(coarse).c_str(), differ, full.color.size(),
                sum / full.color.size());
    EXPECT_GT(differ, 0u) << "the withheld level-0 tile is in view";
    EXPECT_LT(sum / full.color.size(), 4.0) << "mean colour error over the frame, levels";

    paged.cache().setWithheld(nullptr);
    const PagedFrameStats again = paged.prepare(camera, true);
    EXPECT_EQ(again.substituted, 0u);
    EXPECT_EQ(again.copied, 2u) << "only the stand-ins are replaced";
    expectSameImage(renderFrame(*caster, paged.map(), pose, kView), full, "after the tiles came");
}

TEST(PagedTerrain, ATurnFindsEveryTileReadAheadControlPointRaysIncluded) {
    // A turn of 60 degrees a second at 20 frames a second, 8 degrees down, the loaders keeping up
    // between frames: the prefetch along the motion and the turn holds every tile each frame
    // needs, the level-0 tiles under its control points' rays too (far beyond the footprint's
    // level-0 band, and thin: at the lookahead's steps alone, the frames between them miss).
    const PagedFixture& f = fixture();
    const TerrainDb db = TerrainDb::open(f.path);
    PagedTerrain::Options po;
    po.cache.budgetBytes = std::size_t{32} << 20;
    po.pyramid = true;
    po.levels = kLevelsAuto;
    PagedTerrain paged(db, po);
    const double dt = 0.05, yawRate = 60.0 * M_PI / 180.0;
    Pose pose;
    pose.position = {0.3 * f.map.extentX(), 0.3 * f.map.extentY(), 0.0};
    pose.position.z = f.map.surfaceHeight(pose.position.x, pose.position.y) + 120.0;
    pose.pitch = -8.0 * M_PI / 180.0;
    const glm::dvec3 velocity{30.0, 30.0, 0.0};
    paged.prepare(Camera(pose, kView), true, velocity, yawRate);  // its own tiles, waiting
    std::size_t substituted = 0, required = 0;
    for (int i = 1; i <= 24; ++i) {
        paged.cache().waitIdle();  // a disk as fast as the prefetch asks
        pose.position += velocity * dt;
        pose.yaw += yawRate * dt;
        const PagedFrameStats st = paged.prepare(Camera(pose, kView), false, velocity, yawRate);
        substituted += st.substituted;
        required += st.required;
    }
    EXPECT_GT(required, 24u * 100u);
    EXPECT_EQ(substituted, 0u) << "tiles a frame needed that the prefetch had not asked for";
}

// A frame drawn at lower detail (Intrinsics::detail: coarser levels nearer) needs fewer
// level-0 tiles, and over the paged map it is the in-memory render at that detail, to the bit.
TEST(PagedTerrain, LowerDetailNeedsFewerTilesAndEqualsTheInMemoryRenderAtThatDetail) {
    const PagedFixture& f = fixture();
    const TerrainDb db = TerrainDb::open(f.path);
    PagedTerrain::Options po = smallBudget();
    po.cache.budgetBytes = std::size_t{5} << 18;
    po.pyramid = true;
    po.levels = kLevelsAuto;
    PagedTerrain paged(db, po);
    const FastTwins twins(f.map, paged);
    const Caster* inMemory = twins.inMemory.get();
    const Caster* fromCache = twins.fromCache.get();
    Intrinsics half = kView;
    half.detail = 0.5;
    const LevelSelection full = LevelSelection::forCamera(kView, db.info(), kLevelsAuto);
    const LevelSelection coarse = LevelSelection::forCamera(half, db.info(), kLevelsAuto);
    EXPECT_DOUBLE_EQ(coarse.d0, 0.5 * full.d0);
    int pose = 0;
    std::size_t differing = 0;
    for (Pose p : lowSweep(f.map, 12)) {
        p.pitch = -6.0 * M_PI / 180.0;  // far enough that level 0 ends within the view
        const std::size_t level0Full =
            frameFootprint(Camera(p, kView), db.layout(), db.info(), full)
                .count(TileKind::Display, 0);
        const std::size_t level0Half =
            frameFootprint(Camera(p, half), db.layout(), db.info(), coarse)
                .count(TileKind::Display, 0);
        EXPECT_LT(level0Half, level0Full) << "pose " << pose;
        const PagedFrameStats st = paged.prepare(Camera(p, half), true);
        EXPECT_EQ(st.substituted, 0u) << "pose " << pose;
        const RenderedFrame a = renderFrame(*inMemory, f.map, p, half);
        const RenderedFrame b = renderFrame(*fromCache, paged.map(), p, half);
        expectSameImage(a, b, "detail 0.5, pose " + std::to_string(pose));
        differing += colourDifference(a, renderFrame(*inMemory, f.map, p, kView)).first;
        ++pose;
    }
    EXPECT_GT(differing, 0u) << "the detail changed no pixel: the casters do not take it";
}

// chooseDetail: no lower detail without a budget; a budget no write fits drops a turn's frames
// to the lowest detail (as many steps of 2^(-1/4) in a frame as it takes), never below it; held
// still, the detail comes back to full a step a frame at most, each step only once its tiles are
// loaded (no frame on the way draws a tile from a coarser level).
TEST(PagedTerrain, DetailDropsWhereWritesPassTheBudgetAndComesBackWithItsTilesLoaded) {
    const PagedFixture& f = fixture();
    const TerrainDb db = TerrainDb::open(f.path);
    const double dt = 0.05, yawRate = 60.0 * M_PI / 180.0;
    const glm::dvec3 velocity{30.0, 30.0, 0.0};
    Pose start;
    start.position = {0.3 * f.map.extentX(), 0.3 * f.map.extentY(), 0.0};
    start.position.z = f.map.surfaceHeight(start.position.x, start.position.y) + 120.0;
    start.pitch = -8.0 * M_PI / 180.0;
    for (const double budget : {0.0, 1e-6}) {
        SCOPED_TRACE("budget " + std::to_string(budget));
        PagedTerrain::Options po;
        po.cache.budgetBytes = std::size_t{32} << 20;
        po.pyramid = true;
        po.levels = kLevelsAuto;
        po.placeBudgetMs = budget;
        po.minDetail = 0.5;
        PagedTerrain paged(db, po);
        Pose pose = start;
        paged.prepare(Camera(pose, kView), true, velocity, yawRate);
        EXPECT_GT(paged.msPerTile(), 0.0) << "the first frame's writes measured";
        double last = 1.0, lowest = 1.0;
        for (int i = 1; i <= 12; ++i) {
            pose.position += velocity * dt;
            pose.yaw += yawRate * dt;
            const double d = paged.chooseDetail(Camera(pose, kView));
            EXPECT_GE(d, 0.5);
            const double steps = -4.0 * std::log2(d);
            EXPECT_NEAR(steps, std::round(steps), 1e-9) << d << ": not a step";
            last = d;
            lowest = std::min(lowest, d);
            Intrinsics in = kView;
            in.detail = d;
            paged.prepare(Camera(pose, in), false, velocity, yawRate);
        }
        if (budget == 0.0) {
            EXPECT_EQ(lowest, 1.0);
            continue;
        }
        EXPECT_DOUBLE_EQ(lowest, 0.5);
        // Held still: nothing new to write, the loaders keeping up.
        int frames = 0;
        std::size_t substituted = 0;
        while (last < 1.0 && frames < 2000) {
            paged.cache().waitIdle();
            const double d = paged.chooseDetail(Camera(pose, kView));
            EXPECT_LE(d, last * std::exp2(0.25) + 1e-12) << "more than a step up";
            last = d;
            Intrinsics in = kView;
            in.detail = d;
            substituted += paged.prepare(Camera(pose, in), false).substituted;
            ++frames;
        }
        EXPECT_EQ(last, 1.0) << "after " << frames << " frames held still";
        EXPECT_EQ(substituted, 0u);
    }
}

TEST(PagedTerrain, CorruptTileInFlightIsAReportedHoleAndFramesGoOn) {
    const PagedFixture& f = fixture();
    const std::string path =
        vig_test::testTmpPath("paged_terrain", "corrupt_" + std::to_string(::getpid()) + ".db");
    const Pose pose = lookingDown(f.map);
    const Camera camera(pose, kView);
    const auto inMemory = makeCaster(CasterKind::Reference, f.map);
    const RenderedFrame full = renderFrame(*inMemory, f.map, pose, kView);
    const auto [tx, ty] = centreTile(full, camera, 16, f.map);
    const TileKey bad{TileKind::Display, 0, tx, ty};
    {
        std::vector<char> bytes;
        std::ifstream in(f.path, std::ios::binary);
        bytes.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
        std::uint64_t io = 0, off = 0;
        std::memcpy(&io, bytes.data() + 88, 8);
        const TerrainDb db = TerrainDb::open(f.path);
        std::memcpy(&off, bytes.data() + io + db.layout().entryIndex(bad) * 24, 8);
        bytes[off + 40] ^= 0x11;
        std::ofstream(path, std::ios::binary)
            .write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
    }
    const TerrainDb db = TerrainDb::open(path);
    PagedTerrain paged(db, smallBudget());
    const auto caster = makeCaster(CasterKind::Reference, paged.map());
    // A flight that never waits: the frames go on whatever the loaders have done.
    std::size_t reported = 0, failedFrames = 0;
    for (int frame = 0; frame < 40; ++frame) {
        const PagedFrameStats st = paged.prepare(camera, false);
        for (const std::string& m : st.failures) {
            ++reported;
            EXPECT_NE(m.find("display tile (level 0, " + std::to_string(tx) + ", " +
                             std::to_string(ty) + ")"),
                      std::string::npos)
                << m;
            EXPECT_NE(m.find(path), std::string::npos) << m;
        }
        failedFrames += st.failed > 0;
        const RenderedFrame img = renderFrame(*caster, paged.map(), pose, kView);
        EXPECT_EQ(img.color.size(), full.color.size());
        if (frame == 20) paged.cache().waitIdle();
    }
    EXPECT_EQ(reported, 1u) << "reported once";
    EXPECT_GT(failedFrames, 0u);
    EXPECT_EQ(paged.cache().stats().failures, 1u) << "never read again";
    // Once the rest has arrived the frame is the full image but for the hole's tile, which is
    // the coarser level's.
    paged.cache().waitIdle();
    const PagedFrameStats last = paged.prepare(camera, true);
    EXPECT_EQ(last.substituted, 1u);
    EXPECT_EQ(last.failed, 1u);
    const int k = paged.cache().findOrCoarser(bad)->key.level;
    const TerrainPyramid pyr(f.map);
    const TerrainMap twin = withStandIn(f.map, pyr, k, tx, ty, 16);
    const RenderedFrame expected =
        renderFrame(*makeCaster(CasterKind::Reference, twin), twin, pose, kView);
    expectSameImage(renderFrame(*caster, paged.map(), pose, kView), expected, "hole");
    std::filesystem::remove(path);
}

}  // namespace
}  // namespace ig
