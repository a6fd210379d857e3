#include "ig/tile_cache.hpp"

#include <gtest/gtest.h>
#include <unistd.h>

#include <glm/geometric.hpp>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "common/small_terrain_db.hpp"
#include "ig/error.hpp"
#include "ig/synthetic.hpp"
#include "ig/terrain_db_build.hpp"
#include "ig/tile_footprint.hpp"

namespace ig {
namespace {

std::string tmpPath(const std::string& name) {
    return vig_test::testTmpPath("tile_cache", name);
}

using Fixture = vig_test::SmallTerrainDb;

const Fixture& fixture() {
    static const Fixture f("tile_cache");
    return f;
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
    for (int i = 0; i < 24; ++i) {
        // A turning, descending flight over the map.
        Pose pose;
        pose.position = {300.0 + 60.0 * i, 400.0 + 40.0 * i, 1500.0 - 50.0 * i};
        pose.yaw = 0.25 * i;
        pose.pitch = -0.2 - 0.03 * i;
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
