#include "sim/terrain_queries.hpp"

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

PagedTerrainQueries::PagedTerrainQueries(const ig::TerrainDb& db, const Options& options)
    : options_(options), paged_(db, [&] {
          ig::PagedTerrain::Options o;
          o.cache.budgetBytes = options.budgetBytes;
          o.cache.loaderThreads = std::max(options.loaderThreads, 1);
          return o;
      }()) {
    // A level-0 display tile: its samples (shared edges included), colours and cell maxima.
    const std::size_t side = static_cast<std::size_t>(db.layout().tileSize()) + 1;
    const std::size_t tileBytes = side * side * (2 + sizeof(ig::Rgb8) + 2);
    // Half the budget for one placement: the other half keeps the coarse levels and nodes.
    maxTilesPerBatch_ = std::max<std::size_t>(1, options.budgetBytes / 2 / tileBytes);
    const std::size_t n = std::max<std::size_t>(options.maxOutstanding, 1);
    options_.maxOutstanding = n;
    asked_.reserve(n);
    done_.reserve(n);
    work_.reserve(n);
    answers_.reserve(n);
    thread_ = std::thread([this] { loop(); });
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
    paged_.cache().setWithheld(std::move(withheld));
}

void PagedTerrainQueries::loop() {
    std::unique_lock<std::mutex> lock(mutex_);
    while (true) {
        wake_.wait(lock, [&] { return stop_ || !asked_.empty(); });
        if (stop_) return;
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
    const ig::TerrainMap& map = paged_.map();
    // The tiles each question reads.
    std::vector<std::set<ig::TileKey>> tiles(batch.size());
    for (std::size_t i = 0; i < batch.size(); ++i) {
        const TerrainQuestion& q = batch[i].q;
        answers_[i].ticket = q.ticket;
        if (!q.line) {
            tiles[i].insert(paged_.tileUnder(q.origin.x, q.origin.y));
        } else {
            const ig::TerrainRay ray(map, q.origin, q.dir);  // its unit direction
            paged_.addRayTiles(q.origin, ray.dir, tiles[i], q.maxRange);
        }
    }
    // Groups of questions whose tiles fit one placement, in order; one that needs more than
    // a placement may hold is not known.
    std::set<ig::TileKey> group;
    std::size_t first = 0;
    const auto flush = [&](std::size_t end) {
        if (first < end) {
            const ig::PagedFrameStats st = paged_.placeTiles(group);
            std::lock_guard<std::mutex> lock(mutex_);
            ++stats_.batches;
            stats_.tilesRead += st.copied;
        }
        for (std::size_t i = first; i < end; ++i) {
            if (!answers_[i].known) continue;
            bool exact = true;
            for (const ig::TileKey& k : tiles[i])
                exact = exact && paged_.placedExact(k);
            if (exact) {
                answers_[i] = askTerrain(map, batch[i].q);
            } else {
                answers_[i].known = false;
            }
        }
        group.clear();
        first = end;
    };
    for (std::size_t i = 0; i < batch.size(); ++i) {
        if (tiles[i].size() > maxTilesPerBatch_) {
            answers_[i].known = false;
            continue;
        }
        std::size_t added = 0;
        for (const ig::TileKey& k : tiles[i])
            added += group.count(k) == 0;
        if (group.size() + added > maxTilesPerBatch_) flush(i);
        group.insert(tiles[i].begin(), tiles[i].end());
    }
    flush(batch.size());
}

}  // namespace sim
