// The map's arrays are sparse (one address range each for heights, colours and cell maxima, as
// the whole map's), and so are the fast caster's pyramid's (each coarser display level's, each
// node level's): a tile is copied to where the in-memory map or pyramid holds it, so the casters
// index them exactly as they do a loaded map and read the same bits where the tiles are
// placed. Nodes are stored complemented (ig/pyramid.hpp), so a node tile not placed reads "no
// bound" and a march only looks closer there; the frame's footprint holds every node its rays
// pass over, so with every tile resident the nodes read are the in-memory pyramid's. Tiles share
// their edge samples: an exact tile writes all of its samples; a stand-in (upsampled from a coarser
// level) leaves alone the edge samples an exact neighbour holds, and its cell maxima are recomputed
// from the map after every frame's placements, so they bound its bilinear surface whatever its
// neighbours. A page is given back only when no placed tile touches any of its samples.
#include "ig/paged_terrain.hpp"

#include "ig/caster.hpp"
#include "ig/pyramid.hpp"

#include <sys/mman.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <limits>
#include <set>
#include <span>

namespace ig {

namespace {

constexpr std::size_t kPage = 4096;
// Poses at most along the lookahead whose control-point rays are prefetched (a turn of 32
// degrees in half-degree steps).
constexpr int kMaxRaySweepSteps = 64;
// chooseDetail: detail 2^(-step / kDetailStepsPerOctave); a frame that wrote fewer tiles than
// kMinTilesToMeasure does not move the measured cost per tile.
constexpr int kDetailStepsPerOctave = 4;
constexpr std::size_t kMinTilesToMeasure = 16;

double detailAt(int step) {
    return std::exp2(-static_cast<double>(step) / kDetailStepsPerOctave);
}

TerrainMap makeSparseMap(const TerrainDb& db) {
    db.checkPageable();
    const TerrainDbInfo& info = db.info();
    const double a = info.minRaw * info.heightScale + info.heightOffset;
    const double b = info.maxRaw * info.heightScale + info.heightOffset;
    return TerrainMap::sparse(info.width, info.height, info.spacingX, info.spacingY,
                              info.heightScale, info.heightOffset, std::min(a, b), std::max(a, b),
                              info.maxSlope());
}

}  // namespace

PagedTerrain::PagedTerrain(const TerrainDb& db, const Options& options)
    : db_(db), options_(options), cache_(db, options.cache), map_(makeSparseMap(db)) {
    Georeference g;
    g.originX = db.info().originX;
    g.originY = db.info().originY;
    g.crs = db.info().crs;
    map_.setGeoreference(std::move(g));
    if (options_.pyramid) {
        pyramid_ =
            std::make_shared<TerrainPyramid>(map_, options_.levels, TerrainPyramid::Sparse{});
        slopes_ = std::make_shared<const SlopeBlocks>(map_, db.slopeBounds());
    }
}

PagedTerrain::Grid PagedTerrain::grid(TileKind kind, int level) const {
    Grid g;
    if (kind == TileKind::Nodes) {
        g.w = pyramid_->nodesX(level);
        g.h = pyramid_->nodesY(level);
        g.nodes = pyramid_->nodesComplement(level);
    } else if (level == 0) {
        // This object's own map, which the casters see as const: its arrays are written by
        // the placing, between frames.
        TerrainMap& m = const_cast<TerrainMap&>(map_);
        g.w = m.width();
        g.h = m.height();
        g.heights = m.rawHeights().data();
        g.colors = m.colors().data();
        g.cellMax = m.cellMaxData();
    } else {
        const PyramidLevel& l = pyramid_->level(level);
        g.w = l.width;
        g.h = l.height;
        g.heights = pyramid_->levelHeights(level);
        g.colors = pyramid_->levelColors(level);
        g.cellMax = pyramid_->levelCellMax(level);
    }
    return g;
}

std::size_t PagedTerrain::placedTiles() const {
    std::size_t n = 0;
    for (const auto& [key, p] : placed_)
        n += key.kind == TileKind::Display;
    return n;
}

std::size_t PagedTerrain::substitutedTiles() const {
    std::size_t n = 0;
    for (const auto& [key, p] : placed_)
        n += key.kind == TileKind::Display && p.sourceLevel != key.level;
    return n;
}

std::vector<TileKey> PagedTerrain::standIns() const {
    std::vector<TileKey> out;
    for (const auto& [key, p] : placed_)
        if (key.kind == TileKind::Display && p.sourceLevel != key.level) out.push_back(key);
    return out;
}

std::size_t PagedTerrain::placedBytes() const {
    return pageRefs_.size() * kPage;
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
    auto levelBytes = [&](int k) {
        const Grid g = grid(TileKind::Display, k);
        const std::size_t n = static_cast<std::size_t>(g.w) * g.h;
        return resident(g.heights, n * sizeof(std::uint16_t)) +
               resident(g.colors, n * sizeof(Rgb8)) +
               resident(g.cellMax,
                        static_cast<std::size_t>(g.w - 1) * (g.h - 1) * sizeof(std::uint16_t));
    };
    std::size_t total = levelBytes(0);
    if (pyramid_) {
        for (int k = 1; k < pyramid_->levelCount(); ++k)
            total += levelBytes(k);
        for (int j = 1; j < pyramid_->nodeLevelCount(); ++j) {
            const Grid g = grid(TileKind::Nodes, j);
            total += resident(g.nodes, static_cast<std::size_t>(g.w) * g.h * sizeof(std::uint16_t));
        }
    }
    return total;
}

bool PagedTerrain::heldByExactNeighbour(const TileKey& self, int x, int y) const {
    const int t = db_.layout().tileSize();
    for (int ty = std::max(0, (y + t - 1) / t - 1); ty <= y / t; ++ty) {
        for (int tx = std::max(0, (x + t - 1) / t - 1); tx <= x / t; ++tx) {
            const TileKey k{TileKind::Display, self.level, tx, ty};
            if (k == self) continue;
            const auto it = placed_.find(k);
            if (it != placed_.end() && it->second.sourceLevel == self.level) return true;
        }
    }
    return false;
}

void PagedTerrain::copyTile(const TerrainTile& tile) {
    const Grid g = grid(tile.key.kind, tile.key.level);
    const std::size_t w = static_cast<std::size_t>(g.w);
    if (tile.key.kind == TileKind::Nodes) {
        for (int r = 0; r < tile.height; ++r) {
            std::uint16_t* out = g.nodes + static_cast<std::size_t>(tile.y0 + r) * w + tile.x0;
            const std::uint16_t* in = tile.maxima.data() + static_cast<std::size_t>(r) * tile.width;
            for (int c = 0; c < tile.width; ++c)
                out[c] = static_cast<std::uint16_t>(~in[c]);
        }
        return;
    }
    for (int r = 0; r < tile.height; ++r) {
        const std::size_t o = static_cast<std::size_t>(tile.y0 + r) * w + tile.x0;
        const std::size_t s = static_cast<std::size_t>(r) * tile.width;
        std::memcpy(g.heights + o, tile.heights.data() + s, tile.width * sizeof(std::uint16_t));
        std::memcpy(g.colors + o, tile.colors.data() + s, tile.width * sizeof(Rgb8));
    }
    for (int r = 0; r + 1 < tile.height; ++r) {
        const std::size_t o = static_cast<std::size_t>(tile.y0 + r) * (w - 1) + tile.x0;
        const std::size_t s = static_cast<std::size_t>(r) * (tile.width - 1);
        std::memcpy(g.cellMax + o, tile.maxima.data() + s,
                    (tile.width - 1) * sizeof(std::uint16_t));
    }
}

void PagedTerrain::fillFromCoarser(const TileKey& key, const TerrainTile& coarse) {
    int x0, y0, tw, th;
    db_.layout().tileExtent(key, x0, y0, tw, th);
    const Grid g = grid(TileKind::Display, key.level);
    const std::size_t w = static_cast<std::size_t>(g.w);
    // Level-k sample x lies at coarse-level coordinate x / 2^(k' - k).
    const int shift = coarse.key.level - key.level;
    for (int r = 0; r < th; ++r) {
        const int y = y0 + r;
        const double v = std::clamp(std::ldexp(static_cast<double>(y), -shift) - coarse.y0, 0.0,
                                    static_cast<double>(coarse.height - 1));
        const int j = std::min(static_cast<int>(v), std::max(coarse.height - 2, 0));
        const double fv = v - j;
        const int j1 = std::min(j + 1, coarse.height - 1);
        for (int c = 0; c < tw; ++c) {
            const int x = x0 + c;
            // An edge sample an exact neighbour holds stays as it is.
            const bool edge = r == 0 || c == 0 || r == th - 1 || c == tw - 1;
            if (edge && heldByExactNeighbour(key, x, y)) continue;
            const double u = std::clamp(std::ldexp(static_cast<double>(x), -shift) - coarse.x0, 0.0,
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
            g.heights[o] = static_cast<std::uint16_t>(std::clamp(std::lround(hh), 0L, 65535L));
            g.colors[o] =
                Rgb8{q(lerp2(c00.r, c10.r, c01.r, c11.r)), q(lerp2(c00.g, c10.g, c01.g, c11.g)),
                     q(lerp2(c00.b, c10.b, c01.b, c11.b))};
        }
    }
}

void PagedTerrain::updateCellMax(const TileKey& key) {
    int x0, y0, tw, th;
    db_.layout().tileExtent(key, x0, y0, tw, th);
    const Grid g = grid(TileKind::Display, key.level);
    const std::size_t w = static_cast<std::size_t>(g.w);
    for (int r = 0; r + 1 < th; ++r) {
        const std::size_t o = static_cast<std::size_t>(y0 + r) * w + x0;
        cellMaxRow(g.heights + o, g.heights + o + w, tw - 1,
                   g.cellMax + static_cast<std::size_t>(y0 + r) * (w - 1) + x0);
    }
}

void PagedTerrain::tilePages(const TileKey& key, std::vector<std::uintptr_t>& out) const {
    out.clear();
    int x0, y0, tw, th;
    db_.layout().tileExtent(key, x0, y0, tw, th);
    const Grid g = grid(key.kind, key.level);
    const std::size_t w = static_cast<std::size_t>(g.w);
    auto add = [&](const void* base, std::size_t elemBytes, std::size_t first, std::size_t count) {
        const std::uintptr_t b = reinterpret_cast<std::uintptr_t>(base) + first * elemBytes;
        const std::uintptr_t e = b + count * elemBytes;
        for (std::uintptr_t page = b & ~(kPage - 1); page < e; page += kPage)
            out.push_back(page);
    };
    for (int r = 0; r < th; ++r) {
        const std::size_t o = static_cast<std::size_t>(y0 + r) * w + x0;
        if (key.kind == TileKind::Nodes) {
            add(g.nodes, sizeof(std::uint16_t), o, static_cast<std::size_t>(tw));
            continue;
        }
        add(g.heights, sizeof(std::uint16_t), o, static_cast<std::size_t>(tw));
        add(g.colors, sizeof(Rgb8), o, static_cast<std::size_t>(tw));
        if (r + 1 < th) {
            add(g.cellMax, sizeof(std::uint16_t), static_cast<std::size_t>(y0 + r) * (w - 1) + x0,
                static_cast<std::size_t>(tw - 1));
        }
    }
    std::sort(out.begin(), out.end());
    out.erase(std::unique(out.begin(), out.end()), out.end());
}

void PagedTerrain::hold(const TileKey& key) {
    tilePages(key, pages_);
    for (const std::uintptr_t page : pages_)
        if (pageRefs_[page]++ == 0) fresh_.push_back(page);
}

void PagedTerrain::place(const TileKey& key, const Placed& p) {
    placed_[key] = p;
    if (held_.insert(key).second) hold(key);
}

void PagedTerrain::release(const TileKey& key, std::vector<std::uintptr_t>& freed) {
    tilePages(key, pages_);
    for (const std::uintptr_t page : pages_) {
        const auto it = pageRefs_.find(page);
        if (it == pageRefs_.end()) continue;
        if (--it->second == 0) {
            pageRefs_.erase(it);
            freed.push_back(page);
        }
    }
}

void PagedTerrain::advisePages(std::vector<std::uintptr_t>& pages, PlacingStep step) {
    // Runs of adjacent pages, many to a call where the kernel allows, progressPages at a time
    // with a sign of life between (a frame's thousands of tiles can be a second of the
    // kernel's work where it must reclaim the page cache first).
    std::sort(pages.begin(), pages.end());
    const std::size_t batch = std::max<std::size_t>(options_.progressPages, 1);
    for (std::size_t i = 0; i < pages.size();) {
        const std::size_t end = std::min(pages.size(), i + batch);
        pageRuns(std::span<const std::uintptr_t>(pages).subspan(i, end - i), runs_);
        if (step == PlacingStep::Released) {
            releaseSparsePageRuns(runs_);
        } else {
            populateSparsePageRuns(runs_);
        }
        if (options_.progress) options_.progress(step);
        i = end;
    }
    pages.clear();
}

void PagedTerrain::givePagesBack(std::vector<std::uintptr_t>& freed) {
    advisePages(freed, PlacingStep::Released);
}

void PagedTerrain::populateFresh() {
    // Pages no tile held before read zero and are not backed (never written, or given back):
    // backed before the writes instead of a fault each.
    advisePages(fresh_, PlacingStep::Backed);
}

TileKey PagedTerrain::tileUnder(double x, double y) const {
    const int t = db_.layout().tileSize();
    const int cx = std::clamp(static_cast<int>(std::floor(x / map_.spacingX())), 0,
                              std::max(map_.width() - 2, 0));
    const int cy = std::clamp(static_cast<int>(std::floor(y / map_.spacingY())), 0,
                              std::max(map_.height() - 2, 0));
    return TileKey{TileKind::Display, 0, cx / t, cy / t};
}

double PagedTerrain::tileBound(int tx, int ty) const {
    return residentTileBound(cache_, db_, tx, ty, map_.maxHeight());
}

void PagedTerrain::addRayTiles(const glm::dvec3& eye, const glm::dvec3& dir, std::set<TileKey>& out,
                               double maxRange) const {
    const int t = db_.layout().tileSize();
    const double tileX = t * map_.spacingX(), tileY = t * map_.spacingY();
    const int tilesX = db_.layout().tilesX(TileKind::Display, 0);
    const int tilesY = db_.layout().tilesY(TileKind::Display, 0);
    const double lo = map_.minHeight(), hi = map_.maxHeight();
    // The part of the ray over the map: [s0, s1] in its parameter.
    double s0 = 0.0, s1 = maxRange;
    const double ext[2] = {map_.extentX(), map_.extentY()};
    for (int a = 0; a < 2; ++a) {
        if (dir[a] == 0.0) {
            if (eye[a] < 0.0 || eye[a] > ext[a]) return;
            continue;
        }
        double ta = (0.0 - eye[a]) / dir[a], tb = (ext[a] - eye[a]) / dir[a];
        if (ta > tb) std::swap(ta, tb);
        s0 = std::max(s0, ta);
        s1 = std::min(s1, tb);
    }
    // And within the height range: the hit lies there.
    if (dir.z != 0.0) {
        double ta = (lo - eye.z) / dir.z, tb = (hi - eye.z) / dir.z;
        if (ta > tb) std::swap(ta, tb);
        s0 = std::max(s0, ta);
        s1 = std::min(s1, tb);
    } else if (eye.z < lo || eye.z > hi) {
        return;
    }
    if (!(s0 <= s1) || !std::isfinite(s1)) return;
    // Tile by tile along the ground track (a 2D walk over the tile grid).
    const glm::dvec3 p0 = eye + s0 * dir;
    int tx = std::clamp(static_cast<int>(std::floor(p0.x / tileX)), 0, tilesX - 1);
    int ty = std::clamp(static_cast<int>(std::floor(p0.y / tileY)), 0, tilesY - 1);
    const int stepX = dir.x > 0.0 ? 1 : -1, stepY = dir.y > 0.0 ? 1 : -1;
    auto nextCross = [&](int i, int step, double size, double e, double d) {
        if (d == 0.0) return std::numeric_limits<double>::infinity();
        return ((step > 0 ? i + 1 : i) * size - e) / d;
    };
    double s = s0;
    for (int guard = 0; guard < 4 * (tilesX + tilesY) + 8 && s <= s1; ++guard) {
        const double sx = nextCross(tx, stepX, tileX, eye.x, dir.x);
        const double sy = nextCross(ty, stepY, tileY, eye.y, dir.y);
        const double sEnd = std::min({sx, sy, s1});
        const double zLow = std::min(eye.z + s * dir.z, eye.z + sEnd * dir.z);
        if (zLow <= tileBound(tx, ty)) out.insert(TileKey{TileKind::Display, 0, tx, ty});
        if (sEnd >= s1) break;
        s = sEnd;
        if (sx <= sy) {
            tx += stepX;
        } else {
            ty += stepY;
        }
        if (tx < 0 || ty < 0 || tx >= tilesX || ty >= tilesY) break;
    }
}

void PagedTerrain::addControlPointTiles(const Camera& camera, std::set<TileKey>& out) const {
    for (const glm::dvec2& px : controlPointPixels(camera.intrinsics()))
        addRayTiles(camera.pose().position, camera.rayDirection(px.x, px.y), out);
}

void PagedTerrain::warmUp(const Camera& camera, int headings) {
    // At full detail and, where frames may be drawn coarser, at the lowest detail too (its
    // coarser levels' tiles nearer: few).
    std::vector<Intrinsics> details{camera.intrinsics()};
    if (detailSteps() > 0) {
        details.push_back(camera.intrinsics());
        details.back().detail = detailAt(detailSteps());
    }
    std::set<TileKey> all;
    for (const Intrinsics& in : details) {
        const LevelSelection selection =
            LevelSelection::forCamera(in, db_.info(), pyramid_ ? options_.levels : 0);
        for (int i = 0; i < headings; ++i) {
            Pose p = camera.pose();
            p.yaw += 2.0 * M_PI * i / headings;
            const Footprint fp = frameFootprint(Camera(p, in), db_.layout(), db_.info(), selection);
            for (const TileKey& k : fp.tiles) {
                if (holds(k)) all.insert(k);
            }
        }
    }
    // As a prefetch of a frame of its own: nothing placed, so nothing is evicted for it that
    // a placed tile needs.
    cache_.beginFrame(++frame_, {}, all);
    cache_.waitIdle();
}

bool PagedTerrain::placedExact(const TileKey& key) const {
    const auto it = placed_.find(key);
    return it != placed_.end() && it->second.sourceLevel == key.level && !it->second.failed;
}

PagedFrameStats PagedTerrain::placeAround(double x, double y) {
    return page({tileUnder(x, y)}, {}, true);
}

bool PagedTerrain::holds(const TileKey& k) const {
    if (k.kind == TileKind::Nodes) return pyramid_ != nullptr;
    return k.level == 0 || (pyramid_ && k.level < pyramid_->levelCount());
}

PagedTerrain::Writes PagedTerrain::tilesToPlace(const Camera& camera) const {
    const LevelSelection selection =
        LevelSelection::forCamera(camera.intrinsics(), db_.info(), pyramid_ ? options_.levels : 0);
    Writes w;
    for (const TileKey& k : frameFootprint(camera, db_.layout(), db_.info(), selection).tiles) {
        if (!holds(k) || placedExact(k)) continue;
        ++w.tiles;
        w.missing += cache_.find(k) == nullptr;
    }
    return w;
}

int PagedTerrain::detailSteps() const {
    if (options_.placeBudgetMs <= 0.0) return 0;
    const double lowest = std::clamp(options_.minDetail, 1e-3, 1.0);
    return static_cast<int>(std::floor(-kDetailStepsPerOctave * std::log2(lowest) + 1e-9));
}

double PagedTerrain::chooseDetail(const Camera& camera) {
    const int last = detailSteps();
    if (options_.placeBudgetMs <= 0.0 || msPerTile_ <= 0.0 || last <= 0) {
        detailStep_ = 0;
        return 1.0;
    }
    Intrinsics in = camera.intrinsics();
    auto at = [&](int step) {
        in.detail = detailAt(step);
        return tilesToPlace(Camera(camera.pose(), in));
    };
    const double budget = options_.placeBudgetMs;
    // A step finer once the tiles it adds are all loaded and the frames' steady writes there
    // (the last frames' at this step, times the level-0 area's growth, 2^(1/2) a step) fit:
    // its first frame writes the ring of tiles the step adds once.
    if (detailStep_ > 0 && at(detailStep_ - 1).missing == 0 &&
        copiedPerFrame_ * std::sqrt(2.0) * msPerTile_ <= budget) {
        --detailStep_;
        return detailAt(detailStep_);
    }
    // Coarser while this frame's writes would not fit.
    for (; detailStep_ < last; ++detailStep_) {
        const double ms = static_cast<double>(at(detailStep_).tiles) * msPerTile_;
        if (ms <= budget) break;
    }
    return detailAt(detailStep_);
}

PagedFrameStats PagedTerrain::prepare(const Camera& camera, bool wait, const glm::dvec3& velocity,
                                      double yawRate, const Camera* otherEye) {
    const TerrainDbLayout& layout = db_.layout();
    const TerrainDbInfo& info = db_.info();
    // The levels the casters reading this map march: level 0 everywhere, or the fast
    // caster's (its max-height nodes whatever its levels).
    const LevelSelection selection =
        LevelSelection::forCamera(camera.intrinsics(), info, pyramid_ ? options_.levels : 0);
    // Ahead of a frame drawn at lower detail, a step finer: the tiles chooseDetail waits for
    // before it raises the detail.
    Intrinsics ahead = camera.intrinsics();
    ahead.detail = std::min(1.0, ahead.detail * detailAt(-1));
    const LevelSelection aheadSelection =
        LevelSelection::forCamera(ahead, info, pyramid_ ? options_.levels : 0);
    // And a step coarser, where the detail may go down: the coarser levels' tiles nearer (a
    // thin ring each, few tiles), for this pose.
    Intrinsics below = camera.intrinsics();
    below.detail = std::max(detailAt(detailSteps()), below.detail * detailAt(1));
    Footprint fp;
    for (const Camera* eye : {&camera, otherEye}) {
        if (!eye) continue;
        const Footprint own = frameFootprint(*eye, layout, info, selection);
        fp.tiles.insert(own.tiles.begin(), own.tiles.end());
        // The ground under the eye too (the check that the eye is above it, height queries).
        fp.tiles.insert(tileUnder(eye->pose().position.x, eye->pose().position.y));
        if (pyramid_) addControlPointTiles(*eye, fp.tiles);
    }
    std::set<TileKey> prefetch;
    if (velocity != glm::dvec3(0.0) || yawRate != 0.0) {
        prefetch =
            extendedFootprint(camera, layout, info, aheadSelection, velocity, yawRate,
                              options_.lookahead, options_.lookaheadStep, options_.prefetchMargin)
                .tiles;
    } else if (options_.prefetchMargin > 0.0) {
        prefetch =
            frameFootprint(camera, layout, info, aheadSelection, options_.prefetchMargin).tiles;
    }
    if (options_.placeBudgetMs > 0.0 && below.detail < camera.intrinsics().detail) {
        const Footprint coarser =
            frameFootprint(Camera(camera.pose(), below), layout, info,
                           LevelSelection::forCamera(below, info, pyramid_ ? options_.levels : 0));
        prefetch.insert(coarser.tiles.begin(), coarser.tiles.end());
    }
    // The control points' rays ahead too (cast on level 0 at any distance): thin, so swept
    // through the lookahead's turn in steps of at most half a degree, not only at its steps.
    if (pyramid_ && options_.lookahead > 0.0 && (velocity != glm::dvec3(0.0) || yawRate != 0.0)) {
        const double byTurn = std::abs(yawRate) * options_.lookahead / (0.5 * M_PI / 180.0);
        const double bySteps =
            options_.lookaheadStep > 0.0 ? options_.lookahead / options_.lookaheadStep : 1.0;
        const int steps = static_cast<int>(std::clamp(std::ceil(std::max(byTurn, bySteps)), 1.0,
                                                      static_cast<double>(kMaxRaySweepSteps)));
        for (int i = 1; i <= steps; ++i) {
            const double t = options_.lookahead * i / steps;
            Pose p = camera.pose();
            p.position += velocity * t;
            p.yaw += yawRate * t;
            addControlPointTiles(Camera(p, camera.intrinsics()), prefetch);
        }
    }
    // Only what this map holds: level 0, or the pyramid's levels and nodes.
    std::erase_if(fp.tiles, [&](const TileKey& k) { return !holds(k); });
    std::erase_if(prefetch, [&](const TileKey& k) { return !holds(k) || fp.tiles.count(k) > 0; });
    if (options_.progress) options_.progress(PlacingStep::Footprint);
    return page(fp.tiles, prefetch, wait);
}

PagedFrameStats PagedTerrain::page(const std::set<TileKey>& required,
                                   const std::set<TileKey>& prefetch, bool wait) {
    PagedFrameStats st;
    st.frame = ++frame_;
    cache_.beginFrame(frame_, required, prefetch);
    if (wait) cache_.waitIdle();
    if (options_.progress) options_.progress(PlacingStep::Requested);
    // From here on the cost grows with the tiles written (chooseDetail's measure).
    const auto start = std::chrono::steady_clock::now();

    // Tiles no longer needed leave first. Their pages stay (a page is counted once per tile
    // holding it) until the pages held, this frame's new ones included, pass the map's budget;
    // then the oldest leavers give theirs back, down to half of it (below, once the writes
    // are decided).
    for (auto it = placed_.begin(); it != placed_.end();) {
        if (!required.count(it->first)) {
            leaving_[it->first] = frame_;
            it = placed_.erase(it);
        } else {
            ++it;
        }
    }
    for (const TileKey& k : required)
        leaving_.erase(k);

    // The writes are decided first and made once their fresh pages are backed, in the order
    // decided (a stand-in leaves the edge samples an exact neighbour placed in this frame
    // holds; that neighbour's copy writes them, before or after).
    struct Write {
        std::shared_ptr<const TerrainTile> tile;
        TileKey key;  // a stand-in's own key (tile is then the coarser one)
    };
    std::vector<Write> writes;
    fresh_.clear();
    int sinceProgress = 0;
    for (const TileKey& key : required) {
        if (options_.progress && ++sinceProgress == kProgressTiles) {
            options_.progress(PlacingStep::Decided);
            sinceProgress = 0;
        }
        auto it = placed_.find(key);
        const bool placedExact = it != placed_.end() && it->second.sourceLevel == key.level;
        std::shared_ptr<const TerrainTile> tile = cache_.find(key);
        if (key.kind == TileKind::Nodes) {
            ++st.nodesRequired;
            if (tile && !placedExact) writes.push_back(Write{tile, key});
            if (tile || placedExact) {
                place(key, Placed{key.level, false});
            } else {
                ++st.nodesMissing;  // not placed: its nodes read "no bound"
            }
            continue;
        }
        ++st.required;
        st.requiredCoarse += key.level > 0;
        // An exact tile already in place stays, even if the cache has let it go since.
        if (placedExact) continue;
        if (!tile) {
            ++st.substituted;
            const std::string failure = cache_.failure(key);
            if (!failure.empty()) {
                ++st.failed;
                if (reported_.insert(key).second) st.failures.push_back(failure);
            }
            tile = cache_.findOrCoarser(key);
            if (!tile) {
                ++st.holes;
                continue;
            }
            if (tile->key.level > key.level) {
                if (it == placed_.end() || it->second.sourceLevel != tile->key.level) {
                    writes.push_back(Write{tile, key});
                    ++st.copied;
                }
                place(key, Placed{tile->key.level, !failure.empty()});
                continue;
            }
            --st.substituted;  // loaded meanwhile
        }
        writes.push_back(Write{tile, key});
        ++st.copied;
        place(key, Placed{key.level, false});
    }
    if (options_.progress) options_.progress(PlacingStep::Decided);
    // The budget counts the pages this frame's new tiles hold too (counted before them, a
    // fast low pass held the budget and a frame's worth of new pages besides: 1.07 GB over a
    // 512 MB budget). A page a leaver shares with a tile placed now stays held; the pages
    // freed are not fresh ones, which no tile held before.
    const std::size_t budget =
        options_.mapBudgetBytes > 0 ? options_.mapBudgetBytes : cache_.budgetBytes();
    if (pageRefs_.size() * kPage > budget && !leaving_.empty()) {
        std::vector<std::pair<std::uint64_t, TileKey>> oldest;
        for (const auto& [key, f] : leaving_)
            oldest.emplace_back(f, key);
        std::sort(oldest.begin(), oldest.end());
        std::vector<std::uintptr_t> freed;
        for (const auto& [f, key] : oldest) {
            if (pageRefs_.size() * kPage <= budget / 2) break;
            leaving_.erase(key);
            held_.erase(key);
            release(key, freed);
            ++st.released;
        }
        givePagesBack(freed);
    }
    populateFresh();
    sinceProgress = 0;
    for (const Write& w : writes) {
        if (w.tile->key == w.key) {
            copyTile(*w.tile);
        } else {
            fillFromCoarser(w.key, *w.tile);
        }
        if (options_.progress && ++sinceProgress == kProgressTiles) {
            options_.progress(PlacingStep::Written);
            sinceProgress = 0;
        }
    }
    // Stand-ins' cell maxima from the map as it now is: those written in this frame, and those
    // beside a tile written in it (an exact neighbour may have replaced a shared edge). The
    // others' samples, and so their maxima, are as the last frame left them.
    std::set<TileKey> written;
    for (const Write& w : writes)
        if (w.key.kind == TileKind::Display) written.insert(w.key);
    const auto besideWritten = [&written](const TileKey& key) {
        for (int dy = -1; dy <= 1; ++dy)
            for (int dx = -1; dx <= 1; ++dx)
                if (written.count(TileKey{key.kind, key.level, key.tx + dx, key.ty + dy}))
                    return true;
        return false;
    };
    sinceProgress = 0;
    for (const auto& [key, p] : placed_) {
        if (key.kind != TileKind::Display || p.sourceLevel == key.level || !besideWritten(key))
            continue;
        updateCellMax(key);
        if (options_.progress && ++sinceProgress == kProgressTiles) {
            options_.progress(PlacingStep::StandIns);
            sinceProgress = 0;
        }
    }
    if (options_.progress) options_.progress(PlacingStep::StandIns);
    copiedPerFrame_ = 0.75 * copiedPerFrame_ + 0.25 * static_cast<double>(st.copied);
    if (st.copied >= kMinTilesToMeasure) {
        const double ms =
            std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start)
                .count() /
            static_cast<double>(st.copied);
        msPerTile_ = msPerTile_ > 0.0 ? 0.75 * msPerTile_ + 0.25 * ms : ms;
    }
    return st;
}

}  // namespace ig
