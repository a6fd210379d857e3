#include "ig/paged_ground.hpp"

#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <thread>

#include "common/small_terrain_db.hpp"
#include "ig/terrain_db.hpp"

namespace ig {
namespace {

const vig_test::SmallTerrainDb& smallDb() {
    static const vig_test::SmallTerrainDb db("paged_ground");
    return db;
}

PagedGround::Options smallGround() {
    PagedGround::Options o;
    o.budgetBytes = std::size_t{1} << 20;
    o.radiusTiles = 1;
    return o;
}

// Around a point placed before, the ground is the whole map's surface to the bit; away from it
// (tiles not kept), a bound on or above the surface, below the map's highest point.
TEST(PagedGround, TheMapsSurfaceWhereItsTilesAreResidentABoundAboveElsewhere) {
    const auto& f = smallDb();
    const TerrainDb db = TerrainDb::open(f.path);
    PagedGround ground(db, smallGround());
    const double cx = 0.4 * f.map.extentX(), cy = 0.6 * f.map.extentY();
    ground.waitAround(cx, cy);
    // Tiles of 16 cells at 10 m, one around: the tile under the point and its neighbours.
    const double reach = 16 * f.map.spacingX();
    int exact = 0;
    for (int j = -20; j <= 20; ++j) {
        for (int i = -20; i <= 20; ++i) {
            const double x = cx + reach * i / 20.0, y = cy + reach * j / 20.0;
            ASSERT_TRUE(ground.exactAt(x, y)) << x << ", " << y;
            EXPECT_EQ(ground.groundHeight(x, y), f.map.surfaceHeight(x, y)) << x << ", " << y;
            ++exact;
        }
    }
    EXPECT_EQ(ground.stats().exact, static_cast<std::uint64_t>(exact));
    // Far from it: nothing kept there (the thread may have moved on since the last ask, so
    // ask several points and check only the answers that were bounds).
    const double fx = 0.9 * f.map.extentX(), fy = 0.1 * f.map.extentY();
    EXPECT_FALSE(ground.exactAt(fx, fy));
    const PagedGround::Stats before = ground.stats();
    const double h = ground.groundHeight(fx, fy);
    const PagedGround::Stats after = ground.stats();
    if (after.exact == before.exact) {
        EXPECT_GE(h, f.map.surfaceHeight(fx, fy));
        EXPECT_LE(h, f.map.maxHeight() + 1e-9);
    }
}

// Tiles the disk never gives: the ground there is the finest resident node's bound over the tile
// (coarse nodes stay resident), on or above the surface and well below the map's highest point
// where the terrain is low; the video would go on, and so does the flight.
TEST(PagedGround, AWithheldTileGivesABoundOnOrAboveTheSurface) {
    const auto& f = smallDb();
    const TerrainDb db = TerrainDb::open(f.path);
    PagedGround ground(db, smallGround());
    ground.setWithheld(
        [](const TileKey& k) { return k.kind == TileKind::Display && k.level == 0; });
    double lowest = 1e300;
    double lx = 0.0, ly = 0.0;
    for (int j = 1; j < 8; ++j) {
        for (int i = 1; i < 8; ++i) {
            const double x = f.map.extentX() * i / 8.0, y = f.map.extentY() * j / 8.0;
            if (f.map.surfaceHeight(x, y) < lowest) {
                lowest = f.map.surfaceHeight(x, y);
                lx = x;
                ly = y;
            }
        }
    }
    ground.waitAround(lx, ly);
    EXPECT_FALSE(ground.exactAt(lx, ly));
    int bounded = 0;
    for (int j = -10; j <= 10; ++j) {
        for (int i = -10; i <= 10; ++i) {
            const double x = lx + 8.0 * i, y = ly + 8.0 * j;
            const double h = ground.groundHeight(x, y);
            EXPECT_GE(h, f.map.surfaceHeight(x, y)) << x << ", " << y;
            ++bounded;
        }
    }
    EXPECT_GE(ground.stats().bounded + ground.stats().outside, static_cast<std::uint64_t>(bounded));
    EXPECT_LT(ground.groundHeight(lx, ly), f.map.maxHeight())
        << "a node's bound, not the highest point";
}

// The thread follows the points asked for: an aircraft flying across the map at 300 m/s (asked
// every 10 ms, as the flight model's steps and predictions do) finds its ground exact within a
// few updates, without anyone waiting.
TEST(PagedGround, FollowsTheAircraftAcrossTheMap) {
    const auto& f = smallDb();
    const TerrainDb db = TerrainDb::open(f.path);
    PagedGround ground(db, smallGround());
    double x = 0.1 * f.map.extentX(), y = 0.2 * f.map.extentY();
    int exactLate = 0, late = 0;
    for (int k = 0; k < 200; ++k) {
        const double h = ground.groundHeight(x, y);
        if (ground.exactAt(x, y)) {
            EXPECT_EQ(h, f.map.surfaceHeight(x, y));
        }
        EXPECT_GE(h, f.map.surfaceHeight(x, y) - 1e-9);
        if (k >= 100) {
            ++late;
            exactLate += ground.exactAt(x, y);
        }
        x += 3.0;
        y += 1.0;
        std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    // Loads take a millisecond or two here; allow for a loaded machine.
    EXPECT_GE(exactLate, late * 3 / 4) << "the ground was exact at " << exactLate << " of " << late
                                       << " points in the second second";
    EXPECT_GT(ground.cache().stats().tilesRead, 0u);
}

TEST(PagedGround, NonFiniteQueriesHaveNoGround) {
    const auto& f = smallDb();
    const TerrainDb db = TerrainDb::open(f.path);
    PagedGround ground(db, smallGround());
    EXPECT_TRUE(std::isnan(ground.groundHeight(std::nan(""), 10.0)));
    EXPECT_TRUE(std::isnan(ground.groundHeight(10.0, INFINITY)));
}

}  // namespace
}  // namespace ig
