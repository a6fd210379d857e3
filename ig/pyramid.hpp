// Multiresolution terrain: a display pyramid (mean height and colour per level, each half the
// previous) and a conservative max-height pyramid that bounds every display level, for skipping
// empty space.
#pragma once

#include "ig/terrain.hpp"

#include <algorithm>
#include <cstdint>
#include <vector>

namespace ig {

// One row of a coarser display level: sample i of the row is the [1 2 1] x [1 2 1] / 16 mean of
// the finer level around sample 2i of its rows `rows[0..2]` (the rows 2j - 1, 2j, 2j + 1,
// clamped at the edges), columns clamped likewise. Shared by the pyramid and the database
// builder, which streams the same levels row by row.
inline void reduceDisplayRow(const std::uint16_t* const heightRows[3],
                             const Rgb8* const colorRows[3], int fineWidth, int coarseWidth,
                             std::uint16_t* heights, Rgb8* colors) {
    for (int i = 0; i < coarseWidth; ++i) {
        unsigned acc = 0, r = 0, g = 0, bl = 0;
        for (int b = 0; b < 3; ++b) {
            const unsigned wb = b == 1 ? 2 : 1;
            for (int a = 0; a < 3; ++a) {
                const unsigned wgt = wb * (a == 1 ? 2 : 1);
                const int x = std::clamp(2 * i + a - 1, 0, fineWidth - 1);
                acc += wgt * heightRows[b][x];
                const Rgb8 c = colorRows[b][x];
                r += wgt * c.r;
                g += wgt * c.g;
                bl += wgt * c.b;
            }
        }
        heights[i] = static_cast<std::uint16_t>((acc + 8) / 16);
        colors[i] =
            Rgb8{static_cast<std::uint8_t>((r + 8) / 16), static_cast<std::uint8_t>((g + 8) / 16),
                 static_cast<std::uint8_t>((bl + 8) / 16)};
    }
}

// One row of cell maxima: cell cx of the row between sample rows `a` and `b` is the largest of
// its four samples.
inline void cellMaxRow(const std::uint16_t* a, const std::uint16_t* b, int cells,
                       std::uint16_t* out) {
    for (int cx = 0; cx < cells; ++cx) {
        out[cx] = std::max(std::max(a[cx], a[cx + 1]), std::max(b[cx], b[cx + 1]));
    }
}

// One display level, viewed flat. Level k sample (i, j) sits on level-0 sample (i << k, j << k);
// heights are raw units of the map (same scale and offset at every level).
struct PyramidLevel {
    int width = 0, height = 0;  // samples
    int shift = 0;              // k: level-0 samples per sample = 1 << k
    const std::uint16_t* heights = nullptr;
    const Rgb8* colors = nullptr;
    const std::uint16_t* cellMax = nullptr;  // four-sample maxima, (width - 1) per row

    std::size_t index(int ix, int iy) const {
        return static_cast<std::size_t>(iy) * static_cast<std::size_t>(width) + ix;
    }
    std::uint16_t raw(int ix, int iy) const { return heights[index(ix, iy)]; }
    std::uint16_t cellMaxRaw(int cx, int cy) const {
        return cellMax[static_cast<std::size_t>(cy) * static_cast<std::size_t>(width - 1) + cx];
    }
};

class TerrainPyramid {
  public:
    // Builds coarser levels until a level has fewer than 2 cells along either axis, at most
    // `maxLevels` of them (-1: no limit). Level 0 is a view of `map`, which must outlive this.
    explicit TerrainPyramid(const TerrainMap& map, int maxLevels = -1);
    // The same levels and nodes, as sparse blocks never written (ig/terrain.hpp) for whoever
    // fills them from elsewhere (a terrain database's tiles, PagedTerrain): display samples
    // read zero and nodes read 65535 (no bound) until written.
    struct Sparse {};
    TerrainPyramid(const TerrainMap& map, int maxLevels, Sparse);
    TerrainPyramid(const TerrainPyramid&) = delete;
    TerrainPyramid& operator=(const TerrainPyramid&) = delete;

    const TerrainMap& map() const { return map_; }
    // Display levels, level 0 (the map itself) included.
    int levelCount() const { return static_cast<int>(levels_.size()); }
    const PyramidLevel& level(int k) const { return levels_[k]; }

    // Max-height nodes: node (nx, ny) of node level j (1 <= j < nodeLevelCount()) covers level-0
    // cells [nx << j, (nx + 1) << j) x [ny << j, (ny + 1) << j) (clipped to the map) and bounds,
    // in raw units, the bilinear surface of EVERY display level over that region — and hence
    // any blend of them.
    int nodeLevelCount() const { return static_cast<int>(nodes_.size()); }
    int nodesX(int j) const { return nodeW_[j]; }
    int nodesY(int j) const { return nodeH_[j]; }
    // Nodes are stored complemented (~max), so that a node of a sparse pyramid never written
    // reads 65535: no bound, which only makes a march look closer.
    std::uint16_t nodeMaxRaw(int j, int nx, int ny) const {
        return static_cast<std::uint16_t>(
            ~nodes_[j][static_cast<std::size_t>(ny) * static_cast<std::size_t>(nodeW_[j]) + nx]);
    }

    // A sparse pyramid's arrays, to fill: display level k >= 1 (heights, colours, cell maxima,
    // rows of width(k), width(k) - 1 and so on as PyramidLevel), and node level j >= 1 (rows
    // of nodesX(j), each node stored as ~max).
    std::uint16_t* levelHeights(int k) { return store_[k].heights.data(); }
    Rgb8* levelColors(int k) { return store_[k].colors.data(); }
    std::uint16_t* levelCellMax(int k) { return store_[k].cellMax.data(); }
    std::uint16_t* nodesComplement(int j) { return nodes_[j].data(); }

    // Bytes held by the coarser levels and the nodes (level 0 belongs to the map).
    std::size_t bytes() const;

  private:
    // The levels' and nodes' sizes, their arrays allocated (sparse blocks or not).
    void shape(int maxLevels, bool sparse);

    struct LevelStore {
        LargeVector<std::uint16_t> heights;
        LargeVector<Rgb8> colors;
        LargeVector<std::uint16_t> cellMax;
    };

    const TerrainMap& map_;
    std::vector<PyramidLevel> levels_;
    std::vector<LevelStore> store_;                  // store_[k] backs levels_[k], k >= 1
    std::vector<LargeVector<std::uint16_t>> nodes_;  // nodes_[0] unused
    std::vector<int> nodeW_, nodeH_;
};

}  // namespace ig
