// The cache's lock guards the resident map, the queues and the counters; loader threads hold it
// only to take a request and to insert a tile, never while reading or decoding.
//
// Eviction: a tile carries the last frame that needed it (a prefetched tile counts as needed
// the frame before). A new tile may evict only tiles needed less recently than itself, oldest
// first; when that does not free enough room it is dropped, so the budget is never exceeded and
// the current frame's tiles are never evicted for a prefetch.
#include "ig/tile_cache.hpp"

#include "base/check.hpp"
#include "base/fork_gate.hpp"
#include "ig/error.hpp"

#include <algorithm>
#include <bit>

namespace ig {

namespace {

std::size_t storedTileBytes(const TerrainDbLayout& layout, const TileKey& key) {
    int x0, y0, w, h;
    layout.tileExtent(key, x0, y0, w, h);
    const std::size_t n = static_cast<std::size_t>(w) * h;
    if (key.kind == TileKind::Nodes) return n * 2;
    return n * 5 + static_cast<std::size_t>(w - 1) * (h - 1) * 2;
}

// Bytes of every tile of display level k and node level k (decoded).
std::size_t levelBytes(const TerrainDbLayout& layout, int k) {
    std::size_t total = 0;
    for (const TileKind kind : {TileKind::Display, TileKind::Nodes}) {
        if (kind == TileKind::Display && k >= layout.displayLevels()) continue;
        if (kind == TileKind::Nodes && (k < 1 || k >= layout.nodeLevels())) continue;
        for (int ty = 0; ty < layout.tilesY(kind, k); ++ty)
            for (int tx = 0; tx < layout.tilesX(kind, k); ++tx)
                total += storedTileBytes(layout, TileKey{kind, k, tx, ty});
    }
    return total;
}

}  // namespace

TileCache::TileCache(const TerrainDb& db, const Options& options) : db_(db), options_(options) {
    const TerrainDbLayout& layout = db.layout();
    const int top = std::max(layout.displayLevels(), layout.nodeLevels()) - 1;
    // Node levels past the display levels are always resident (they are a few nodes wide).
    std::size_t pinnedBytes = 0;
    for (int k = layout.displayLevels(); k <= top; ++k)
        pinnedBytes += levelBytes(layout, k);
    residentFrom_ = layout.displayLevels() - 1;
    pinnedBytes += levelBytes(layout, residentFrom_);
    if (options.residentFromLevel >= 0) {
        residentFrom_ = std::min(options.residentFromLevel, layout.displayLevels() - 1);
        pinnedBytes = 0;
        for (int k = residentFrom_; k <= top; ++k)
            pinnedBytes += levelBytes(layout, k);
    } else {
        while (residentFrom_ > 0 &&
               pinnedBytes + levelBytes(layout, residentFrom_ - 1) <= options.budgetBytes / 8) {
            --residentFrom_;
            pinnedBytes += levelBytes(layout, residentFrom_);
        }
    }
    if (pinnedBytes > options.budgetBytes) {
        throw InputError(db.path() + ": cache budget of " +
                         std::to_string(options.budgetBytes >> 20) + " MB is below the " +
                         std::to_string((pinnedBytes + (1 << 20) - 1) >> 20) +
                         " MB the coarse levels kept resident need");
    }
    for (int k = residentFrom_; k <= top; ++k) {
        for (const TileKind kind : {TileKind::Display, TileKind::Nodes}) {
            if (kind == TileKind::Display && k >= layout.displayLevels()) continue;
            if (kind == TileKind::Nodes && (k < 1 || k >= layout.nodeLevels())) continue;
            for (int ty = 0; ty < layout.tilesY(kind, k); ++ty) {
                for (int tx = 0; tx < layout.tilesX(kind, k); ++tx) {
                    const TileKey key{kind, k, tx, ty};
                    auto tile = std::make_shared<const TerrainTile>(db.readTile(key));
                    Entry e;
                    e.bytes = tile->bytes();
                    e.tile = std::move(tile);
                    e.pinned = true;
                    bytes_ += e.bytes;
                    resident_.emplace(key, std::move(e));
                    ++stats_.tilesRead;
                    stats_.bytesRead += db.storedBytes(key);
                }
            }
        }
    }
    for (int i = 0; i < std::max(options.loaderThreads, 1); ++i)
        loaders_.push_back(base::ForkGate::startThread([this] { loaderLoop(); }));
}

TileCache::~TileCache() {
    {
        const std::lock_guard lock(mutex_);
        stop_ = true;
    }
    work_.notify_all();
    for (std::thread& t : loaders_)
        t.join();
}

bool TileCache::isPinned(const TileKey& key) const {
    return key.level >= residentFrom_;
}

void TileCache::setWithheld(std::function<bool(const TileKey&)> withheld) {
    const std::lock_guard lock(mutex_);
    withheld_ = std::move(withheld);
}

void TileCache::beginFrame(std::uint64_t frame, const std::set<TileKey>& required,
                           const std::set<TileKey>& prefetch) {
    {
        const std::lock_guard lock(mutex_);
        frame_ = frame;
        urgent_.clear();
        background_.clear();
        queued_.clear();
        for (const TileKey& key : required) {
            const auto it = resident_.find(key);
            if (it != resident_.end()) {
                ++stats_.hits;
                touchLocked(*it, frame);
                continue;
            }
            ++stats_.misses;
            if (failed_.count(key) || loading_.count(key)) continue;
            urgent_.push_back(key);
            queued_.insert(key);
        }
        for (const TileKey& key : prefetch) {
            const auto it = resident_.find(key);
            if (it != resident_.end()) {
                touchLocked(*it, std::max(it->second.lastNeeded, frame > 0 ? frame - 1 : 0));
                continue;
            }
            if (failed_.count(key) || loading_.count(key) || queued_.count(key)) continue;
            background_.push_back(key);
            queued_.insert(key);
        }
        required_ = required;
    }
    work_.notify_all();
}

void TileCache::loaderLoop() {
    std::unique_lock lock(mutex_);
    for (;;) {
        work_.wait(lock, [&] { return stop_ || !urgent_.empty() || !background_.empty(); });
        if (stop_) return;
        // One tile's work is one piece of work for a fork to wait on (base/fork_gate.hpp),
        // entered with the lock released: the gate may wait.
        lock.unlock();
        const base::ForkGate::Working working;
        lock.lock();
        if (stop_) return;
        if (urgent_.empty() && background_.empty()) continue;
        std::deque<TileKey>& q = !urgent_.empty() ? urgent_ : background_;
        const TileKey key = q.front();
        q.pop_front();
        queued_.erase(key);
        if (withheld_ && withheld_(key)) {
            if (urgent_.empty() && background_.empty() && loading_.empty()) idle_.notify_all();
            continue;
        }
        loading_.insert(key);
        lock.unlock();
        std::shared_ptr<const TerrainTile> tile;
        std::string error;
        try {
            tile = std::make_shared<const TerrainTile>(db_.readTile(key));
        } catch (const InputError& e) {
            error = e.what();
        }
        lock.lock();
        loading_.erase(key);
        if (tile) {
            ++stats_.tilesRead;
            stats_.bytesRead += db_.storedBytes(key);
            const std::size_t bytes = tile->bytes();
            insertLocked(key, std::move(tile), bytes);
        } else {
            ++stats_.failures;
            failed_.emplace(key, error);
        }
        if (urgent_.empty() && background_.empty() && loading_.empty()) idle_.notify_all();
    }
}

void TileCache::insertLocked(const TileKey& key, std::shared_ptr<const TerrainTile> tile,
                             std::size_t bytes) {
    if (resident_.count(key)) return;
    const std::uint64_t needed = required_.count(key) ? frame_ : (frame_ > 0 ? frame_ - 1 : 0);
    while (bytes_ + bytes > options_.budgetBytes) {
        // The least recently needed unpinned tile (the first key of those, as a scan in key
        // order would find it).
        if (lru_.empty() || lru_.begin()->first >= needed) {
            ++stats_.overBudget;
            return;
        }
        const auto victim = resident_.find(lru_.begin()->second);
        bytes_ -= victim->second.bytes;
        lru_.erase(lru_.begin());
        resident_.erase(victim);
        ++stats_.evictions;
    }
    Entry e;
    e.tile = std::move(tile);
    e.bytes = bytes;
    e.lastNeeded = needed;
    bytes_ += bytes;
    resident_.emplace(key, std::move(e));
    lru_.emplace(needed, key);
}

void TileCache::touchLocked(std::pair<const TileKey, Entry>& entry, std::uint64_t lastNeeded) {
    Entry& e = entry.second;
    if (e.lastNeeded == lastNeeded) return;
    if (!e.pinned) {
        lru_.erase({e.lastNeeded, entry.first});
        lru_.emplace(lastNeeded, entry.first);
    }
    e.lastNeeded = lastNeeded;
}

std::shared_ptr<const TerrainTile> TileCache::find(const TileKey& key) const {
    const std::lock_guard lock(mutex_);
    const auto it = resident_.find(key);
    return it == resident_.end() ? nullptr : it->second.tile;
}

std::shared_ptr<const TerrainTile> TileCache::findOrCoarser(const TileKey& key) const {
    const TerrainDbLayout& layout = db_.layout();
    const int levels = key.kind == TileKind::Display ? layout.displayLevels() : layout.nodeLevels();
    const std::lock_guard lock(mutex_);
    TileKey k = key;
    for (;;) {
        const auto it = resident_.find(k);
        if (it != resident_.end()) {
            if (k.level != key.level) substitutions_.fetch_add(1, std::memory_order_relaxed);
            return it->second.tile;
        }
        if (k.level + 1 >= levels) break;
        k.level += 1;
        k.tx >>= 1;
        k.ty >>= 1;
    }
    holes_.fetch_add(1, std::memory_order_relaxed);
    return nullptr;
}

void TileCache::waitIdle() const {
    std::unique_lock lock(mutex_);
    idle_.wait(lock, [&] { return urgent_.empty() && background_.empty() && loading_.empty(); });
}

TileCacheStats TileCache::stats() const {
    const std::lock_guard lock(mutex_);
    TileCacheStats s = stats_;
    s.substitutions = substitutions_.load();
    s.holes = holes_.load();
    return s;
}

std::size_t TileCache::residentBytes() const {
    const std::lock_guard lock(mutex_);
    return bytes_;
}

std::size_t TileCache::residentTiles() const {
    const std::lock_guard lock(mutex_);
    return resident_.size();
}

std::string TileCache::failure(const TileKey& key) const {
    const std::lock_guard lock(mutex_);
    const auto it = failed_.find(key);
    return it == failed_.end() ? std::string() : it->second;
}

double residentTileBound(const TileCache& cache, const TerrainDb& db, int tx, int ty,
                         double otherwise) {
    const TerrainDbLayout& layout = db.layout();
    const TerrainDbInfo& info = db.info();
    const int t = layout.tileSize();
    const int j0 = std::countr_zero(static_cast<unsigned>(t));  // a node per level-0 tile
    for (int j = std::max(j0, 1); j < layout.nodeLevels(); ++j) {
        // The node over the tile's first cell covers the whole tile from level j0 up.
        const int nx = (tx * t) >> j, ny = (ty * t) >> j;
        const auto tile = cache.find(TileKey{TileKind::Nodes, j, nx / t, ny / t});
        if (!tile) continue;
        const std::size_t i =
            static_cast<std::size_t>(ny - tile->y0) * tile->width + (nx - tile->x0);
        return tile->maxima[i] * info.heightScale + info.heightOffset;
    }
    return otherwise;
}

}  // namespace ig
