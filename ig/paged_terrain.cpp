// The map's arrays are sparse (one address range each for heights, colours and cell maxima, as
// the whole map's): a level-0 tile is copied to where the in-memory map holds it, so the casters
// index the map exactly as they do a loaded one and read the same bits where the tiles are
// placed. Tiles share their edge samples: an exact tile writes all of its samples; a stand-in
// (upsampled from a coarser level) leaves alone the edge samples an exact neighbour holds, and
// its cell maxima are recomputed from the map after every frame's placements, so they bound
// its bilinear surface whatever its neighbours. A page is given back only when no placed tile
// touches any of its samples.
#include "ig/paged_terrain.hpp"

#include "ig/pyramid.hpp"

#include <sys/mman.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <set>

namespace ig {

namespace {

constexpr std::size_t kPage = 4096;

TerrainMap makeSparseMap(const TerrainDbInfo& info) {
    const double a = info.minRaw * info.heightScale + info.heightOffset;
    const double b = info.maxRaw * info.heightScale + info.heightOffset;
    // The header has no slope bound: the height range over one sample spacing bounds it.
    const double range =
        static_cast<double>(info.maxRaw - info.minRaw) * std::abs(info.heightScale);
    const double gx = range / info.spacingX, gy = range / info.spacingY;
    return TerrainMap::sparse(info.width, info.height, info.spacingX, info.spacingY,
                              info.heightScale, info.heightOffset, std::min(a, b), std::max(a, b),
                              std::sqrt(gx * gx + gy * gy));
}

// Gives back the pages of an array (elements of `elemBytes`, `rowLen` a row, `total` in all)
// that overlap elements [first, first + count) and hold no element `used(row, c0, c1)` claims.
template <typename Used>
void releaseRange(void* base, std::size_t elemBytes, std::size_t rowLen, std::size_t total,
                  std::size_t first, std::size_t count, Used used) {
    if (count == 0 || rowLen == 0) return;
    const std::size_t b0 = first * elemBytes / kPage * kPage;
    const std::size_t b1 = (first + count) * elemBytes;
    for (std::size_t pb = b0; pb < b1; pb += kPage) {
        const std::size_t e0 = pb / elemBytes;
        const std::size_t e1 = std::min(total, (pb + kPage + elemBytes - 1) / elemBytes);
        bool inUse = false;
        for (std::size_t row = e0 / rowLen; !inUse && row * rowLen < e1; ++row) {
            const std::size_t c0 = std::max(e0, row * rowLen) - row * rowLen;
            const std::size_t c1 = std::min(e1, (row + 1) * rowLen) - 1 - row * rowLen;
            inUse = used(static_cast<int>(row), static_cast<int>(c0), static_cast<int>(c1));
        }
        if (!inUse) releaseSparsePages(static_cast<char*>(base) + pb, kPage);
    }
}

}  // namespace

PagedTerrain::PagedTerrain(const TerrainDb& db, const Options& options)
    : db_(db), options_(options), cache_(db, options.cache), map_(makeSparseMap(db.info())) {
    Georeference g;
    g.originX = db.info().originX;
    g.originY = db.info().originY;
    g.crs = db.info().crs;
    map_.setGeoreference(std::move(g));
}

std::size_t PagedTerrain::substitutedTiles() const {
    std::size_t n = 0;
    for (const auto& [cell, p] : placed_)
        n += p.sourceLevel != 0;
    return n;
}

std::size_t PagedTerrain::placedBytes() const {
    const int t = db_.layout().tileSize();
    // Heights, colours and cell maxima: rows of at most T + 1 samples, each row spanning at
    // most two pages per array.
    return placed_.size() * static_cast<std::size_t>(t + 1) * 3 * 2 * kPage;
}

std::size_t PagedTerrain::residentMapBytes() const {
    auto resident = [](const void* data, std::size_t bytes) -> std::size_t {
        if (bytes == 0) return 0;
        const std::size_t pages = (bytes + kPage - 1) / kPage;
        std::vector<unsigned char> in(pages);
        if (mincore(const_cast<void*>(data), pages * kPage, in.data()) != 0) return 0;
        std::size_t n = 0;
        for (const unsigned char c : in)
            n += c & 1;
        return n * kPage;
    };
    return resident(map_.rawHeights().data(), map_.rawHeights().size() * sizeof(std::uint16_t)) +
           resident(map_.colors().data(), map_.colors().size() * sizeof(Rgb8)) +
           resident(map_.cellMaxData(),
                    (static_cast<std::size_t>(map_.width() - 1) * (map_.height() - 1) + 2) *
                        sizeof(std::uint16_t));
}

bool PagedTerrain::samplePlaced(int x, int y) const {
    const int t = db_.layout().tileSize();
    for (int ty = std::max(0, (y + t - 1) / t - 1); ty <= y / t; ++ty)
        for (int tx = std::max(0, (x + t - 1) / t - 1); tx <= x / t; ++tx)
            if (placed_.count({tx, ty})) return true;
    return false;
}

void PagedTerrain::copyTile(const TerrainTile& tile) {
    const std::size_t w = static_cast<std::size_t>(map_.width());
    std::uint16_t* heights = map_.rawHeights().data();
    Rgb8* colors = map_.colors().data();
    std::uint16_t* cellMax = map_.cellMaxData();
    for (int r = 0; r < tile.height; ++r) {
        const std::size_t o = static_cast<std::size_t>(tile.y0 + r) * w + tile.x0;
        const std::size_t s = static_cast<std::size_t>(r) * tile.width;
        std::memcpy(heights + o, tile.heights.data() + s, tile.width * sizeof(std::uint16_t));
        std::memcpy(colors + o, tile.colors.data() + s, tile.width * sizeof(Rgb8));
    }
    for (int r = 0; r + 1 < tile.height; ++r) {
        const std::size_t o = static_cast<std::size_t>(tile.y0 + r) * (w - 1) + tile.x0;
        const std::size_t s = static_cast<std::size_t>(r) * (tile.width - 1);
        std::memcpy(cellMax + o, tile.maxima.data() + s, (tile.width - 1) * sizeof(std::uint16_t));
    }
}

void PagedTerrain::fillFromCoarser(int tx, int ty, const TerrainTile& coarse) {
    int x0, y0, tw, th;
    db_.layout().tileExtent(TileKey{TileKind::Display, 0, tx, ty}, x0, y0, tw, th);
    const std::size_t w = static_cast<std::size_t>(map_.width());
    std::uint16_t* heights = map_.rawHeights().data();
    Rgb8* colors = map_.colors().data();
    const int k = coarse.key.level;
    const int t = db_.layout().tileSize();
    // An edge sample an exact neighbour holds stays as it is.
    auto heldByExact = [&](int x, int y) {
        for (int ny = std::max(0, (y + t - 1) / t - 1); ny <= y / t; ++ny) {
            for (int nx = std::max(0, (x + t - 1) / t - 1); nx <= x / t; ++nx) {
                if (nx == tx && ny == ty) continue;
                const auto it = placed_.find({nx, ny});
                if (it != placed_.end() && it->second.sourceLevel == 0) return true;
            }
        }
        return false;
    };
    for (int r = 0; r < th; ++r) {
        const int y = y0 + r;
        const double v = std::clamp(std::ldexp(static_cast<double>(y), -k) - coarse.y0, 0.0,
                                    static_cast<double>(coarse.height - 1));
        const int j = std::min(static_cast<int>(v), std::max(coarse.height - 2, 0));
        const double fv = v - j;
        const int j1 = std::min(j + 1, coarse.height - 1);
        for (int c = 0; c < tw; ++c) {
            const int x = x0 + c;
            const bool edge = r == 0 || c == 0 || r == th - 1 || c == tw - 1;
            if (edge && heldByExact(x, y)) continue;
            const double u = std::clamp(std::ldexp(static_cast<double>(x), -k) - coarse.x0, 0.0,
                                        static_cast<double>(coarse.width - 1));
            const int i = std::min(static_cast<int>(u), std::max(coarse.width - 2, 0));
            const double fu = u - i;
            const int i1 = std::min(i + 1, coarse.width - 1);
            const std::size_t a = static_cast<std::size_t>(j) * coarse.width;
            const std::size_t b = static_cast<std::size_t>(j1) * coarse.width;
            auto lerp2 = [&](double p00, double p10, double p01, double p11) {
                return (p00 * (1 - fu) + p10 * fu) * (1 - fv) + (p01 * (1 - fu) + p11 * fu) * fv;
            };
            const double hh = lerp2(coarse.heights[a + i], coarse.heights[a + i1],
                                    coarse.heights[b + i], coarse.heights[b + i1]);
            const Rgb8 c00 = coarse.colors[a + i], c10 = coarse.colors[a + i1];
            const Rgb8 c01 = coarse.colors[b + i], c11 = coarse.colors[b + i1];
            auto q = [](double val) {
                return static_cast<std::uint8_t>(std::clamp(std::lround(val), 0L, 255L));
            };
            const std::size_t o = static_cast<std::size_t>(y) * w + x;
            heights[o] = static_cast<std::uint16_t>(std::clamp(std::lround(hh), 0L, 65535L));
            colors[o] =
                Rgb8{q(lerp2(c00.r, c10.r, c01.r, c11.r)), q(lerp2(c00.g, c10.g, c01.g, c11.g)),
                     q(lerp2(c00.b, c10.b, c01.b, c11.b))};
        }
    }
}

void PagedTerrain::updateCellMax(int tx, int ty) {
    int x0, y0, tw, th;
    db_.layout().tileExtent(TileKey{TileKind::Display, 0, tx, ty}, x0, y0, tw, th);
    const std::size_t w = static_cast<std::size_t>(map_.width());
    const std::uint16_t* heights = map_.rawHeights().data();
    std::uint16_t* cellMax = map_.cellMaxData();
    for (int r = 0; r + 1 < th; ++r) {
        const std::size_t o = static_cast<std::size_t>(y0 + r) * w + x0;
        cellMaxRow(heights + o, heights + o + w, tw - 1,
                   cellMax + static_cast<std::size_t>(y0 + r) * (w - 1) + x0);
    }
}

void PagedTerrain::release(int tx, int ty) {
    int x0, y0, tw, th;
    db_.layout().tileExtent(TileKey{TileKind::Display, 0, tx, ty}, x0, y0, tw, th);
    const int t = db_.layout().tileSize();
    const std::size_t w = static_cast<std::size_t>(map_.width());
    const std::size_t n = w * static_cast<std::size_t>(map_.height());
    // Samples: a placed tile's extent includes its edges.
    auto samplesUsed = [&](int row, int c0, int c1) {
        for (int sy = std::max(0, (row + t - 1) / t - 1); sy <= row / t; ++sy)
            for (int sx = std::max(0, (c0 + t - 1) / t - 1); sx <= c1 / t; ++sx)
                if (placed_.count({sx, sy})) return true;
        return false;
    };
    // Cells belong to exactly one tile.
    auto cellsUsed = [&](int row, int c0, int c1) {
        for (int sx = c0 / t; sx <= c1 / t; ++sx)
            if (placed_.count({sx, row / t})) return true;
        return false;
    };
    for (int r = 0; r < th; ++r) {
        const std::size_t o = static_cast<std::size_t>(y0 + r) * w + x0;
        releaseRange(map_.rawHeights().data(), sizeof(std::uint16_t), w, n, o, tw, samplesUsed);
        releaseRange(map_.colors().data(), sizeof(Rgb8), w, n, o, tw, samplesUsed);
        if (r + 1 < th) {
            const std::size_t oc = static_cast<std::size_t>(y0 + r) * (w - 1) + x0;
            releaseRange(map_.cellMaxData(), sizeof(std::uint16_t), w - 1,
                         (w - 1) * (map_.height() - 1), oc, tw - 1, cellsUsed);
        }
    }
}

TileKey PagedTerrain::tileUnder(double x, double y) const {
    const int t = db_.layout().tileSize();
    const int cx = std::clamp(static_cast<int>(std::floor(x / map_.spacingX())), 0,
                              std::max(map_.width() - 2, 0));
    const int cy = std::clamp(static_cast<int>(std::floor(y / map_.spacingY())), 0,
                              std::max(map_.height() - 2, 0));
    return TileKey{TileKind::Display, 0, cx / t, cy / t};
}

PagedFrameStats PagedTerrain::placeAround(double x, double y) {
    return page({tileUnder(x, y)}, {}, true);
}

PagedFrameStats PagedTerrain::prepare(const Camera& camera, bool wait, const glm::dvec3& velocity,
                                      double yawRate) {
    const TerrainDbLayout& layout = db_.layout();
    const TerrainDbInfo& info = db_.info();
    // The casters reading this map march level 0 everywhere.
    const LevelSelection selection = LevelSelection::forCamera(camera.intrinsics(), info, 0);
    Footprint fp = frameFootprint(camera, layout, info, selection);
    // The ground under the eye too (the check that the eye is above it, height queries).
    fp.tiles.insert(tileUnder(camera.pose().position.x, camera.pose().position.y));
    std::set<TileKey> prefetch;
    if (velocity != glm::dvec3(0.0) || yawRate != 0.0) {
        prefetch =
            extendedFootprint(camera, layout, info, selection, velocity, yawRate,
                              options_.lookahead, options_.lookaheadStep, options_.prefetchMargin)
                .tiles;
    } else if (options_.prefetchMargin > 0.0) {
        prefetch = frameFootprint(camera, layout, info, selection, options_.prefetchMargin).tiles;
    }
    for (const TileKey& k : fp.tiles)
        prefetch.erase(k);
    return page(fp.tiles, prefetch, wait);
}

PagedFrameStats PagedTerrain::page(const std::set<TileKey>& required,
                                   const std::set<TileKey>& prefetch, bool wait) {
    PagedFrameStats st;
    st.frame = ++frame_;
    cache_.beginFrame(frame_, required, prefetch);
    if (wait) cache_.waitIdle();

    std::set<Cell> needed;
    for (const TileKey& k : required)
        if (k.kind == TileKind::Display && k.level == 0) needed.insert({k.tx, k.ty});
    st.required = needed.size();

    // Tiles no longer needed leave first (their pages go back unless a kept tile touches them).
    std::vector<Cell> gone;
    for (const auto& [cell, p] : placed_)
        if (!needed.count(cell)) gone.push_back(cell);
    for (const Cell& c : gone)
        placed_.erase(c);
    for (const Cell& c : gone)
        release(c.first, c.second);
    st.released = gone.size();

    for (const Cell& c : needed) {
        const TileKey key{TileKind::Display, 0, c.first, c.second};
        auto it = placed_.find(c);
        std::shared_ptr<const TerrainTile> tile = cache_.find(key);
        if (!tile) {
            ++st.substituted;
            const std::string failure = cache_.failure(key);
            if (!failure.empty()) {
                ++st.failed;
                if (reported_.insert(c).second) st.failures.push_back(failure);
            }
            tile = cache_.findOrCoarser(key);
            if (!tile) {
                ++st.holes;
                continue;
            }
            if (tile->key.level > 0) {
                if (it == placed_.end() || it->second.sourceLevel != tile->key.level) {
                    fillFromCoarser(c.first, c.second, *tile);
                    ++st.copied;
                }
                placed_[c] = Placed{tile->key.level, !failure.empty()};
                continue;
            }
            --st.substituted;  // loaded meanwhile
        }
        if (it == placed_.end() || it->second.sourceLevel != 0) {
            copyTile(*tile);
            ++st.copied;
        }
        placed_[c] = Placed{0, false};
    }
    // Stand-ins' cell maxima from the map as it now is (an exact neighbour may have replaced
    // a shared edge).
    for (const auto& [cell, p] : placed_)
        if (p.sourceLevel != 0) updateCellMax(cell.first, cell.second);
    return st;
}

}  // namespace ig
