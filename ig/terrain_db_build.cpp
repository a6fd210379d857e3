// The streaming builder. Pass 1 takes level-0 rows strip by strip and cascades: each display
// level keeps only the rows its next tile row and the next coarser row need (a coarser row j
// is reduceDisplayRow of rows 2j - 1..2j + 1, as TerrainPyramid computes it), emits a tile row
// as soon as its T + 1 sample rows are there, and hands that tile row's cell maxima (a "band")
// to the max-height nodes. The nodes are built bottom-up band by band (node j = max of its
// four children and display level j's cell); their top-down part (the max with every coarser
// display level's cell above them) needs the coarse levels, which are complete only at the
// end, so pass 1 spills the bottom-up node bands and the cell-maxima bands of levels >= 1 to an
// unlinked temporary file, and pass 2 finishes the node tiles from it: node j at n is the max
// of its bottom-up value and C_m(n >> (m - j)) over the display levels m > j.
#include "ig/terrain_db_build.hpp"

#include "base/check.hpp"
#include "ig/error.hpp"
#include "ig/pyramid.hpp"
#include "ig/slope_bound.hpp"
#include "ig/synthetic.hpp"

#include <fcntl.h>
#include <sys/resource.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <deque>
#include <fstream>
#include <limits>
#include <sstream>
#include <string_view>

namespace ig {

namespace {

// A "Key:   N kB" line of /proc/self/status, bytes; 0 where unknown.
std::size_t statusBytes(std::string_view key) {
    std::ifstream f("/proc/self/status");
    std::string line;
    while (std::getline(f, line)) {
        if (line.size() > key.size() && line.compare(0, key.size(), key) == 0 &&
            line[key.size()] == ':') {
            std::istringstream s(line.substr(key.size() + 1));
            std::size_t kb = 0;
            s >> kb;
            return kb * 1024;
        }
    }
    return 0;
}

}  // namespace

std::size_t peakResidentBytes() {
    return statusBytes("VmHWM");
}

std::size_t residentBytes() {
    return statusBytes("VmRSS");
}

namespace {

double cpuSecondsNow() {
    rusage u{};
    getrusage(RUSAGE_SELF, &u);
    return u.ru_utime.tv_sec + u.ru_stime.tv_sec + 1e-6 * (u.ru_utime.tv_usec + u.ru_stime.tv_usec);
}

class MapRowSource final : public TerrainRowSource {
  public:
    explicit MapRowSource(const TerrainMap& map) : map_(map) {}
    TerrainDbInfo info() const override {
        TerrainDbInfo i;
        i.width = map_.width();
        i.height = map_.height();
        i.spacingX = map_.spacingX();
        i.spacingY = map_.spacingY();
        i.heightScale = map_.heightScale();
        i.heightOffset = map_.heightOffset();
        i.originX = i.originY = std::numeric_limits<double>::quiet_NaN();
        return i;
    }
    void readRows(int y0, int rows, std::uint16_t* heights, Rgb8* colors) override {
        const std::size_t begin = map_.index(0, y0),
                          n = static_cast<std::size_t>(rows) * map_.width();
        std::copy_n(map_.rawHeights().data() + begin, n, heights);
        std::copy_n(map_.colors().data() + begin, n, colors);
    }

  private:
    const TerrainMap& map_;
};

class SyntheticRowSource final : public TerrainRowSource {
  public:
    SyntheticRowSource(int size, std::uint64_t seed, double spacing)
        : size_(size), seed_(seed), spacing_(spacing) {
        generateSyntheticRows(size, seed, spacing, 0, 0, nullptr, nullptr);  // checks the size
    }
    TerrainDbInfo info() const override {
        TerrainDbInfo i;
        i.width = i.height = size_;
        i.spacingX = i.spacingY = spacing_;
        i.heightScale = kSyntheticHeightScale;
        i.heightOffset = kSyntheticHeightOffset;
        i.originX = i.originY = std::numeric_limits<double>::quiet_NaN();
        return i;
    }
    void readRows(int y0, int rows, std::uint16_t* heights, Rgb8* colors) override {
        generateSyntheticRows(size_, seed_, spacing_, y0, y0 + rows, heights, colors);
    }

