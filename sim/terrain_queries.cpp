#include "sim/terrain_queries.hpp"

#include "base/fork_gate.hpp"
#include "ig/surface_hit.hpp"
#include "io/field_clock.hpp"

#include <algorithm>
#include <cmath>
#include <set>
#include <utility>

namespace sim {

glm::dvec2 surfaceGradient(const ig::TerrainMap& map, double x, double y) {
    int ix, iy;
    double fx, fy;
    ig::gridCellOf(x, map.spacingX(), map.width(), ix, fx);
    ig::gridCellOf(y, map.spacingY(), map.height(), iy, fy);
    const int ix1 = std::min(ix + 1, map.width() - 1), iy1 = std::min(iy + 1, map.height() - 1);
    const double h00 = map.heightAt(ix, iy), h10 = map.heightAt(ix1, iy);
    const double h01 = map.heightAt(ix, iy1), h11 = map.heightAt(ix1, iy1);
    return {((h10 - h00) * (1 - fy) + (h11 - h01) * fy) / map.spacingX(),
            ((h01 - h00) * (1 - fx) + (h11 - h10) * fx) / map.spacingY()};
}

TerrainAnswer askTerrain(const ig::TerrainMap& map, const TerrainQuestion& q) {
    TerrainAnswer a;
    a.ticket = q.ticket;
    if (!q.line) {
        a.height = map.surfaceHeight(q.origin.x, q.origin.y);
        a.slope = surfaceGradient(map, q.origin.x, q.origin.y);
        return a;
    }
    const ig::TerrainRay ray(map, q.origin, q.dir);
    a.range = ig::exactHitInRange(map, ray, q.minRange, q.maxRange);
    if (a.range >= 0.0 && std::isfinite(a.range)) {
        const glm::dvec3 hit = ray.at(a.range);
        map.surfaceColor(hit.x, hit.y, a.color);
        a.slope = surfaceGradient(map, hit.x, hit.y);
    }
    return a;
}

TerrainAnswer askTerrain(const ig::NestedMaps& maps, const TerrainQuestion& q) {
    if (maps.insets.empty()) return askTerrain(*maps.global, q);
    TerrainAnswer a;
    a.ticket = q.ticket;
    if (!q.line) {
        a.height = maps.surfaceHeight(q.origin.x, q.origin.y);
        a.slope = surfaceGradient(*maps.global, q.origin.x, q.origin.y);
        for (const ig::NestedMaps::Part& p : maps.insets) {
            if (!p.placement->covers(q.origin.x, q.origin.y)) continue;
            const glm::dvec2 o = p.placement->origin;
            a.slope = surfaceGradient(*p.map, q.origin.x - o.x, q.origin.y - o.y);
            break;
        }
        return a;
    }
    // The nearest hit over the global map (lowered under each inset) and every inset's.
    const ig::TerrainMap* hitMap = maps.global;
    glm::dvec2 shift{0.0};
    const ig::TerrainRay ray(*maps.global, q.origin, q.dir);
    a.range = ig::exactHitInRange(*maps.global, ray, q.minRange, q.maxRange);
    if (!std::isfinite(a.range)) a.range = -1.0;
    for (const ig::NestedMaps::Part& p : maps.insets) {
        const glm::dvec2 o = p.placement->origin;
        const ig::TerrainRay local(*p.map, q.origin - glm::dvec3{o, 0.0}, q.dir);
        const double end = a.range >= 0.0 ? a.range : q.maxRange;
        const double t = ig::exactHitInRange(*p.map, local, q.minRange, end);
        if (t >= 0.0 && std::isfinite(t) && (a.range < 0.0 || t <= a.range)) {
            a.range = t;
            hitMap = p.map;
            shift = o;
        }
    }
    if (a.range >= 0.0) {
        const glm::dvec3 hit = ray.at(a.range);
        hitMap->surfaceColor(hit.x - shift.x, hit.y - shift.y, a.color);
        a.slope = surfaceGradient(*hitMap, hit.x - shift.x, hit.y - shift.y);
    }
    return a;
}

PagedTerrainQueries::PagedTerrainQueries(const ig::TerrainDb& db, const Options& options)
    : options_(options), paged_(db, [&] {
          ig::PagedTerrain::Options o;
          o.cache.budgetBytes = options.budgetBytes;
          o.cache.loaderThreads = std::max(options.loaderThreads, 1);
          return o;
      }()) {
    // Each map's share of the budget (ig::PagedNestedTerrain: the global map half of it with
    // insets, the insets the other half equally), half of which one placement may take: the
    // other half keeps the coarse levels and nodes. A level-0 display tile holds its samples
    // (shared edges included), colours and cell maxima.
    const std::size_t n = paged_.insetCount();
    const auto perPlacement = [&](std::size_t share, int tileSize) {
        const std::size_t side = static_cast<std::size_t>(tileSize) + 1;
        const std::size_t tileBytes = side * side * (2 + sizeof(ig::Rgb8) + 2);
        return std::max<std::size_t>(1, share / 2 / tileBytes);
    };
    maxTilesPerBatch_.push_back(perPlacement(n > 0 ? options.budgetBytes / 2 : options.budgetBytes,
                                             paged_.global().tileSize()));
    for (std::size_t k = 0; k < n; ++k)
        maxTilesPerBatch_.push_back(
            perPlacement(options.budgetBytes / 2 / n, paged_.inset(k).tileSize()));
    const std::size_t outstanding = std::max<std::size_t>(options.maxOutstanding, 1);
    options_.maxOutstanding = outstanding;
    asked_.reserve(outstanding);
    done_.reserve(outstanding);
    work_.reserve(outstanding);
    answers_.reserve(outstanding);
    thread_ = base::ForkGate::startThread([this] { loop(); });
}

PagedTerrainQueries::~PagedTerrainQueries() {
    {
        std::lock_guard<std::mutex> lock(mutex_);
        stop_ = true;
    }
    wake_.notify_all();
    thread_.join();
}

bool PagedTerrainQueries::ask(const TerrainQuestion& q) {
    {
        std::lock_guard<std::mutex> lock(mutex_);
        if (outstanding_ >= options_.maxOutstanding) {
            ++stats_.refused;
            return false;
        }
        ++outstanding_;
        ++stats_.asked;
        asked_.push_back({q, io::monotonicNs()});  // within the capacity reserved
    }
    wake_.notify_one();
    return true;
}

void PagedTerrainQueries::collect(std::vector<TerrainAnswer>& out, std::size_t max) {
    std::lock_guard<std::mutex> lock(mutex_);
    const std::size_t room = out.capacity() > out.size() ? out.capacity() - out.size() : 0;
    const std::size_t n = std::min({room, max, done_.size()});
    out.insert(out.end(), done_.begin(), done_.begin() + static_cast<std::ptrdiff_t>(n));
    done_.erase(done_.begin(), done_.begin() + static_cast<std::ptrdiff_t>(n));
    outstanding_ -= n;
}

std::size_t PagedTerrainQueries::outstanding() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return outstanding_;
}

