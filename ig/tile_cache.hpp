// Resident tiles of a terrain database under a fixed memory budget: loaded asynchronously by
// loader threads, evicted least recently needed first; a frame never waits for a tile — where
// one is missing the finest resident coarser tile stands in (counted as a substitution).
#pragma once

#include "ig/terrain_db.hpp"

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <set>
#include <string>
#include <thread>
#include <utility>
#include <vector>

namespace ig {

struct TileCacheStats {
    std::uint64_t tilesRead = 0;      // tiles loaded from the database
    std::uint64_t bytesRead = 0;      // their stored bytes
    std::uint64_t hits = 0;           // required tiles resident when asked for
    std::uint64_t misses = 0;         // required tiles not resident (requested)
    std::uint64_t substitutions = 0;  // lookups answered by a coarser tile
    std::uint64_t holes = 0;          // lookups with nothing resident at or above the tile
    std::uint64_t evictions = 0;
    std::uint64_t failures = 0;    // tiles that could not be read (corrupt, truncated)
    std::uint64_t overBudget = 0;  // loaded tiles dropped: no room without evicting this frame's
};

class TileCache;

// A bound (metres) on the surface over level-0 display tile (tx, ty) of `db`: the finest node
// resident in `cache` covering it, else `otherwise`. Never blocks.
double residentTileBound(const TileCache& cache, const TerrainDb& db, int tx, int ty,
                         double otherwise);

class TileCache {
  public:
    struct Options {
        std::size_t budgetBytes = std::size_t{512} << 20;
        int loaderThreads = 2;
        // Display levels from this one up, and every node level from it up, are loaded at
        // construction and never evicted (-1: the coarsest levels whose tiles take at most an
        // eighth of the budget).
        int residentFromLevel = -1;
    };

    // Loads the resident coarse levels synchronously; throws InputError when they do not fit
    // the budget or cannot be read.
    TileCache(const TerrainDb& db, const Options& options);
    ~TileCache();
    TileCache(const TileCache&) = delete;
    TileCache& operator=(const TileCache&) = delete;

    // Between frames, on the renderer's thread: the tiles frame `frame` needs (they become the
    // most recently needed; missing ones are requested first), and those to prefetch (requested
    // after them). Requests left from earlier frames are dropped. Never blocks on the disk.
    void beginFrame(std::uint64_t frame, const std::set<TileKey>& required,
                    const std::set<TileKey>& prefetch = {});

    // The tile if resident (never blocks on a load).
    std::shared_ptr<const TerrainTile> find(const TileKey& key) const;
    // The tile, or where it is missing the finest resident tile above it (coarser display
    // level, or coarser node level); null only when nothing above is resident (a hole).
    std::shared_ptr<const TerrainTile> findOrCoarser(const TileKey& key) const;

    // Blocks until no request is queued or loading (tests and tools only).
    void waitIdle() const;

    // Test hook: tiles for which it returns true are never loaded (as if the disk never
    // answered).
    void setWithheld(std::function<bool(const TileKey&)> withheld);

    TileCacheStats stats() const;
    std::size_t residentBytes() const;
    std::size_t residentTiles() const;
    std::size_t budgetBytes() const { return options_.budgetBytes; }
    int residentFromLevel() const { return residentFrom_; }
    // The message of a tile that failed to load (empty when none).
    std::string failure(const TileKey& key) const;

  private:
    struct Entry {
        std::shared_ptr<const TerrainTile> tile;
        std::size_t bytes = 0;
        std::uint64_t lastNeeded = 0;
        bool pinned = false;
    };
    void loaderLoop();
    bool isPinned(const TileKey& key) const;
    void insertLocked(const TileKey& key, std::shared_ptr<const TerrainTile> tile,
                      std::size_t bytes);
    // Sets a resident entry's last frame needed (and its place in lru_).
    void touchLocked(std::pair<const TileKey, Entry>& entry, std::uint64_t lastNeeded);

    const TerrainDb& db_;
    Options options_;
    int residentFrom_ = 0;
    mutable std::mutex mutex_;
    mutable std::condition_variable work_, idle_;
    std::map<TileKey, Entry> resident_;
    // The unpinned resident tiles by (last frame needed, key): the eviction order.
    std::set<std::pair<std::uint64_t, TileKey>> lru_;
    std::deque<TileKey> urgent_, background_;
    std::set<TileKey> queued_, loading_;
    std::set<TileKey> required_;  // the current frame's
    std::map<TileKey, std::string> failed_;
    std::function<bool(const TileKey&)> withheld_;
    std::uint64_t frame_ = 0;
    std::size_t bytes_ = 0;
    bool stop_ = false;
    TileCacheStats stats_;
    mutable std::atomic<std::uint64_t> substitutions_{0}, holes_{0};
    std::vector<std::thread> loaders_;
};

}  // namespace ig