  private:
    int size_;
    std::uint64_t seed_;
    double spacing_;
};

struct Band {
    int rows = 0, width = 0;
    std::vector<std::uint16_t> data;  // rows x width
    std::uint16_t at(int x, int y) const {
        return data[static_cast<std::size_t>(y) * static_cast<std::size_t>(width) + x];
    }
};

// An unlinked scratch file for the bands pass 2 reads back.
class ScratchFile {
  public:
    explicit ScratchFile(const std::string& near) {
        const std::string path = near + ".scratch";
        fd_ = ::open(path.c_str(), O_RDWR | O_CREAT | O_TRUNC | O_CLOEXEC, 0600);
        if (fd_ < 0) throw InputError(path + ": cannot create: " + std::strerror(errno));
        ::unlink(path.c_str());
    }
    ~ScratchFile() { ::close(fd_); }
    std::uint64_t write(const Band& b) {
        const std::uint64_t at = end_;
        const auto* p = reinterpret_cast<const std::uint8_t*>(b.data.data());
        std::size_t n = b.data.size() * 2;
        std::uint64_t off = end_;
        while (n > 0) {
            const ssize_t w = ::pwrite(fd_, p, n, static_cast<off_t>(off));
            if (w < 0) {
                if (errno == EINTR) continue;
                throw InputError(std::string("scratch file: cannot write: ") +
                                 std::strerror(errno));
            }
            p += w;
            n -= static_cast<std::size_t>(w);
            off += static_cast<std::uint64_t>(w);
        }
        end_ = off;
        return at;
    }
    void read(std::uint64_t at, Band& b) {
        auto* p = reinterpret_cast<std::uint8_t*>(b.data.data());
        std::size_t n = b.data.size() * 2;
        while (n > 0) {
            const ssize_t r = ::pread(fd_, p, n, static_cast<off_t>(at));
            if (r <= 0) {
                if (r < 0 && errno == EINTR) continue;
                throw InputError(std::string("scratch file: cannot read back"));
            }
            p += r;
            n -= static_cast<std::size_t>(r);
            at += static_cast<std::uint64_t>(r);
        }
    }

  private:
    int fd_ = -1;
    std::uint64_t end_ = 0;
};

class Builder {
  public:
    Builder(TerrainRowSource& source, const std::string& path, const DbBuildOptions& options)
        : source_(source),
          info_(source.info()),
          options_(options),
          t_(options.tileSize),
          layout_(info_.width, info_.height, options.tileSize),
          writer_(path, layout_, options.codec),
          scratch_(writer_.temporaryPath()) {
        const int levels = layout_.displayLevels(), nodes = layout_.nodeLevels();
        disp_.resize(static_cast<std::size_t>(levels));
        for (int k = 0; k < levels; ++k) {
            disp_[k].w = layout_.levelWidth(k);
            disp_[k].h = layout_.levelHeight(k);
            disp_[k].tileRows = layout_.tilesY(TileKind::Display, k);
        }
        bq_.resize(static_cast<std::size_t>(nodes));
        bDone_.assign(static_cast<std::size_t>(nodes), 0);
        bFirst_.assign(static_cast<std::size_t>(nodes), 0);
        cq_.resize(static_cast<std::size_t>(levels));
        cDone_.assign(static_cast<std::size_t>(levels), 0);
        cOffsets_.resize(static_cast<std::size_t>(levels));
        bOffsets_.resize(static_cast<std::size_t>(nodes));
    }

    // The inset databases to embed, made once the map's lowest sample is known.
    std::function<std::vector<TerrainDbWriter::Embedded>(std::uint16_t floorRaw)> embed;
    // A database embedded in another: its box's floor at most `floorRaw`, and finish() leaves
    // it at temporaryPath().
    void embedded(std::uint16_t floorRaw) {
        floorRaw_ = floorRaw;
        writer_.keepTemporary();
    }
    const std::string& temporaryPath() const { return writer_.temporaryPath(); }

