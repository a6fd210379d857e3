#include "ig/tile_footprint.hpp"

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
#include "ig/pose_sweep.hpp"
#include "ig/synthetic.hpp"
#include "ig/terrain_db_build.hpp"
#include "ig/tile_footprint.hpp"

namespace ig {
namespace {

using Fixture = vig_test::SmallTerrainDb;

const Fixture& fixture() {
    static const Fixture f("tile_footprint");
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

}  // namespace
}  // namespace ig
