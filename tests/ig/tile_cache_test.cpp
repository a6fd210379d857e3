#include "ig/tile_cache.hpp"

#include <gtest/gtest.h>

#include <glm/geometric.hpp>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "ig/error.hpp"
#include "ig/pose_sweep.hpp"
#include "ig/synthetic.hpp"
#include "ig/terrain_db_build.hpp"
#include "ig/tile_footprint.hpp"

namespace ig {
namespace {

std::string tmpPath(const std::string& name) {
    const std::filesystem::path dir = std::filesystem::path(VIG_TEST_TMP) / "tile_cache";
    std::filesystem::create_directories(dir);
    return (dir / name).string();
}

// A 257 x 257 synthetic map (10 m) and its database in tiles of 16.
struct Fixture {
    TerrainMap map;
    std::string path;
    Fixture() : map(makeSyntheticTerrain(256, 6)), path(tmpPath("map.db")) {
        auto source = mapRowSource(map);
        DbBuildOptions o;
        o.tileSize = 16;
        buildTerrainDb(*source, path, o);
    }
};

const Fixture& fixture() {
    static const Fixture f;
    return f;
}

// The slow twin of the footprint: marches every pixel's ray in quarter-cell steps through the
// map's box from the eye until it meets the bilinear surface, and records the tile of every
// level the multiresolution caster reads at each step's distance (LevelSelection::band).
std::set<TileKey> marchedTiles(const Camera& camera, const TerrainMap& map,
                               const TerrainDbLayout& layout, const LevelSelection& sel) {
    std::set<TileKey> out;
    const double lo = map.minHeight(), hi = map.maxHeight();
    const double ex = map.extentX(), ey = map.extentY();
    const glm::dvec3 eye = camera.pose().position;
    const double step = 0.25 * std::min(map.spacingX(), map.spacingY());
    const Intrinsics& in = camera.intrinsics();
    for (int py = 0; py < in.height; ++py) {
        for (int px = 0; px < in.width; ++px) {
            const glm::dvec3 d = glm::normalize(camera.rayDirection(px + 0.5, py + 0.5));
            // The ray's stretch inside the box [0, ex] x [0, ey] x [lo, hi].
            double t0 = 0, t1 = 1e12;
            const double bmin[3] = {0, 0, lo}, bmax[3] = {ex, ey, hi};
            bool inside = true;
            for (int a = 0; a < 3 && inside; ++a) {
                if (std::abs(d[a]) < 1e-15) {
                    inside = eye[a] >= bmin[a] && eye[a] <= bmax[a];
                    continue;
                }
                double ta = (bmin[a] - eye[a]) / d[a], tb = (bmax[a] - eye[a]) / d[a];
                if (ta > tb) std::swap(ta, tb);
                t0 = std::max(t0, ta);
                t1 = std::min(t1, tb);
                inside = t0 <= t1;
            }
            if (!inside) continue;
            for (double t = t0; t <= t1; t += step) {
                const glm::dvec3 p = eye + d * t;
                const double dist = std::hypot(p.x - eye.x, p.y - eye.y);
                for (int k = 0; k < layout.displayLevels(); ++k) {
                    double nearD, farD;
                    sel.band(k, layout.displayLevels(), nearD, farD);
                    if (dist < nearD || dist >= farD) continue;
                    const double cs = std::ldexp(map.spacingX(), k);
                    const int cx =
                        std::clamp(static_cast<int>(p.x / cs), 0, layout.levelWidth(k) - 2);
                    const int cy =
                        std::clamp(static_cast<int>(p.y / cs), 0, layout.levelHeight(k) - 2);
                    out.insert(TileKey{TileKind::Display, k, cx / layout.tileSize(),
                                       cy / layout.tileSize()});
                }
                if (p.z <= map.surfaceHeight(p.x, p.y)) break;
            }
        }
    }
    return out;
}

TEST(TileFootprint, HoldsEveryTileTheRaysReadOverAPoseSweep) {
    const Fixture& f = fixture();
    const TerrainDb db = TerrainDb::open(f.path);
    const Intrinsics intr = Intrinsics::fromFov(32, 24, 60.0 * M_PI / 180.0, 2);
    std::size_t footprintTiles = 0, marched = 0, missing = 0;
    for (const int levels : {0, -1}) {
        for (Pose pose : sweepPoses(f.map, 16)) {
            const Camera camera(pose, intr);
            const LevelSelection sel = LevelSelection::forCamera(intr, db.info(), levels);
            const Footprint fp = frameFootprint(camera, db.layout(), db.info(), sel);
            const std::set<TileKey> touched = marchedTiles(camera, f.map, db.layout(), sel);
            for (const TileKey& k : touched) {
                if (!fp.tiles.count(k)) {
                    ++missing;
                    ADD_FAILURE() << describeTile(k) << " missing at pose " << pose.position.x
                                  << "," << pose.position.y << "," << pose.position.z << " yaw "
                                  << pose.yaw << " pitch " << pose.pitch;
                }
                // Node tiles above every display tile.
                if (k.level + 1 < db.layout().nodeLevels()) {
                    EXPECT_TRUE(
                        fp.tiles.count(TileKey{TileKind::Nodes, std::max(k.level, 1),
                                               k.tx >> (k.level == 0), k.ty >> (k.level == 0)}));
                }
            }
            for (const TileKey& k : fp.tiles)
                footprintTiles += k.kind == TileKind::Display;
            marched += touched.size();
        }
    }
    EXPECT_EQ(missing, 0u);
    // The footprint ignores occlusion, so it is larger than what the rays read before their
    // hits; not wildly larger.
    const double ratio = static_cast<double>(footprintTiles) / std::max<std::size_t>(marched, 1);
    std::printf("footprint / marched display tiles: %zu / %zu = %.2f\n", footprintTiles, marched,
                ratio);
    EXPECT_LT(ratio, 4.0);
}

TEST(TileFootprint, ExtendedHoldsTheFramesAheadAndTheMargin) {
    const Fixture& f = fixture();
    const TerrainDb db = TerrainDb::open(f.path);
    const Intrinsics intr = Intrinsics::fromFov(64, 48, 50.0 * M_PI / 180.0);
    Pose pose;
    pose.position = {600, 700, 900};
    pose.yaw = 0.3;
    pose.pitch = -0.3;
    const Camera camera(pose, intr);
    const LevelSelection sel = LevelSelection::forCamera(intr, db.info(), -1);
    const glm::dvec3 v{80, 40, 0};
    const double yawRate = 0.4;
    const Footprint ext =
        extendedFootprint(camera, db.layout(), db.info(), sel, v, yawRate, 1.0, 0.25, 50.0);
    const Footprint now = frameFootprint(camera, db.layout(), db.info(), sel);
    std::size_t ahead = 0;
    for (const double t : {0.0, 0.5, 1.0}) {
        Pose p = pose;
        p.position += v * t;
        p.yaw += yawRate * t;
        const Footprint fp = frameFootprint(Camera(p, intr), db.layout(), db.info(), sel);
        for (const TileKey& k : fp.tiles) {
            EXPECT_TRUE(ext.tiles.count(k)) << describeTile(k) << " at t " << t;
            ahead += !now.tiles.count(k);
        }
    }
    EXPECT_GT(ahead, 0u);  // the motion reaches tiles the frame itself does not need
    EXPECT_GT(ext.tiles.size(), now.tiles.size());
}

TEST(TileFootprint, NothingWhenTheViewMissesTheTerrain) {
    const Fixture& f = fixture();
    const TerrainDb db = TerrainDb::open(f.path);
    const Intrinsics intr = Intrinsics::fromFov(64, 48, 40.0 * M_PI / 180.0);
    Pose up;
    up.position = {1000, 1000, 5000};
    up.pitch = 1.2;  // looking up from above the highest point
    const LevelSelection sel = LevelSelection::forCamera(intr, db.info(), -1);
    EXPECT_TRUE(frameFootprint(Camera(up, intr), db.layout(), db.info(), sel).tiles.empty());
}

// Level-0 display keys of full 16 x 16 tiles, in a row.
TileKey tile0(int i) {
    return TileKey{TileKind::Display, 0, i % 8, i / 8};
}

TEST(TileCache, KeepsItsBudgetAndEvictsTheLeastRecentlyNeeded) {
    const Fixture& f = fixture();
    const TerrainDb db = TerrainDb::open(f.path);
    TileCache::Options o;
    o.residentFromLevel = 3;
    std::size_t pinned = 0, tileBytes = 0;
    {
        const TileCache probe(db, o);
        pinned = probe.residentBytes();
        tileBytes = db.readTile(tile0(0)).bytes();
    }
    o.budgetBytes = pinned + 4 * tileBytes;  // room for four level-0 tiles
    TileCache cache(db, o);
    EXPECT_EQ(cache.residentBytes(), pinned);
    auto frame = [&](std::uint64_t n, std::set<TileKey> req, std::set<TileKey> pre = {}) {
        cache.beginFrame(n, req, pre);
        cache.waitIdle();
        EXPECT_LE(cache.residentBytes(), o.budgetBytes);
    };
    frame(1, {tile0(1), tile0(2)});
    frame(2, {tile0(3), tile0(4)});
    EXPECT_TRUE(cache.find(tile0(1)) && cache.find(tile0(4)));
    frame(3, {tile0(5)});  // evicts one of frame 1's
    EXPECT_EQ(!cache.find(tile0(1)) + !cache.find(tile0(2)), 1);
    EXPECT_TRUE(cache.find(tile0(3)) && cache.find(tile0(4)) && cache.find(tile0(5)));
    frame(4, {tile0(6)});  // evicts the other of frame 1's, not frame 2's
    EXPECT_FALSE(cache.find(tile0(1)) || cache.find(tile0(2)));
    EXPECT_TRUE(cache.find(tile0(3)) && cache.find(tile0(4)) && cache.find(tile0(6)));
    // A prefetch never evicts the frame's own tiles.
    frame(5, {tile0(3), tile0(4), tile0(5), tile0(6)}, {tile0(7)});
    EXPECT_FALSE(cache.find(tile0(7)));
    EXPECT_TRUE(cache.find(tile0(3)) && cache.find(tile0(4)) && cache.find(tile0(5)) &&
                cache.find(tile0(6)));
    const TileCacheStats s = cache.stats();
    EXPECT_EQ(s.evictions, 2u);  // 1 and 2
    EXPECT_EQ(s.overBudget, 1u);
    EXPECT_GE(s.hits, 3u);
    // Coarse levels stay resident whatever the frames ask.
    EXPECT_TRUE(cache.find(TileKey{TileKind::Display, 3, 0, 0}));
}

TEST(TileCache, BudgetBelowTheCoarseLevelsIsAClearError) {
    const Fixture& f = fixture();
    const TerrainDb db = TerrainDb::open(f.path);
    TileCache::Options o;
    o.residentFromLevel = 0;
    o.budgetBytes = 1000;
    try {
        const TileCache cache(db, o);
        ADD_FAILURE() << "no error";
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find("coarse levels"), std::string::npos) << e.what();
    }
}

TEST(TileCache, WithheldTileIsAHoleFilledFromCoarser) {
    const Fixture& f = fixture();
    const TerrainDb db = TerrainDb::open(f.path);
    TileCache::Options o;
    o.residentFromLevel = 2;
    TileCache cache(db, o);
    const TileKey fine{TileKind::Display, 0, 5, 6};
    cache.setWithheld([&](const TileKey& k) { return k == fine; });
    cache.beginFrame(1, {fine, tile0(0)});
    cache.waitIdle();
    EXPECT_FALSE(cache.find(fine));
    EXPECT_TRUE(cache.find(tile0(0)));
    // Level 1 was not asked for: level 2 (resident) stands in.
    const auto sub = cache.findOrCoarser(fine);
    ASSERT_TRUE(sub);
    EXPECT_EQ(sub->key, (TileKey{TileKind::Display, 2, 1, 1}));
    EXPECT_EQ(cache.stats().substitutions, 1u);
    EXPECT_EQ(cache.findOrCoarser(tile0(0))->key, tile0(0));
    EXPECT_EQ(cache.stats().substitutions, 1u);
    EXPECT_EQ(cache.stats().holes, 0u);
}

TEST(TileCache, CorruptTileIsReportedAndSubstituted) {
    const Fixture& f = fixture();
    const std::string path = tmpPath("corrupt.db");
    std::vector<char> bytes;
    {
        std::ifstream in(f.path, std::ios::binary);
        bytes.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
    }
    const TileKey bad{TileKind::Display, 0, 2, 3};
    std::uint64_t io = 0, off = 0;
    std::memcpy(&io, bytes.data() + 88, 8);
    {
        const TerrainDb db = TerrainDb::open(f.path);
        std::memcpy(&off, bytes.data() + io + db.layout().entryIndex(bad) * 24, 8);
    }
    bytes[off + 40] ^= 0x11;
    std::ofstream(path, std::ios::binary)
        .write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
    const TerrainDb db = TerrainDb::open(path);
    TileCache::Options o;
    o.residentFromLevel = 3;
    TileCache cache(db, o);
    cache.beginFrame(1, {bad, tile0(0)});
    cache.waitIdle();
    EXPECT_EQ(cache.stats().failures, 1u);
    EXPECT_NE(cache.failure(bad).find("display tile (level 0, 2, 3)"), std::string::npos)
        << cache.failure(bad);
    const auto sub = cache.findOrCoarser(bad);
    ASSERT_TRUE(sub);
    EXPECT_EQ(sub->key.level, 3);
    // Asked again, a failed tile is not read again.
    cache.beginFrame(2, {bad});
    cache.waitIdle();
    EXPECT_EQ(cache.stats().failures, 1u);
}

TEST(TileCache, ManyFramesFromSeveralLoadersStayConsistent) {
    const Fixture& f = fixture();
    const TerrainDb db = TerrainDb::open(f.path);
    TileCache::Options o;
    o.loaderThreads = 4;
    o.residentFromLevel = 3;
    o.budgetBytes = 200 * 1024;
    TileCache cache(db, o);
    const Intrinsics intr = Intrinsics::fromFov(64, 48, 60.0 * M_PI / 180.0);
    std::uint64_t n = 0;
    for (const Pose& pose : sweepPoses(fixture().map, 12)) {
        const Camera camera(pose, intr);
        const LevelSelection sel = LevelSelection::forCamera(intr, db.info(), -1);
        const Footprint fp = frameFootprint(camera, db.layout(), db.info(), sel);
        const Footprint ext =
            extendedFootprint(camera, db.layout(), db.info(), sel, {50, 0, 0}, 0.2, 1.0, 0.5, 30);
        cache.beginFrame(++n, fp.tiles, ext.tiles);
        // The frame goes on at once: every lookup answers without waiting.
        for (const TileKey& k : fp.tiles) {
            const auto t = cache.findOrCoarser(k);
            if (t) {
                EXPECT_LE(k.level, t->key.level);
            }
        }
        EXPECT_LE(cache.residentBytes(), o.budgetBytes);
    }
    cache.waitIdle();
    EXPECT_LE(cache.residentBytes(), o.budgetBytes);
    EXPECT_GT(cache.stats().tilesRead, 0u);
}

}  // namespace
}  // namespace ig