    DbBuildStats run() {
        const auto start = std::chrono::steady_clock::now();
        const double cpuStart = cpuSecondsNow();
        const int w = info_.width, h = info_.height;
        // Strips of up to 512 rows and 64 MiB: the sources read (and the synthetic generator
        // runs in parallel over) a strip at a time.
        const int strip = options_.stripRows > 0
                              ? options_.stripRows
                              : std::max(t_, std::min(512, static_cast<int>((std::size_t{1} << 26) /
                                                                            (5 * std::size_t(w)))));
        std::vector<std::uint16_t> hs(static_cast<std::size_t>(strip) * w);
        std::vector<Rgb8> cs(hs.size());
        std::uint16_t lo = 65535, hi = 0;
        for (int y0 = 0; y0 < h; y0 += strip) {
            const int rows = std::min(strip, h - y0);
            source_.readRows(y0, rows, hs.data(), cs.data());
            for (int r = 0; r < rows; ++r) {
                const std::size_t o = static_cast<std::size_t>(r) * w;
                const auto [mn, mx] = std::minmax_element(hs.begin() + o, hs.begin() + o + w);
                lo = std::min(lo, *mn);
                hi = std::max(hi, *mx);
                if (disp_[0].produced > 0) addSlopeCells(disp_[0].heights.back().data(), &hs[o]);
                disp_[0].heights.emplace_back(hs.begin() + o, hs.begin() + o + w);
                disp_[0].colors.emplace_back(cs.begin() + o, cs.begin() + o + w);
                ++disp_[0].produced;
                // After every row, so the order of the tiles in the file (and so its bytes)
                // does not depend on the strip size.
                pump();
            }
            if (options_.progress) options_.progress(0.9 * (y0 + rows) / h);
        }
        pump();
        for (const Display& d : disp_)
            CHECK(d.produced == d.h && d.nextTileRow == d.tileRows);
        for (int j = 1; j < layout_.nodeLevels(); ++j)
            CHECK(bDone_[j] == layout_.tilesY(TileKind::Nodes, j));
        disp_.clear();
        finishNodes();
        info_.minRaw = std::min(lo, floorRaw_);
        info_.maxRaw = hi;
        info_.maxDx = static_cast<std::uint16_t>(maxDx_);
        info_.maxDy = static_cast<std::uint16_t>(maxDy_);
        DbBuildStats stats;
        stats.fileBytes =
            writer_.finish(info_, embed ? embed(lo) : std::vector<TerrainDbWriter::Embedded>{});
        stats.samples = static_cast<std::uint64_t>(w) * h;
        stats.tiles = static_cast<std::uint64_t>(layout_.entryCount());
        stats.seconds =
            std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
        stats.cpuSeconds = cpuSecondsNow() - cpuStart;
        stats.peakRssBytes = peakResidentBytes();
        if (options_.progress) options_.progress(1.0);
        return stats;
    }

  private:
    struct Display {
        int w = 0, h = 0, tileRows = 0;
        std::deque<std::vector<std::uint16_t>> heights;
        std::deque<std::vector<Rgb8>> colors;
        int first = 0;     // row index of heights.front()
        int produced = 0;  // rows pushed so far
        int nextTileRow = 0;
        const std::uint16_t* h16(int y) const { return heights[y - first].data(); }
        const Rgb8* rgb(int y) const { return colors[y - first].data(); }
    };

    // The cells between level-0 sample rows `a` (row y - 1) and `b` (row y) into the slope
    // section's current block row (SlopeBlocks' per-block bounds and TerrainMap's global one,
    // from the same sample differences), written out when the row of blocks is complete.
    void addSlopeCells(const std::uint16_t* a, const std::uint16_t* b) {
        const int w = info_.width, bx = SlopeBlocks::blocksAlong(w);
        if (slopeDx_.empty()) {
            slopeDx_.assign(static_cast<std::size_t>(bx), 0);
            slopeDy_.assign(slopeDx_.size(), 0);
            slopeRow_.resize(slopeDx_.size());
        }
        for (int cx = 0; cx + 1 < w; ++cx) {
            const int h00 = a[cx], h10 = a[cx + 1], h01 = b[cx], h11 = b[cx + 1];
            const int dx = std::max(std::abs(h10 - h00), std::abs(h11 - h01));
            const int dy = std::max(std::abs(h01 - h00), std::abs(h11 - h10));
            const std::size_t k = static_cast<std::size_t>(cx / SlopeBlocks::kBlock);
            slopeDx_[k] = std::max(slopeDx_[k], dx);
            slopeDy_[k] = std::max(slopeDy_[k], dy);
        }
        const int cy = slopeCellRows_++;
        if ((cy + 1) % SlopeBlocks::kBlock != 0 && cy + 2 < info_.height) return;
        const double sx = std::abs(info_.heightScale) / info_.spacingX;
        const double sy = std::abs(info_.heightScale) / info_.spacingY;
        for (std::size_t k = 0; k < slopeRow_.size(); ++k) {
            slopeRow_[k] = SlopeBlocks::boundOf(slopeDx_[k], slopeDy_[k], sx, sy);
            maxDx_ = std::max(maxDx_, slopeDx_[k]);
            maxDy_ = std::max(maxDy_, slopeDy_[k]);
        }
        writer_.writeSlopeRow(cy / SlopeBlocks::kBlock, slopeRow_.data());
        std::fill(slopeDx_.begin(), slopeDx_.end(), 0);
        std::fill(slopeDy_.begin(), slopeDy_.end(), 0);
    }

