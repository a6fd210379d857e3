// A terrain database rendered through its tile cache: the map the casters read is a sparse one
// (ig/terrain.hpp: address space for the whole map, memory only for the pages written), into
// which, between frames, the level-0 tiles the frame's footprint needs are copied from the
// resident tiles; a needed tile not resident (not loaded yet, withheld, unreadable) is filled by
// upsampling the finest resident coarser level, so the casters need no change. For the fast
// caster a sparse pyramid is filled the same way (its coarser display levels where the frame
// reads them, and the max-height nodes above them), and its slope bounds are the database's.
// The tiles no longer needed give their pages back. docs/design/terrain_db.md, "Casters reading
// through the cache".
#pragma once

#include "ig/camera.hpp"
#include "ig/pyramid.hpp"
#include "ig/slope_bound.hpp"
#include "ig/terrain.hpp"
#include "ig/terrain_db.hpp"
#include "ig/tile_cache.hpp"
#include "ig/tile_footprint.hpp"

#include <glm/vec3.hpp>

#include <cstdint>
#include <functional>
#include <limits>
#include <map>
#include <memory>
#include <set>
#include <string>
#include <unordered_map>
#include <utility>
#include <vector>

namespace ig {

// What preparing one frame found (display tiles of every level read; node tiles apart).
struct PagedFrameStats {
    std::uint64_t frame = 0;
    std::size_t required = 0;           // display tiles the frame's footprint needs
    std::size_t requiredCoarse = 0;     // of those, of levels >= 1 (fast caster)
    std::size_t copied = 0;             // copied into the map for this frame
    std::size_t substituted = 0;        // needed, not resident: filled from a coarser level
    std::size_t failed = 0;             // of those, unreadable (corrupt, truncated): reported holes
    std::size_t holes = 0;              // nothing resident above either: left as they were
    std::size_t released = 0;           // tiles no longer needed whose pages were given back
    std::size_t nodesRequired = 0;      // node tiles the footprint needs (fast caster)
    std::size_t nodesMissing = 0;       // of those, not resident: those nodes give no bound
    std::vector<std::string> failures;  // messages of failed tiles, each reported once
};

// The steps of placing a frame's tiles (PagedTerrain::Options::progress), in order.
enum class PlacingStep : std::uint8_t {
    Footprint,  // the tiles required and prefetched are known
    Requested,  // the cache has them (or has them on the way)
    Decided,    // the tiles to write chosen and their pages counted (kProgressTiles at a time)
    Released,   // pages given back (Options::progressPages at a time)
    Backed,     // fresh pages backed ahead of the writes (Options::progressPages at a time)
    Written,    // tiles copied into the map (kProgressTiles at a time)
    StandIns,   // stand-ins' cell maxima made (kProgressTiles at a time); last, all placed
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
        // What the casters reading the map need. False: level 0 only (reference, naive
        // casters). True: the fast caster's pyramid too, with `levels` coarser display levels
        // (kLevelsAuto, -1: all; 0: none, the max-height nodes only), as RenderOptions::levels.
        bool pyramid = false;
        int levels = 0;
        // Tiles no longer needed keep their pages (a tile that comes back is copied again)
        // until the pages the tiles placed and waiting hold pass this many bytes; then the
        // oldest waiting give theirs back, down to half of it (giving pages back is a system
        // call and a TLB shootdown across the renderer's threads). 0: the cache's budget.
        std::size_t mapBudgetBytes = 0;
        // Real-time detail (chooseDetail): where writing the tiles a frame needs would take
        // longer than this, the frame is drawn at a lower Intrinsics::detail, in steps of
        // 2^(-1/4) down to minDetail; it comes back a step a frame. 0: always full detail.
        double placeBudgetMs = 60.0;
        double minDetail = 0.5;
        // Called on the renderer's thread now and then while a frame's tiles are placed, with
        // the step just done: after the footprint, after the cache's requests, after every
        // progressPages pages given back or backed, every kProgressTiles tiles decided and
        // written, and once the stand-ins' bounds are made. A renderer process's sign of life,
        // since placing a frame can take seconds. Empty: nothing is called.
        std::function<void(PlacingStep)> progress;
        // Pages (4 KiB) given back or backed between two calls of `progress` (32 MiB).
        std::size_t progressPages = 8192;
    };
    static constexpr int kProgressTiles = 64;

    // `db` must outlive this. Loads the cache's resident coarse levels (InputError when the
    // budget cannot hold them).
    PagedTerrain(const TerrainDb& db, const Options& options);
    PagedTerrain(const PagedTerrain&) = delete;
    PagedTerrain& operator=(const PagedTerrain&) = delete;

