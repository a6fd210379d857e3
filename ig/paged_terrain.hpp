// A terrain database rendered through its tile cache: the map the casters read is a sparse one
// (ig/terrain.hpp: address space for the whole map, memory only for the pages written), into
// which, between frames, the level-0 tiles the frame's footprint needs are copied from the
// resident tiles; a needed tile not resident (not loaded yet, withheld, unreadable) is filled by
// upsampling the finest resident coarser level, so the casters need no change. The tiles no
// longer needed give their pages back. docs/design/terrain_db.md, "Casters reading through the
// cache".
#pragma once

#include "ig/camera.hpp"
#include "ig/terrain.hpp"
#include "ig/terrain_db.hpp"
#include "ig/tile_cache.hpp"
#include "ig/tile_footprint.hpp"

#include <glm/vec3.hpp>

#include <cstdint>
#include <map>
#include <set>
#include <string>
#include <utility>
#include <vector>

namespace ig {

// What preparing one frame found (level-0 display tiles).
struct PagedFrameStats {
    std::uint64_t frame = 0;
    std::size_t required = 0;           // tiles the frame's footprint needs
    std::size_t copied = 0;             // copied into the map for this frame
    std::size_t substituted = 0;        // needed, not resident: filled from a coarser level
    std::size_t failed = 0;             // of those, unreadable (corrupt, truncated): reported holes
    std::size_t holes = 0;              // nothing resident above either: left as they were
    std::size_t released = 0;           // placed tiles no longer needed, their pages given back
    std::vector<std::string> failures;  // messages of failed tiles, each reported once
};

class PagedTerrain {
  public:
    struct Options {
        TileCache::Options cache;
        // Prefetch: the footprint along the motion over this many seconds, widened by
        // prefetchMargin metres (0: the frame's own footprint widened by the margin).
        double lookahead = 0.5;
        double lookaheadStep = 0.125;
        double prefetchMargin = 0.0;
    };

    // `db` must outlive this. Loads the cache's resident coarse levels (InputError when the
    // budget cannot hold them).
    PagedTerrain(const TerrainDb& db, const Options& options);
    PagedTerrain(const PagedTerrain&) = delete;
    PagedTerrain& operator=(const PagedTerrain&) = delete;

    // The map the casters read (level 0 of the database, resident where a frame needed it).
    const TerrainMap& map() const { return map_; }
    TileCache& cache() { return cache_; }
    const TileCache& cache() const { return cache_; }

    // Between frames, on the renderer's thread (never while a caster reads the map): requests
    // the tiles `camera` needs and, moving at `velocity` (m/s) and turning at `yawRate`
    // (rad/s), those to prefetch; then fills the map. With `wait` it first waits until every
    // request is served (a program rendering without a deadline: its image equals the
    // in-memory render's where every tile could be read); without, it never waits and
    // substitutes what is missing (the real-time pipeline).
    PagedFrameStats prepare(const Camera& camera, bool wait, const glm::dvec3& velocity = {},
                            double yawRate = 0.0);

    // Places the level-0 tile under world (x, y) (clamped to the map), waiting for it, and
    // only it (what a program needs before its first frame: the ground under a pose given as
    // a height above it). The next prepare() keeps it only if its frame needs it.
    PagedFrameStats placeAround(double x, double y);

    // Level-0 tiles placed in the map now, and how many of them are stand-ins.
    std::size_t placedTiles() const { return placed_.size(); }
    std::size_t substitutedTiles() const;
    // Bytes of the map's pages that placed tiles can cover (a bound on the map's memory).
    std::size_t placedBytes() const;
    // Bytes of the map's arrays in memory now (mincore over the sparse blocks).
    std::size_t residentMapBytes() const;

  private:
    struct Placed {
        int sourceLevel = 0;  // 0: the tile itself; k > 0: upsampled from level k
        bool failed = false;  // its own read failed
    };
    using Cell = std::pair<int, int>;  // (tx, ty) of level 0

    TileKey tileUnder(double x, double y) const;
    PagedFrameStats page(const std::set<TileKey>& required, const std::set<TileKey>& prefetch,
                         bool wait);
    void copyTile(const TerrainTile& tile);
    void fillFromCoarser(int tx, int ty, const TerrainTile& coarse);
    void updateCellMax(int tx, int ty);
    void release(int tx, int ty);
    bool samplePlaced(int x, int y) const;

    const TerrainDb& db_;
    Options options_;
    TileCache cache_;
    TerrainMap map_;
    std::map<Cell, Placed> placed_;
    std::set<Cell> reported_;  // failed tiles already reported
    std::uint64_t frame_ = 0;
};

}  // namespace ig