    // Does whatever the rows and bands at hand allow, until nothing more can be done.
    void pump() {
        for (bool progress = true; progress;) {
            progress = false;
            const int levels = static_cast<int>(disp_.size());
            for (int k = 0; k < levels; ++k) {
                Display& d = disp_[k];
                while (d.nextTileRow < d.tileRows &&
                       d.produced > std::min(d.nextTileRow * t_ + t_, d.h - 1)) {
                    emitTileRow(k);
                    progress = true;
                }
                int keep = d.nextTileRow * t_;
                if (k + 1 < levels) {
                    progress |= produceCoarse(k);
                    const Display& c = disp_[k + 1];
                    if (c.produced < c.h) keep = std::min(keep, std::max(2 * c.produced - 1, 0));
                }
                while (d.first < keep && !d.heights.empty()) {
                    d.heights.pop_front();
                    d.colors.pop_front();
                    ++d.first;
                }
            }
            for (int j = 1; j < layout_.nodeLevels(); ++j) {
                while (produceNodes(j))
                    progress = true;
            }
        }
    }

    bool produceCoarse(int k) {
        const Display& f = disp_[k];
        Display& c = disp_[k + 1];
        int n = 0;
        while (c.produced + n < c.h && f.produced > std::min(2 * (c.produced + n) + 1, f.h - 1))
            ++n;
        if (n == 0) return false;
        std::vector<std::vector<std::uint16_t>> hs(static_cast<std::size_t>(n));
        std::vector<std::vector<Rgb8>> cs(static_cast<std::size_t>(n));
        tbb::parallel_for(0, n, [&](int r) {
            const int j = c.produced + r;
            const std::uint16_t* hr[3];
            const Rgb8* cr[3];
            for (int b = 0; b < 3; ++b) {
                const int y = std::clamp(2 * j + b - 1, 0, f.h - 1);
                hr[b] = f.h16(y);
                cr[b] = f.rgb(y);
            }
            hs[r].resize(static_cast<std::size_t>(c.w));
            cs[r].resize(static_cast<std::size_t>(c.w));
            reduceDisplayRow(hr, cr, f.w, c.w, hs[r].data(), cs[r].data());
        });
        for (int r = 0; r < n; ++r) {
            c.heights.push_back(std::move(hs[r]));
            c.colors.push_back(std::move(cs[r]));
        }
        c.produced += n;
        return true;
    }

    // Encodes the tiles of a row in parallel, writes them in order.
    void writeTiles(std::vector<TerrainTile>& tiles) {
        std::vector<std::vector<std::uint8_t>> stored(tiles.size());
        std::vector<std::uint32_t> raw(tiles.size());
        tbb::parallel_for(std::size_t{0}, tiles.size(), [&](std::size_t i) {
            stored[i] = encodeTile(tiles[i], options_.codec, raw[i]);
        });
        for (std::size_t i = 0; i < tiles.size(); ++i)
            writer_.append(tiles[i].key, stored[i], raw[i]);
    }