void PagedTerrainQueries::waitIdle() {
    std::unique_lock<std::mutex> lock(mutex_);
    idle_.wait(lock, [&] { return asked_.empty() && working_ == 0; });
}

PagedTerrainQueries::Stats PagedTerrainQueries::stats() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return stats_;
}

void PagedTerrainQueries::setWithheld(std::function<bool(const ig::TileKey&)> withheld) {
    paged_.global().cache().setWithheld(withheld);
    for (std::size_t k = 0; k < paged_.insetCount(); ++k)
        paged_.inset(k).cache().setWithheld(withheld);
}

void PagedTerrainQueries::loop() {
    std::unique_lock<std::mutex> lock(mutex_);
    while (true) {
        wake_.wait(lock, [&] { return stop_ || !asked_.empty(); });
        if (stop_) return;
        // One batch is one piece of work for a fork to wait on (base/fork_gate.hpp), entered
        // with the lock released: the gate may wait.
        lock.unlock();
        const base::ForkGate::Working working;
        lock.lock();
        if (stop_) return;
        if (asked_.empty()) continue;
        work_.swap(asked_);  // both keep their capacity
        working_ = work_.size();
        lock.unlock();
        answerBatch(work_);
        lock.lock();
        const std::uint64_t now = io::monotonicNs();
        for (std::size_t i = 0; i < answers_.size(); ++i) {
            stats_.answered += 1;
            stats_.unknown += answers_[i].known ? 0 : 1;
            stats_.maxAnswerMs =
                std::max(stats_.maxAnswerMs, static_cast<double>(now - work_[i].askedNs) * 1e-6);
            done_.push_back(answers_[i]);
        }
        work_.clear();
        working_ = 0;
        idle_.notify_all();
    }
}