    // The map the casters read (level 0 of the database, resident where a frame needed it).
    const TerrainMap& map() const { return map_; }
    // The database's tile size, samples a side.
    int tileSize() const { return db_.layout().tileSize(); }
    // The fast caster's pyramid over map() and the database's slope bounds (null unless
    // Options::pyramid): for RenderOptions::pyramid and ::slopes.
    std::shared_ptr<const TerrainPyramid> pyramid() const { return pyramid_; }
    std::shared_ptr<const SlopeBlocks> slopes() const { return slopes_; }
    TileCache& cache() { return cache_; }
    const TileCache& cache() const { return cache_; }

    // Between frames, on the renderer's thread (never while a caster reads the map): requests
    // the tiles `camera` needs and, moving at `velocity` (m/s) and turning at `yawRate`
    // (rad/s), those to prefetch; then fills the map. With `wait` it first waits until every
    // request is served (a program rendering without a deadline: its image equals the
    // in-memory render's where every tile could be read); without, it never waits and
    // substitutes what is missing (the real-time pipeline).
    // `otherEye`, when given, is a stereo pair's right eye: its tiles are the frame's too.
    PagedFrameStats prepare(const Camera& camera, bool wait, const glm::dvec3& velocity = {},
                            double yawRate = 0.0, const Camera* otherEye = nullptr);

    // For a real-time frame of `camera` (its detail ignored), before prepare(): the detail to
    // draw it at (set it in the camera's intrinsics), in steps of 2^(-1/4) from the last
    // frame's. Coarser while writing the tiles the frame needs, at the cost per tile measured
    // over the frames so far, would pass Options::placeBudgetMs (down to minDetail); a step
    // finer once every tile that step adds is loaded and the frames' writes there would fit.
    // 1 until a frame has written enough tiles to measure.
    double chooseDetail(const Camera& camera);
    // The display and node tiles `camera`'s footprint needs that are not placed from their
    // own data (each a write), and of those, not loaded.
    struct Writes {
        std::size_t tiles = 0, missing = 0;
    };
    Writes tilesToPlace(const Camera& camera) const;
    // The cost of a tile written, measured (ms; 0 before any).
    double msPerTile() const { return msPerTile_; }

    // Before a flight's first frame: loads (waiting) the tiles of `camera`'s view turned to
    // `headings` headings all round, so that a turn from the start finds its tiles resident
    // (within the cache's budget), at full detail and at chooseDetail's lowest. Places
    // nothing: the next prepare() places its frame's.
    void warmUp(const Camera& camera, int headings = 6);

    // Places the level-0 tile under world (x, y) (clamped to the map), waiting for it, and
    // only it (what a program needs before its first frame: the ground under a pose given as
    // a height above it). The next prepare() keeps it only if its frame needs it.
    PagedFrameStats placeAround(double x, double y);

    // For a thread that asks the map questions rather than rendering it (a host's height and
    // line-of-sight queries, sim/terrain_queries.hpp). The level-0 tile whose cell holds world
    // (x, y) (clamped to the map): the bilinear surface there reads it alone (tiles share their
    // edge samples).
    TileKey tileUnder(double x, double y) const;
    // Adds the level-0 tiles an exact cast from `origin` along `dir` can read within
    // [0, maxRange] before its hit: those its ground track crosses where it is within the
    // terrain's height range and not above the finest resident bound on the tile.
    void addRayTiles(const glm::dvec3& origin, const glm::dvec3& dir, std::set<TileKey>& out,
                     double maxRange = std::numeric_limits<double>::infinity()) const;
    // addRayTiles along the rays of `camera`'s control points (cast exactly on level 0 by
    // renderFrame, at any distance).
    void addControlPointTiles(const Camera& camera, std::set<TileKey>& out) const;
    // Places exactly `tiles`, waiting for them (the others placed leave, as between frames).
    PagedFrameStats placeTiles(const std::set<TileKey>& tiles) { return page(tiles, {}, true); }
    // Whether `key` is placed from its own data (not a stand-in from a coarser level).
    bool placedExact(const TileKey& key) const;