    void emitTileRow(int k) {
        Display& d = disp_[k];
        const int ty = d.nextTileRow;
        const int y0 = ty * t_, y1 = std::min(y0 + t_, d.h - 1);
        Band cells;
        cells.rows = y1 - y0;
        cells.width = d.w - 1;
        cells.data.resize(static_cast<std::size_t>(cells.rows) * cells.width);
        tbb::parallel_for(0, cells.rows, [&](int r) {
            cellMaxRow(d.h16(y0 + r), d.h16(y0 + r + 1), cells.width,
                       cells.data.data() + static_cast<std::size_t>(r) * cells.width);
        });
        const int nx = layout_.tilesX(TileKind::Display, k);
        std::vector<TerrainTile> tiles(static_cast<std::size_t>(nx));
        tbb::parallel_for(0, nx, [&](int tx) {
            TerrainTile& t = tiles[tx];
            t.key = TileKey{TileKind::Display, k, tx, ty};
            layout_.tileExtent(t.key, t.x0, t.y0, t.width, t.height);
            const std::size_t n = static_cast<std::size_t>(t.width) * t.height;
            t.heights.resize(n);
            t.colors.resize(n);
            t.maxima.resize(static_cast<std::size_t>(t.width - 1) * (t.height - 1));
            for (int y = 0; y < t.height; ++y) {
                std::copy_n(d.h16(t.y0 + y) + t.x0, t.width,
                            t.heights.begin() + static_cast<std::ptrdiff_t>(y) * t.width);
                std::copy_n(d.rgb(t.y0 + y) + t.x0, t.width,
                            t.colors.begin() + static_cast<std::ptrdiff_t>(y) * t.width);
            }
            for (int y = 0; y + 1 < t.height; ++y) {
                std::copy_n(
                    cells.data.begin() + static_cast<std::ptrdiff_t>(y) * cells.width + t.x0,
                    t.width - 1, t.maxima.begin() + static_cast<std::ptrdiff_t>(y) * (t.width - 1));
            }
        });
        writeTiles(tiles);
        ++d.nextTileRow;
        if (k == 0) {
            bq_[0].push_back(std::move(cells));
            ++bDone_[0];
        } else {
            cOffsets_[k].push_back(scratch_.write(cells));
            if (k < layout_.nodeLevels()) {
                cq_[k].push_back(std::move(cells));
                ++cDone_[k];
            }
        }
    }

    // Bottom-up node band bDone_[j] of node level j, when its inputs are there.
    bool produceNodes(int j) {
        const int ty = bDone_[j];
        if (ty >= layout_.tilesY(TileKind::Nodes, j)) return false;
        const int childBands =
            j == 1 ? layout_.tilesY(TileKind::Display, 0) : layout_.tilesY(TileKind::Nodes, j - 1);
        const int lastChild = std::min(2 * ty + 1, childBands - 1);
        if (bDone_[j - 1] <= lastChild) return false;
        const bool haveLevel = j < layout_.displayLevels();
        if (haveLevel && cDone_[j] <= ty) return false;
        const int fw = layout_.nodesX(j - 1), fh = layout_.nodesY(j - 1);
        Band out;
        out.width = layout_.nodesX(j);
        out.rows = std::min(t_, layout_.nodesY(j) - ty * t_);
        out.data.resize(static_cast<std::size_t>(out.rows) * out.width);
        const std::deque<Band>& in = bq_[j - 1];
        const int inFirst = bFirst_[j - 1];
        const Band* cBand = haveLevel ? &cq_[j].front() : nullptr;
        tbb::parallel_for(0, out.rows, [&](int r) {
            const int ny = ty * t_ + r;
            for (int nx = 0; nx < out.width; ++nx) {
                std::uint16_t m = 0;
                for (int fy = 2 * ny; fy < std::min(2 * ny + 2, fh); ++fy) {
                    const Band& b = in[static_cast<std::size_t>(fy / t_ - inFirst)];
                    for (int fx = 2 * nx; fx < std::min(2 * nx + 2, fw); ++fx)
                        m = std::max(m, b.at(fx, fy % t_));
                }
                if (cBand) m = std::max(m, cBand->at(nx, r));
                out.data[static_cast<std::size_t>(r) * out.width + nx] = m;
            }
        });
        bOffsets_[j].push_back(scratch_.write(out));
        while (bFirst_[j - 1] <= lastChild) {
            bq_[j - 1].pop_front();
            ++bFirst_[j - 1];
        }
        if (haveLevel) cq_[j].pop_front();
        if (j + 1 < layout_.nodeLevels()) bq_[j].push_back(std::move(out));
        ++bDone_[j];
        return true;
    }