void PagedTerrainQueries::answerBatch(std::vector<Asked>& batch) {
    answers_.assign(batch.size(), TerrainAnswer{});
    const ig::NestedMaps& maps = paged_.maps();
    const std::size_t n = 1 + paged_.insetCount();  // the global map, then each inset
    const auto pagedMap = [&](std::size_t m) -> ig::PagedTerrain& {
        return m == 0 ? paged_.global() : paged_.inset(m - 1);
    };
    const auto shiftOf = [&](std::size_t m) {
        return m == 0 ? glm::dvec3(0.0) : glm::dvec3{paged_.placement(m - 1).origin, 0.0};
    };
    // The tiles each question reads, map by map (an inset's where it lies under the point or
    // the line).
    std::vector<std::vector<std::set<ig::TileKey>>> tiles(batch.size(),
                                                          std::vector<std::set<ig::TileKey>>(n));
    for (std::size_t i = 0; i < batch.size(); ++i) {
        const TerrainQuestion& q = batch[i].q;
        answers_[i].ticket = q.ticket;
        for (std::size_t m = 0; m < n; ++m) {
            const ig::PagedTerrain& p = pagedMap(m);
            const glm::dvec3 at = q.origin - shiftOf(m);
            if (!q.line) {
                if (m == 0 || paged_.placement(m - 1).covers(q.origin.x, q.origin.y))
                    tiles[i][m].insert(p.tileUnder(at.x, at.y));
            } else {
                const ig::TerrainRay ray(p.map(), at, q.dir);  // its unit direction
                p.addRayTiles(at, ray.dir, tiles[i][m], q.maxRange);
            }
        }
    }
    // Groups of questions whose tiles fit one placement of every map, in order; one that needs
    // more than a placement may hold is not known.
    std::vector<std::set<ig::TileKey>> group(n);
    std::size_t first = 0;
    const auto flush = [&](std::size_t end) {
        if (first < end) {
            std::size_t copied = 0;
            for (std::size_t m = 0; m < n; ++m) {
                if (m > 0 && group[m].empty()) continue;
                copied += pagedMap(m).placeTiles(group[m]).copied;
            }
            std::lock_guard<std::mutex> lock(mutex_);
            ++stats_.batches;
            stats_.tilesRead += copied;
        }
        for (std::size_t i = first; i < end; ++i) {
            if (!answers_[i].known) continue;
            bool exact = true;
            for (std::size_t m = 0; m < n; ++m) {
                for (const ig::TileKey& k : tiles[i][m])
                    exact = exact && pagedMap(m).placedExact(k);
            }
            if (exact) {
                answers_[i] = askTerrain(maps, batch[i].q);
            } else {
                answers_[i].known = false;
            }
        }
        for (std::set<ig::TileKey>& g : group)
            g.clear();
        first = end;
    };
    for (std::size_t i = 0; i < batch.size(); ++i) {
        bool fits = true, full = false;
        for (std::size_t m = 0; m < n; ++m) {
            fits = fits && tiles[i][m].size() <= maxTilesPerBatch_[m];
            std::size_t added = 0;
            for (const ig::TileKey& k : tiles[i][m])
                added += group[m].count(k) == 0;
            full = full || group[m].size() + added > maxTilesPerBatch_[m];
        }
        if (!fits) {
            answers_[i].known = false;
            continue;
        }
        if (full) flush(i);
        for (std::size_t m = 0; m < n; ++m)
            group[m].insert(tiles[i][m].begin(), tiles[i][m].end());
    }
    flush(batch.size());
}

}  // namespace sim