    // Display tiles placed in the map (and pyramid) now, and how many of them are stand-ins.
    std::size_t placedTiles() const;
    std::size_t substitutedTiles() const;
    // The display tiles placed as stand-ins now.
    std::vector<TileKey> standIns() const;
    // Bytes of the pages that placed tiles (display and node), and those whose pages are not
    // given back yet, have written: the most the map's and pyramid's arrays can hold.
    std::size_t placedBytes() const;
    // Bytes of the map's and pyramid's arrays in memory now (mincore over the sparse blocks).
    std::size_t residentMapBytes() const;

  private:
    struct Placed {
        int sourceLevel = 0;  // the tile's own level: itself; a coarser one: upsampled from it
        bool failed = false;  // its own read failed
    };
    // One level's arrays: display (samples w x h, colours, cell maxima) or nodes (w x h,
    // stored complemented).
    struct Grid {
        int w = 0, h = 0;
        std::uint16_t* heights = nullptr;
        Rgb8* colors = nullptr;
        std::uint16_t* cellMax = nullptr;
        std::uint16_t* nodes = nullptr;
    };

    Grid grid(TileKind kind, int level) const;
    // Whether this map holds `k`'s kind and level: level 0, or the pyramid's levels and nodes.
    bool holds(const TileKey& k) const;
    // chooseDetail's coarsest step (detail 2^(-steps/4), the lowest not below minDetail); 0
    // without a placing budget.
    int detailSteps() const;
    // A bound (metres) on the surface over level-0 tile (tx, ty): the finest resident node
    // covering it, else the map's highest point.
    double tileBound(int tx, int ty) const;
    PagedFrameStats page(const std::set<TileKey>& required, const std::set<TileKey>& prefetch,
                         bool wait);
    void copyTile(const TerrainTile& tile);
    void fillFromCoarser(const TileKey& key, const TerrainTile& coarse);
    void updateCellMax(const TileKey& key);
    // The pages a tile's data lie in (sorted, each once).
    void tilePages(const TileKey& key, std::vector<std::uintptr_t>& out) const;
    // A tile enters the map: placed, and holding its pages.
    void place(const TileKey& key, const Placed& p);
    void hold(const TileKey& key);
    // A tile's pages no longer held by it; those no tile holds now go to `freed`.
    void release(const TileKey& key, std::vector<std::uintptr_t>& freed);
    void givePagesBack(std::vector<std::uintptr_t>& freed);
    // Gives back (Released) or backs (Backed) `pages`, then clears it.
    void advisePages(std::vector<std::uintptr_t>& pages, PlacingStep step);
    // Backs the pages hold() found no tile holding before (fresh_), ahead of their writes.
    void populateFresh();
    // Whether an exact placed tile (not a stand-in) of `self`'s level other than `self` holds
    // sample (x, y) of that level.
    bool heldByExactNeighbour(const TileKey& self, int x, int y) const;

    const TerrainDb& db_;
    Options options_;
    TileCache cache_;
    TerrainMap map_;
    std::shared_ptr<TerrainPyramid> pyramid_;
    std::shared_ptr<const SlopeBlocks> slopes_;
    std::map<TileKey, Placed> placed_;
    // Tiles no longer placed whose pages are not given back yet: the frame they left.
    std::map<TileKey, std::uint64_t> leaving_;
    std::set<TileKey> held_;  // placed_ and leaving_: the tiles holding pages
    std::unordered_map<std::uintptr_t, std::uint32_t> pageRefs_;  // page -> tiles holding it
    std::vector<std::uintptr_t> pages_;                           // scratch
    std::vector<std::uintptr_t> fresh_;  // pages a tile placed in this frame holds first
    std::vector<PageRun> runs_;          // scratch
    std::set<TileKey> reported_;         // failed tiles already reported
    std::uint64_t frame_ = 0;
    int detailStep_ = 0;           // chooseDetail's last: detail 2^(-step/4)
    double msPerTile_ = 0.0;       // page()'s time per tile written, smoothed
    double copiedPerFrame_ = 0.0;  // tiles page() wrote a frame, smoothed
};

// The ground of a paged map for what is worked out before a run, off the field thread (a scene's
// placements): each height read first places, waiting, the level-0 tile under its point, so it
// is the whole map's surfaceHeight there. `paged` must outlive this; one thread at a time.
class PlacingGround final : public Ground {
  public:
    explicit PlacingGround(PagedTerrain& paged) : paged_(paged) {}
    double groundHeight(double x, double y) const override {
        paged_.placeAround(x, y);
        return paged_.map().groundHeight(x, y);
    }
    double extentX() const override { return paged_.map().extentX(); }
    double extentY() const override { return paged_.map().extentY(); }

  private:
    PagedTerrain& paged_;
};

}  // namespace ig