    // Pass 2: the node tiles, bottom-up bands raised by the coarser display levels' cells.
    void finishNodes() {
        const int levels = layout_.displayLevels();
        std::vector<int> cached(static_cast<std::size_t>(levels), -1);
        std::vector<Band> cBands(static_cast<std::size_t>(levels));
        const int nodeLevels = layout_.nodeLevels();
        for (int j = 1; j < nodeLevels; ++j) {
            const int bands = layout_.tilesY(TileKind::Nodes, j);
            for (int ty = 0; ty < bands; ++ty) {
                Band b;
                b.width = layout_.nodesX(j);
                b.rows = std::min(t_, layout_.nodesY(j) - ty * t_);
                b.data.resize(static_cast<std::size_t>(b.rows) * b.width);
                scratch_.read(bOffsets_[j][ty], b);
                for (int m = j + 1; m < levels; ++m) {
                    const int d = m - j, bi = ty >> d;
                    Band& c = cBands[m];
                    if (cached[m] != bi) {
                        c.width = layout_.nodesX(m);
                        c.rows = std::min(t_, layout_.nodesY(m) - bi * t_);
                        c.data.resize(static_cast<std::size_t>(c.rows) * c.width);
                        scratch_.read(cOffsets_[m][bi], c);
                        cached[m] = bi;
                    }
                    tbb::parallel_for(0, b.rows, [&](int r) {
                        const int cy = ((ty * t_ + r) >> d) - bi * t_;
                        std::uint16_t* row = b.data.data() + static_cast<std::size_t>(r) * b.width;
                        for (int nx = 0; nx < b.width; ++nx)
                            row[nx] = std::max(row[nx], c.at(nx >> d, cy));
                    });
                }
                const int nx = layout_.tilesX(TileKind::Nodes, j);
                std::vector<TerrainTile> tiles(static_cast<std::size_t>(nx));
                for (int tx = 0; tx < nx; ++tx) {
                    TerrainTile& t = tiles[tx];
                    t.key = TileKey{TileKind::Nodes, j, tx, ty};
                    layout_.tileExtent(t.key, t.x0, t.y0, t.width, t.height);
                    t.maxima.resize(static_cast<std::size_t>(t.width) * t.height);
                    for (int y = 0; y < t.height; ++y) {
                        std::copy_n(
                            b.data.begin() + static_cast<std::ptrdiff_t>(y) * b.width + t.x0,
                            t.width, t.maxima.begin() + static_cast<std::ptrdiff_t>(y) * t.width);
                    }
                }
                writeTiles(tiles);
            }
            if (options_.progress) options_.progress(0.9 + 0.1 * j / nodeLevels);
        }
    }

    TerrainRowSource& source_;
    std::uint16_t floorRaw_ = 65535;
    TerrainDbInfo info_;
    DbBuildOptions options_;
    int t_;
    TerrainDbLayout layout_;
    TerrainDbWriter writer_;
    std::vector<int> slopeDx_, slopeDy_;  // the block row being gathered
    std::vector<float> slopeRow_;
    int slopeCellRows_ = 0;
    int maxDx_ = 0, maxDy_ = 0;
    ScratchFile scratch_;
    std::vector<Display> disp_;
    std::vector<std::deque<Band>> bq_;  // bottom-up node bands (level 0: level-0 cell maxima)
    std::vector<int> bDone_, bFirst_;
    std::vector<std::deque<Band>> cq_;  // cell-maxima bands of display levels >= 1
    std::vector<int> cDone_;
    std::vector<std::vector<std::uint64_t>> cOffsets_, bOffsets_;
};

// Level 0 of a database, one tile row decoded at a time.
class DbRowSource final : public TerrainRowSource {
  public:
    explicit DbRowSource(const TerrainDb& db) : db_(db) {}
    TerrainDbInfo info() const override {
        TerrainDbInfo i = db_.info();
        i.minRaw = i.maxRaw = i.maxDx = i.maxDy = 0;
        return i;
    }
    void readRows(int y0, int rows, std::uint16_t* heights, Rgb8* colors) override {
        const int w = db_.info().width, t = db_.layout().tileSize();
        const int tilesY = db_.layout().tilesY(TileKind::Display, 0);
        for (int r = 0; r < rows; ++r) {
            const int y = y0 + r;
            const int ty = std::min(y / t, tilesY - 1);
            if (ty != rowTy_) load(ty);
            const std::size_t src = static_cast<std::size_t>(y - ty * t) * w;
            std::copy_n(h_.data() + src, w, heights + static_cast<std::size_t>(r) * w);
            std::copy_n(c_.data() + src, w, colors + static_cast<std::size_t>(r) * w);
        }
    }

