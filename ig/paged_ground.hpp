// The ground of a terrain database paged beyond memory, for the threads that are not the
// renderer's: the flight model's floor on the field thread. It keeps a small tile cache and a
// thread of its own; groundHeight() never blocks on the disk, never allocates and takes no lock
// the loaders hold: where the level-0 tile under the point is resident it answers the map's
// bilinear surface (TerrainMap::surfaceHeight of the whole map, to the bit), elsewhere a bound on
// or above the surface (the finest resident max-height node over the tile). Its thread keeps the
// tiles around the last point asked for resident, and prefetches those ahead along its motion.
// docs/design/terrain_db.md, "A ground for the other threads".
#pragma once

#include "ig/terrain.hpp"
#include "ig/terrain_db.hpp"
#include "ig/tile_cache.hpp"

#include <atomic>
#include <condition_variable>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <thread>
#include <utility>
#include <vector>

namespace ig {

class PagedGround final : public Ground {
  public:
    struct Options {
        std::size_t budgetBytes = std::size_t{16} << 20;
        // Level-0 tiles kept around the last point asked for: (2r + 1)^2 of them.
        int radiusTiles = 2;
        // Prefetched along the motion: this many seconds ahead.
        double lookahead = 2.0;
        // Seconds between the thread's updates.
        double period = 0.02;
        int loaderThreads = 1;
    };
    struct Stats {
        std::uint64_t exact = 0;    // answered from a resident level-0 tile
        std::uint64_t bounded = 0;  // answered by a node's bound (tile not resident)
        std::uint64_t outside = 0;  // beyond the tiles kept: the map's highest point
    };

    // `db` must outlive this. Starts the thread; nothing is kept until a point is asked for or
    // waitAround() places one.
    PagedGround(const TerrainDb& db, const Options& options);
    ~PagedGround() override;
    PagedGround(const PagedGround&) = delete;
    PagedGround& operator=(const PagedGround&) = delete;

    double groundHeight(double x, double y) const override;
    double extentX() const override;
    double extentY() const override;
    // The point the thread keeps the tiles around, from now on (any thread): without it, the
    // last point asked for. A caller asking about several places (a host's entities) names
    // the one to follow (its ownship).
    void follow(double x, double y) const override;
    // Loads, waiting, the tiles around (x, y) and keeps them (before a run, off the field
    // thread): the next groundHeight() there is exact where the tiles could be read.
    void waitAround(double x, double y);
    // Whether groundHeight(x, y) would answer from a resident level-0 tile now.
    bool exactAt(double x, double y) const;

    Stats stats() const;
    const TileCache& cache() const { return cache_; }
    // Test hook: tiles for which it returns true are never loaded (TileCache::setWithheld).
    void setWithheld(std::function<bool(const TileKey&)> withheld) {
        cache_.setWithheld(std::move(withheld));
    }

  private:
    // The tiles around a point, published to the readers whole: exact tiles (null where not
    // resident) and each one's bound in metres.
    struct Snapshot {
        int tx0 = 0, ty0 = 0, n = 0;
        std::vector<std::shared_ptr<const TerrainTile>> tiles;
        std::vector<double> bound;
    };
    struct Cell {
        int ix, iy;
        double fx, fy;
    };
    Cell cellOf(double x, double y) const;
    // The snapshot's slot of the tile holding cell `c`; -1 when it holds none there.
    std::ptrdiff_t slotOf(const Snapshot& s, const Cell& c) const;
    void loop();
    // Requests the tiles around (x, y) (and ahead along (vx, vy) m/s), waits for them when
    // `wait`, and publishes what is resident. Holds update_.
    void update(double x, double y, double vx, double vy, bool wait);

    const TerrainDb& db_;
    Options options_;
    TileCache cache_;
    double highest_ = 0.0;
    // The published snapshot. Its mutex is held only to copy or swap the pointer (never while
    // loading or reading tiles): libstdc++'s std::atomic<std::shared_ptr> orders its internal
    // lock in a way ThreadSanitizer cannot follow.
    std::shared_ptr<const Snapshot> snapshot_;
    mutable std::mutex snapshotMutex_;
    std::shared_ptr<const Snapshot> published() const {
        std::lock_guard<std::mutex> lock(snapshotMutex_);
        return snapshot_;
    }
    std::shared_ptr<const Snapshot> retired_;  // the one replaced last (update_ guards it)
    // The last point asked for, and how many asks so far (the thread follows them).
    mutable std::atomic<double> lastX_{0.0}, lastY_{0.0};
    mutable std::atomic<std::uint64_t> asks_{0};
    mutable std::atomic<bool> followed_{
        false};  // follow() was called: asks no longer move the point
    mutable std::atomic<std::uint64_t> exact_{0}, bounded_{0}, outside_{0};
    std::mutex update_;  // one update at a time (the cache has one caller of beginFrame)
    std::uint64_t frame_ = 0;
    std::mutex mutex_;
    std::condition_variable wake_;
    bool stop_ = false;
    std::thread thread_;
};

}  // namespace ig
