// A snapshot of the tiles around the point is built on the ground's thread and published whole
// (a shared pointer swapped under a mutex held for nothing else); a reader copies it, looks up one
// tile and reads four samples. The thread keeps the snapshot it replaced until the next one, so the
// reader never drops the last reference to a snapshot (which would free it on the field thread).
#include "ig/paged_ground.hpp"

#include "base/fork_gate.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <set>

namespace ig {

namespace {

TileCache::Options cacheOptions(const PagedGround::Options& o) {
    TileCache::Options c;
    c.budgetBytes = o.budgetBytes;
    c.loaderThreads = o.loaderThreads;
    return c;
}

}  // namespace

PagedGround::PagedGround(const TerrainDb& db, const Options& options)
    : db_(db), options_(options), cache_(db, cacheOptions(options)) {
    const TerrainDbInfo& info = db.info();
    highest_ = std::max(info.minRaw * info.heightScale + info.heightOffset,
                        info.maxRaw * info.heightScale + info.heightOffset);
    options_.radiusTiles = std::clamp(options_.radiusTiles, 0, 64);
    thread_ = base::ForkGate::startThread([this] { loop(); });
}

PagedGround::~PagedGround() {
    {
        std::lock_guard<std::mutex> lock(mutex_);
        stop_ = true;
    }
    wake_.notify_all();
    thread_.join();
}

// As TerrainMap::surfaceHeight finds its cell (clamped to the grid).
PagedGround::Cell PagedGround::cellOf(double x, double y) const {
    const TerrainDbInfo& info = db_.info();
    Cell c;
    gridCellOf(x, info.spacingX, info.width, c.ix, c.fx);
    gridCellOf(y, info.spacingY, info.height, c.iy, c.fy);
    return c;
}

double PagedGround::groundHeight(double x, double y) const {
    if (!std::isfinite(x) || !std::isfinite(y)) return std::numeric_limits<double>::quiet_NaN();
    if (!followed_.load(std::memory_order_relaxed)) {
        lastX_.store(x, std::memory_order_relaxed);
        lastY_.store(y, std::memory_order_relaxed);
        asks_.fetch_add(1, std::memory_order_release);
    }
    const Cell c = cellOf(x, y);
    const std::shared_ptr<const Snapshot> s = published();
    if (s) {
        if (const std::ptrdiff_t slot = slotOf(*s, c); slot >= 0) {
            const auto k = static_cast<std::size_t>(slot);
            const TerrainTile* tile = s->tiles[k].get();
            if (!tile) {
                bounded_.fetch_add(1, std::memory_order_relaxed);
                return s->bound[k];
            }
            exact_.fetch_add(1, std::memory_order_relaxed);
            const TerrainDbInfo& info = db_.info();
            const int ix1 = std::min(c.ix + 1, info.width - 1);
            const int iy1 = std::min(c.iy + 1, info.height - 1);
            auto h = [&](int sx, int sy) {
                const std::size_t at = static_cast<std::size_t>(sy - tile->y0) * tile->width +
                                       static_cast<std::size_t>(sx - tile->x0);
                return tile->heights[at] * info.heightScale + info.heightOffset;
            };
            return bilinearHeight(h(c.ix, c.iy), h(ix1, c.iy), h(c.ix, iy1), h(ix1, iy1), c.fx,
                                  c.fy);
        }
    }
    outside_.fetch_add(1, std::memory_order_relaxed);
    return highest_;
}

double PagedGround::extentX() const {
    return (db_.info().width - 1) * db_.info().spacingX;
}

double PagedGround::extentY() const {
    return (db_.info().height - 1) * db_.info().spacingY;
}

void PagedGround::follow(double x, double y) const {
    if (!std::isfinite(x) || !std::isfinite(y)) return;
    followed_.store(true, std::memory_order_relaxed);
    lastX_.store(x, std::memory_order_relaxed);
    lastY_.store(y, std::memory_order_relaxed);
    asks_.fetch_add(1, std::memory_order_release);
}

std::ptrdiff_t PagedGround::slotOf(const Snapshot& s, const Cell& c) const {
    const int t = db_.layout().tileSize();
    const int i = c.ix / t - s.tx0, j = c.iy / t - s.ty0;
    if (i < 0 || j < 0 || i >= s.n || j >= s.n) return -1;
    return static_cast<std::ptrdiff_t>(j) * s.n + i;
}

bool PagedGround::exactAt(double x, double y) const {
    const std::shared_ptr<const Snapshot> s = published();
    if (!s) return false;
    const std::ptrdiff_t slot = slotOf(*s, cellOf(x, y));
    return slot >= 0 && s->tiles[static_cast<std::size_t>(slot)] != nullptr;
}

PagedGround::Stats PagedGround::stats() const {
    return Stats{exact_.load(std::memory_order_relaxed), bounded_.load(std::memory_order_relaxed),
                 outside_.load(std::memory_order_relaxed)};
}

void PagedGround::waitAround(double x, double y) {
    update(x, y, 0.0, 0.0, true);
}

void PagedGround::update(double x, double y, double vx, double vy, bool wait) {
    std::lock_guard<std::mutex> lock(update_);
    const TerrainDbLayout& layout = db_.layout();
    const TerrainDbInfo& info = db_.info();
    const int t = layout.tileSize();
    const int tilesX = layout.tilesX(TileKind::Display, 0);
    const int tilesY = layout.tilesY(TileKind::Display, 0);
    const int r = options_.radiusTiles;
    auto tileOf = [&](double px, double py, int& tx, int& ty) {
        const Cell c = cellOf(px, py);
        tx = std::min(c.ix / t, tilesX - 1);
        ty = std::min(c.iy / t, tilesY - 1);
    };
    auto around = [&](int cx, int cy, int radius, std::set<TileKey>& out) {
        for (int ty = std::max(cy - radius, 0); ty <= std::min(cy + radius, tilesY - 1); ++ty)
            for (int tx = std::max(cx - radius, 0); tx <= std::min(cx + radius, tilesX - 1); ++tx)
                out.insert(TileKey{TileKind::Display, 0, tx, ty});
    };
    int cx, cy;
    tileOf(x, y, cx, cy);
    std::set<TileKey> required, prefetch;
    around(cx, cy, r, required);
    const double speed = std::hypot(vx, vy);
    if (std::isfinite(speed) && speed > 0.0 && options_.lookahead > 0.0) {
        // Points ahead, a tile's length apart.
        const double tileM = t * std::min(info.spacingX, info.spacingY);
        const double reach = speed * options_.lookahead;
        for (double d = tileM; d <= reach + 0.5 * tileM; d += tileM) {
            int ax, ay;
            tileOf(x + vx / speed * d, y + vy / speed * d, ax, ay);
            around(ax, ay, std::min(r, 1), prefetch);
        }
        for (const TileKey& k : required)
            prefetch.erase(k);
    }
    cache_.beginFrame(++frame_, required, prefetch);
    if (wait) cache_.waitIdle();

    auto snap = std::make_shared<Snapshot>();
    snap->n = 2 * r + 1;
    snap->tx0 = cx - r;
    snap->ty0 = cy - r;
    const std::size_t cells = static_cast<std::size_t>(snap->n) * snap->n;
    snap->tiles.resize(cells);
    snap->bound.assign(cells, highest_);
    for (int j = 0; j < snap->n; ++j) {
        for (int i = 0; i < snap->n; ++i) {
            const int tx = snap->tx0 + i, ty = snap->ty0 + j;
            if (tx < 0 || ty < 0 || tx >= tilesX || ty >= tilesY) continue;
            const std::size_t k = static_cast<std::size_t>(j) * snap->n + i;
            snap->tiles[k] = cache_.find(TileKey{TileKind::Display, 0, tx, ty});
            if (!snap->tiles[k]) snap->bound[k] = residentTileBound(cache_, db_, tx, ty, highest_);
        }
    }
    // The replaced snapshot is dropped at the next update (see the top of the file).
    std::shared_ptr<const Snapshot> next(std::move(snap));
    {
        std::lock_guard<std::mutex> publish(snapshotMutex_);
        snapshot_.swap(next);
    }
    retired_ = std::move(next);
}

void PagedGround::loop() {
    using Clock = std::chrono::steady_clock;
    const auto period = std::chrono::duration<double>(std::max(options_.period, 0.001));
    std::uint64_t seen = 0;
    double px = 0.0, py = 0.0;
    Clock::time_point pt{};
    bool previous = false;
    std::unique_lock<std::mutex> lock(mutex_);
    while (!stop_) {
        wake_.wait_for(lock, period);
        if (stop_) break;
        const std::uint64_t asks = asks_.load(std::memory_order_acquire);
        if (asks == seen) continue;  // nobody asked since: the point has not moved
        seen = asks;
        const double x = lastX_.load(std::memory_order_relaxed);
        const double y = lastY_.load(std::memory_order_relaxed);
        const Clock::time_point now = Clock::now();
        double vx = 0.0, vy = 0.0;
        if (previous) {
            const double dt = std::chrono::duration<double>(now - pt).count();
            if (dt > 0.0) {
                vx = (x - px) / dt;
                vy = (y - py) / dt;
            }
        }
        px = x;
        py = y;
        pt = now;
        previous = true;
        lock.unlock();
        {
            const base::ForkGate::Working working;
            update(x, y, vx, vy, false);
        }
        lock.lock();
    }
}

}  // namespace ig