  private:
    void load(int ty) {
        const int w = db_.info().width, t = db_.layout().tileSize();
        const int nx = db_.layout().tilesX(TileKind::Display, 0);
        h_.assign(static_cast<std::size_t>(t + 1) * w, 0);
        c_.assign(h_.size(), Rgb8{});
        for (int tx = 0; tx < nx; ++tx) {
            const TerrainTile tile = db_.readTile(TileKey{TileKind::Display, 0, tx, ty});
            for (int v = 0; v < tile.height; ++v) {
                const std::size_t src = static_cast<std::size_t>(v) * tile.width;
                const std::size_t dst = static_cast<std::size_t>(v) * w + tile.x0;
                std::copy_n(tile.heights.data() + src, tile.width, h_.data() + dst);
                std::copy_n(tile.colors.data() + src, tile.width, c_.data() + dst);
            }
        }
        rowTy_ = ty;
    }

    const TerrainDb& db_;
    int rowTy_ = -1;
    std::vector<std::uint16_t> h_;
    std::vector<Rgb8> c_;
};

// A source with the global samples over new insets lowered.
class LoweredRowSource final : public TerrainRowSource {
  public:
    LoweredRowSource(TerrainRowSource& source, const InsetNesting& nesting)
        : source_(source), nesting_(nesting) {}
    TerrainDbInfo info() const override { return source_.info(); }
    void readRows(int y0, int rows, std::uint16_t* heights, Rgb8* colors) override {
        source_.readRows(y0, rows, heights, colors);
        nesting_.lowerRows(y0, rows, heights);
    }

