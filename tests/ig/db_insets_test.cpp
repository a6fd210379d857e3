// High-resolution insets held in a terrain database (docs/design/insets.md, "Insets in a
// database"): built with the map or added to an existing database, read back whole, and paged
// with the map; every image equal to the nested terrain's in memory.
#include <gtest/gtest.h>
#include <unistd.h>
#include <zlib.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "common/small_terrain_db.hpp"
#include "ig/caster.hpp"
#include "ig/error.hpp"
#include "ig/inset.hpp"
#include "ig/paged_insets.hpp"
#include "ig/synthetic.hpp"
#include "ig/terrain_db.hpp"
#include "ig/terrain_db_build.hpp"

namespace ig {
namespace {

constexpr std::uint64_t kSeed = 7;
constexpr double kSpacing = 8.0;

InsetSource insetA() {
    return syntheticInset(kSeed, kSpacing, 200, 210, 64, 48, 4);
}
InsetSource insetB() {
    return syntheticInset(kSeed, kSpacing, 60, 300, 40, 40, 2);
}

std::uint32_t crcOf(const char* p, std::size_t n) {
    return static_cast<std::uint32_t>(
        crc32(crc32(0L, Z_NULL, 0), reinterpret_cast<const Bytef*>(p), static_cast<uInt>(n)));
}

std::string tmp(const std::string& name) {
    return vig_test::testTmpPath("db_insets", name + "_" + std::to_string(::getpid()) + ".db");
}

std::vector<char> bytesOf(const std::string& path) {
    std::ifstream f(path, std::ios::binary);
    return {std::istreambuf_iterator<char>(f), std::istreambuf_iterator<char>()};
}

DbBuildOptions tiles(int size) {
    DbBuildOptions o;
    o.tileSize = size;
    return o;
}

void expectSameMap(const TerrainMap& a, const TerrainMap& b, const std::string& what) {
    ASSERT_EQ(a.width(), b.width()) << what;
    ASSERT_EQ(a.height(), b.height()) << what;
    EXPECT_TRUE(std::equal(a.rawHeights().begin(), a.rawHeights().end(), b.rawHeights().begin()))
        << what;
    EXPECT_TRUE(std::equal(a.colors().begin(), a.colors().end(), b.colors().begin(),
                           [](Rgb8 x, Rgb8 y) { return x.r == y.r && x.g == y.g && x.b == y.b; }))
        << what;
    EXPECT_EQ(a.minHeight(), b.minHeight()) << what << " (the box's floor)";
    EXPECT_EQ(a.spacingX(), b.spacingX()) << what;
}

// A 512² map at 8 m with two insets (2 m and 4 m), nested in memory and built into a
// database in tiles of 16.
struct Fixture {
    NestedTerrain nested;
    std::string path;
    Fixture()
        : nested(makeSyntheticTerrain(512, kSeed, kSpacing), {insetA(), insetB()}, 16),
          path(tmp("nested")) {
        const TerrainMap plain = makeSyntheticTerrain(512, kSeed, kSpacing);
        auto rows = mapRowSource(plain);
        DbBuildOptions o = tiles(16);
        o.insets = {insetA(), insetB()};
        buildTerrainDb(*rows, path, o);
    }
    ~Fixture() { std::filesystem::remove(path); }
};

const Fixture& fixture() {
    static const Fixture f;
    return f;
}

TEST(DbInsets, TheDatabaseHoldsTheNestedTerrainBitForBit) {
    const Fixture& f = fixture();
    const TerrainDb db = TerrainDb::open(f.path);
    ASSERT_EQ(db.insets().size(), 2u);
    // The global map is the lowered one, and its tiles and pyramid are those of a database
    // built from it.
    expectSameMap(db.loadMap(), f.nested.global(), "global map");
    const std::string plainPath = tmp("lowered");
    {
        auto rows = mapRowSource(f.nested.global());
        buildTerrainDb(*rows, plainPath, tiles(16));
    }
    const TerrainDb plain = TerrainDb::open(plainPath);
    ASSERT_EQ(plain.layout().entryCount(), db.layout().entryCount());
    for (std::int64_t i = 0; i < db.layout().entryCount(); ++i) {
        const TileKey key = db.layout().keyAt(i);
        const TerrainTile a = db.readTile(key), b = plain.readTile(key);
        ASSERT_EQ(a.heights, b.heights) << describeTile(key);
        ASSERT_EQ(a.maxima, b.maxima) << describeTile(key);
    }
    std::filesystem::remove(plainPath);
    // Each inset: its placement and its nested map, floor included.
    const std::vector<Inset> back = readInsets(db);
    ASSERT_EQ(back.size(), 2u);
    for (std::size_t k = 0; k < 2; ++k) {
        const Inset& want = f.nested.insets()[k];
        EXPECT_EQ(back[k].name, want.name);
        EXPECT_EQ(back[k].x0, want.x0);
        EXPECT_EQ(back[k].y1, want.y1);
        EXPECT_EQ(back[k].factor, want.factor);
        EXPECT_EQ(back[k].mapX0, want.mapX0);
        expectSameMap(back[k].map, want.map, want.name);
    }
}

TEST(DbInsets, AddedToAnExistingDatabaseEqualsBuiltAtOnce) {
    const Fixture& f = fixture();
    const TerrainMap plain = makeSyntheticTerrain(512, kSeed, kSpacing);
    const std::string p0 = tmp("plain"), p1 = tmp("plus_a"), p2 = tmp("plus_b");
    {
        auto rows = mapRowSource(plain);
        buildTerrainDb(*rows, p0, tiles(16));
    }
    {
        const TerrainDb db = TerrainDb::open(p0);
        auto rows = dbRowSource(db);
        DbBuildOptions o = tiles(16);
        o.insets = {insetA()};
        buildTerrainDb(*rows, p1, o);
    }
    {
        const TerrainDb db = TerrainDb::open(p1);
        auto rows = dbRowSource(db);
        DbBuildOptions o = tiles(16);
        o.nestedInsets = readInsets(db);
        o.insets = {insetB()};
        buildTerrainDb(*rows, p2, o);
    }
    EXPECT_TRUE(bytesOf(p2) == bytesOf(f.path)) << "one at a time differs from both at once";
    // Too near an inset the database holds: refused, naming both.
    {
        const TerrainDb db = TerrainDb::open(p1);
        auto rows = dbRowSource(db);
        DbBuildOptions o = tiles(16);
        o.nestedInsets = readInsets(db);
        o.insets = {syntheticInset(kSeed, kSpacing, 266, 210, 8, 8, 2)};
        try {
            buildTerrainDb(*rows, tmp("refused"), o);
            ADD_FAILURE() << "an inset next to a held one accepted";
        } catch (const InputError& e) {
            EXPECT_NE(std::string(e.what()).find("holds already"), std::string::npos) << e.what();
        }
        EXPECT_FALSE(std::filesystem::exists(tmp("refused")));
    }
    for (const std::string& p : {p0, p1, p2})
        std::filesystem::remove(p);
}

// Poses looking at inset A from outside, above and inside it, at inset B, and at the corners.
std::vector<Pose> views(const NestedTerrain& t) {
    std::vector<Pose> out;
    const struct {
        int inset;
        double yaw, pitch, range, up;
    } vs[] = {{0, 0, -25, 500, 150},
              {0, 70, -40, 300, 220},
              {0, 315, -70, 80, 400},
              {0, 135, -8, 1200, 250},
              {1, 200, -20, 400, 120}};
    for (const auto& v : vs) {
        const Inset& in = t.insets()[v.inset];
        const glm::dvec2 c = 0.5 * (in.coverMin + in.coverMax);
        const double yaw = degToRad(v.yaw);
        Pose p;
        p.position = {c.x - v.range * std::sin(yaw), c.y - v.range * std::cos(yaw), 0.0};
        p.position.z = t.surfaceHeight(p.position.x, p.position.y) + v.up;
        p.yaw = yaw;
        p.pitch = degToRad(v.pitch);
        out.push_back(p);
    }
    // The map's four corners, looking down: tiles far from the insets, so the global cache
    // evicts.
    for (const double cx : {400.0, 3700.0}) {
        for (const double cy : {400.0, 3700.0}) {
            Pose p;
            p.position = {cx, cy, t.surfaceHeight(cx, cy) + 250.0};
            p.yaw = std::atan2(cx - 2044.0, cy - 2044.0);
            p.pitch = degToRad(-35);
            out.push_back(p);
        }
    }
    return out;
}

TEST(DbInsets, PagedRenderEqualsTheNestedTerrainInMemory) {
    const Fixture& f = fixture();
    const TerrainDb db = TerrainDb::open(f.path);
    const Intrinsics intr = Intrinsics::fromFov(200, 130, degToRad(50), 8);
    for (const CasterKind kind : {CasterKind::Fast, CasterKind::Reference}) {
        for (const int levels : {0, kLevelsAuto}) {
            if (kind == CasterKind::Reference && levels != 0) continue;
            PagedTerrain::Options po;
            // The global map is 1.8 MB of tiles, the 2 m inset 0.9 MB: a cache far smaller.
            // The global map's half of the budget is smaller than its tiles: the views evict.
            po.cache.budgetBytes = std::size_t{6} << 19;
            po.pyramid = kind == CasterKind::Fast;
            po.levels = levels;
            PagedNestedTerrain paged(db, po);
            ASSERT_EQ(paged.insetCount(), 2u);
            RenderOptions options;
            options.levels = levels;
            const auto pagedCaster = paged.makeCaster(kind, options);
            const auto memCaster = makeNestedCaster(kind, f.nested, options);
            std::uint64_t read = 0;
            for (const Pose& pose : views(f.nested)) {
                const PagedFrameStats st = paged.prepare(Camera(pose, intr), true);
                EXPECT_EQ(st.substituted, 0u);
                const RenderedFrame a = renderNestedFrame(*pagedCaster, paged.maps(), pose, intr);
                const RenderedFrame b = renderNestedFrame(*memCaster, f.nested, pose, intr);
                std::size_t differ = 0;
                for (std::size_t i = 0; i < a.color.size(); ++i) {
                    differ += a.color[i].r != b.color[i].r || a.color[i].g != b.color[i].g ||
                              a.color[i].b != b.color[i].b || a.depth[i] != b.depth[i];
                }
                EXPECT_EQ(differ, 0u)
                    << casterName(kind) << " levels " << levels << " yaw " << pose.yaw;
                for (int k = 0; k < kControlPointCount; ++k)
                    EXPECT_EQ(a.controlPoints[k].world, b.controlPoints[k].world);
            }
            for (std::size_t k = 0; k < paged.insetCount(); ++k)
                read += paged.inset(k).cache().stats().tilesRead;
            // The insets were paged: their tiles read through their own caches.
            EXPECT_GT(read, 0u);
            EXPECT_GT(paged.global().cache().stats().evictions, 0u)
                << "the global cache never evicted: paging did not happen";
        }
    }
}

// A slow flight (6 m a frame, at 60 m over the nested surface) crossing inset A's border, each
// frame's tiles placed as they come: each frame is the in-memory nested terrain's, so the
// border shows no spike that the in-memory flight (Insets.NoSpikeAcrossTheBorderAlongASlow
// Flight) does not.
TEST(DbInsets, ASlowFlightAcrossTheBorderIsTheInMemoryFlight) {
    const Fixture& f = fixture();
    const TerrainDb db = TerrainDb::open(f.path);
    const Intrinsics intr = Intrinsics::fromFov(160, 90, degToRad(60));
    PagedTerrain::Options po;
    po.cache.budgetBytes = std::size_t{32} << 20;
    po.pyramid = true;
    po.levels = kLevelsAuto;
    PagedNestedTerrain paged(db, po);
    RenderOptions options;
    options.levels = kLevelsAuto;
    const auto pagedCaster = paged.makeCaster(CasterKind::Fast, options);
    const auto memCaster = makeNestedCaster(CasterKind::Fast, f.nested, options);
    const Inset& in = f.nested.insets()[0];
    const double y = 0.5 * (in.coverMin.y + in.coverMax.y);
    std::size_t differ = 0, substituted = 0;
    for (int i = 0; i < 40; ++i) {
        Pose pose;
        pose.position.x = in.coverMin.x - 150.0 + 6.0 * i;
        pose.position.y = y;
        pose.position.z = f.nested.surfaceHeight(pose.position.x, y) + 60.0;
        pose.yaw = degToRad(90);
        pose.pitch = degToRad(-6);
        const PagedFrameStats st = paged.prepare(Camera(pose, intr), true, {6.0 * 60.0, 0.0, 0.0});
        substituted += st.substituted;
        const RenderedFrame a = renderNestedFrame(*pagedCaster, paged.maps(), pose, intr);
        const RenderedFrame b = renderNestedFrame(*memCaster, f.nested, pose, intr);
        for (std::size_t p = 0; p < a.color.size(); ++p) {
            differ += a.color[p].r != b.color[p].r || a.color[p].g != b.color[p].g ||
                      a.color[p].b != b.color[p].b || a.depth[p] != b.depth[p];
        }
    }
    EXPECT_EQ(substituted, 0u);
    EXPECT_EQ(differ, 0u);
}

// The flight model's ground over the paged insets: over each inset, its surface (the nested
// terrain's, to the bit where its tiles are resident); elsewhere the global map's.
TEST(DbInsets, TheGroundOverAPagedInsetIsItsSurface) {
    const Fixture& f = fixture();
    const TerrainDb db = TerrainDb::open(f.path);
    PagedGround::Options go;
    PagedGround global(db, go);
    PagedNestedGround ground(global, db, go);
    std::size_t checked = 0;
    for (const Inset& in : f.nested.insets()) {
        for (int i = 0; i < 25; ++i) {
            const double x = in.coverMin.x + (in.coverMax.x - in.coverMin.x) * (i % 5 + 0.3) / 5;
            const double y = in.coverMin.y + (in.coverMax.y - in.coverMin.y) * (i / 5 + 0.6) / 5;
            // Followed here, so the grounds' own threads place around this point too (a height
            // asked of a ground nobody follows moves its tiles there later, on its thread).
            ground.follow(x, y);
            global.waitAround(x, y);
            ground.waitAround(x, y);
            EXPECT_EQ(ground.groundHeight(x, y), f.nested.surfaceHeight(x, y)) << in.name;
            // The inset's own relief stands over the lowered global surface.
            EXPECT_GE(ground.groundHeight(x, y), f.nested.global().surfaceHeight(x, y));
            ++checked;
        }
    }
    ground.follow(100.0, 100.0);
    global.waitAround(100.0, 100.0);
    EXPECT_EQ(ground.groundHeight(100.0, 100.0), f.nested.global().surfaceHeight(100.0, 100.0));
    EXPECT_EQ(checked, 50u);
}

TEST(DbInsets, ABrokenInsetsTableOrDatabaseIsAClearError) {
    const Fixture& f = fixture();
    std::vector<char> bytes = bytesOf(f.path);
    const TerrainDb db = TerrainDb::open(f.path);
    const DbInset& in = db.insets()[1];
    auto expectError = [&](const std::vector<char>& file, const std::string& what,
                           bool openInsets) {
        const std::string p = tmp("broken");
        std::ofstream(p, std::ios::binary).write(file.data(), std::streamsize(file.size()));
        try {
            const TerrainDb broken = TerrainDb::open(p);
            if (openInsets) {
                for (std::size_t k = 0; k < broken.insets().size(); ++k)
                    (void)readInsets(broken);
            }
            ADD_FAILURE() << "accepted: " << what;
        } catch (const InputError& e) {
            EXPECT_NE(std::string(e.what()).find(what), std::string::npos) << e.what();
            EXPECT_NE(std::string(e.what()).find(p), std::string::npos) << e.what();
        }
        std::filesystem::remove(p);
    };
    // The table's last byte flipped.
    std::vector<char> table = bytes;
    table[table.size() - 1] = static_cast<char>(table[table.size() - 1] ^ 1);
    expectError(table, "insets table checksum mismatch", false);
    // Cut inside the second inset's database.
    std::vector<char> cut(bytes.begin(), bytes.begin() + std::ptrdiff_t(in.offset + in.bytes / 2));
    expectError(cut, "truncated", false);
    // The table placing the second inset one global cell wider than its database (checksums
    // resealed): opening it whole or paged is refused, naming the inset.
    {
        std::vector<char> wide = bytes;
        std::uint64_t tableOffset = 0;
        std::memcpy(&tableOffset, wide.data() + 136, 8);
        char* entry = wide.data() + tableOffset + 176;
        std::int32_t x1 = 0;
        std::memcpy(&x1, entry + 8, 4);
        x1 += 1;
        std::memcpy(entry + 8, &x1, 4);
        const std::uint32_t tc = crcOf(wide.data() + tableOffset, 2 * 176);
        std::memcpy(wide.data() + 148, &tc, 4);
        const std::uint32_t hc = crcOf(wide.data(), 252);
        std::memcpy(wide.data() + 252, &hc, 4);
        const std::string p = tmp("wide");
        std::ofstream(p, std::ios::binary).write(wide.data(), std::streamsize(wide.size()));
        const TerrainDb opened = TerrainDb::open(p);
        PagedTerrain::Options po;
        po.cache.budgetBytes = std::size_t{8} << 20;
        for (const bool paged : {false, true}) {
            try {
                if (paged) {
                    PagedNestedTerrain t(opened, po);
                } else {
                    NestedTerrain::fromNested(opened.loadMap(), readInsets(opened));
                }
                ADD_FAILURE() << "an inset wider than its database accepted";
            } catch (const InputError& e) {
                EXPECT_NE(std::string(e.what()).find(in.name + ": map of"), std::string::npos)
                    << e.what();
            }
        }
        std::filesystem::remove(p);
    }
    // A tile of the second inset's database damaged: named with the inset.
    std::vector<char> tile = bytes;
    tile[in.offset + in.bytes / 2] ^= 0x55;
    expectError(tile, "(inset '" + in.name + "')", true);
}

}  // namespace
}  // namespace ig