  private:
    TerrainRowSource& source_;
    const InsetNesting& nesting_;
};

DbBuildStats buildNested(TerrainRowSource& source, const std::string& path,
                         const DbBuildOptions& options) {
    const TerrainDbInfo info = source.info();
    const GlobalGrid grid{info.width,    info.height,      info.spacingX,
                          info.spacingY, info.heightScale, info.heightOffset};
    const InsetNesting nesting(grid, options.insets, options.insetBlend);
    std::vector<Inset> all = options.nestedInsets;
    const int apart = kInsetSkirtCells + 1;
    for (std::size_t k = 0; k < nesting.size(); ++k) {
        const Inset& a = nesting.placement(k);
        for (const Inset& b : options.nestedInsets) {
            if (a.x0 - apart <= b.x1 && a.x1 + apart >= b.x0 && a.y0 - apart <= b.y1 &&
                a.y1 + apart >= b.y0) {
                throw InputError(a.name + ": lies within " + std::to_string(apart) +
                                 " global cells of " + b.name +
                                 ", which the database holds already (nest the two in one "
                                 "build)");
            }
        }
    }
    // Each new inset's map, from a window of the lowered global map around it.
    for (std::size_t k = 0; k < nesting.size(); ++k) {
        int x0, y0, x1, y1;
        nesting.window(k, x0, y0, x1, y1);
        const int ww = x1 - x0 + 1, wh = y1 - y0 + 1, w = info.width;
        TerrainMap window(ww, wh, info.spacingX, info.spacingY, info.heightScale,
                          info.heightOffset);
        const int chunk = std::max(
            1, std::min(wh, static_cast<int>((std::size_t{1} << 24) / (5 * std::size_t(w)))));
        std::vector<std::uint16_t> hs(static_cast<std::size_t>(chunk) * w);
        std::vector<Rgb8> cs(hs.size());
        for (int y = y0; y <= y1; y += chunk) {
            const int rows = std::min(chunk, y1 + 1 - y);
            source.readRows(y, rows, hs.data(), cs.data());
            nesting.lowerRows(y, rows, hs.data());
            for (int r = 0; r < rows; ++r) {
                const std::size_t src = static_cast<std::size_t>(r) * w + x0;
                const std::size_t dst = window.index(0, y + r - y0);
                std::copy_n(hs.data() + src, ww, window.rawHeights().data() + dst);
                std::copy_n(cs.data() + src, ww, window.colors().data() + dst);
            }
        }
        all.push_back(nesting.nest(k, window, x0, y0, 65535));
    }
    LoweredRowSource lowered(source, nesting);
    DbBuildOptions global = options;
    global.insets.clear();
    global.nestedInsets.clear();
    Builder builder(lowered, path, global);
    builder.embed = [&](std::uint16_t floorRaw) {
        std::vector<TerrainDbWriter::Embedded> out;
        for (std::size_t k = 0; k < all.size(); ++k) {
            const Inset& in = all[k];
            DbBuildOptions own;
            own.tileSize = options.tileSize;
            own.codec = options.codec;
            const auto rows = mapRowSource(in.map);
            Builder b(*rows, path + ".inset-" + std::to_string(k + 1), own);
            b.embedded(floorRaw);
            b.run();
            DbInset d;
            d.name = in.name;
            d.x0 = in.x0;
            d.y0 = in.y0;
            d.x1 = in.x1;
            d.y1 = in.y1;
            d.factor = in.factor;
            d.mapX0 = in.mapX0;
            d.mapY0 = in.mapY0;
            out.push_back({d, b.temporaryPath()});
        }
        return out;
    };
    return builder.run();
}

}  // namespace

std::unique_ptr<TerrainRowSource> dbRowSource(const TerrainDb& db) {
    return std::make_unique<DbRowSource>(db);
}

Inset insetPlacement(const TerrainDb& db, std::size_t k) {
    const DbInset& d = db.insets()[k];
    const TerrainDbInfo& g = db.info();
    Inset in;
    in.name = d.name;
    in.x0 = d.x0;
    in.y0 = d.y0;
    in.x1 = d.x1;
    in.y1 = d.y1;
    in.factor = d.factor;
    in.mapX0 = d.mapX0;
    in.mapY0 = d.mapY0;
    in.origin = {d.mapX0 * g.spacingX, d.mapY0 * g.spacingY};
    in.coverMin = {d.x0 * g.spacingX, d.y0 * g.spacingY};
    in.coverMax = {d.x1 * g.spacingX, d.y1 * g.spacingY};
    return in;
}

std::vector<Inset> readInsets(const TerrainDb& db) {
    std::vector<Inset> out;
    for (std::size_t k = 0; k < db.insets().size(); ++k) {
        Inset in = insetPlacement(db, k);
        const TerrainDb own = db.openInset(k);
        in.map = own.loadMap();
        const TerrainDbInfo& i = own.info();
        in.map.extendFloor(i.minRaw * i.heightScale + i.heightOffset);
        out.push_back(std::move(in));
    }
    return out;
}

std::unique_ptr<TerrainRowSource> mapRowSource(const TerrainMap& map) {
    return std::make_unique<MapRowSource>(map);
}

std::unique_ptr<TerrainRowSource> syntheticRowSource(int size, std::uint64_t seed, double spacing) {
    return std::make_unique<SyntheticRowSource>(size, seed, spacing);
}

DbBuildStats buildTerrainDb(TerrainRowSource& source, const std::string& path,
                            const DbBuildOptions& options) {
    const int t = options.tileSize;
    if (t < kMinDbTileSize || t > kMaxDbTileSize || (t & (t - 1)) != 0) {
        throw InputError("--tile: " + std::to_string(t) + " is not a power of two from " +
                         std::to_string(kMinDbTileSize) + " to " + std::to_string(kMaxDbTileSize));
    }
    const TerrainDbInfo info = source.info();
    if (info.width < 2 || info.height < 2) {
        throw InputError("terrain: needs at least 2 x 2 samples to build a database");
    }
    if (!options.insets.empty() || !options.nestedInsets.empty()) {
        return buildNested(source, path, options);
    }
    Builder builder(source, path, options);
    return builder.run();
}

}  // namespace ig
