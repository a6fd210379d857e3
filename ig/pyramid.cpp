// Display levels: each sample is the [1 2 1] x [1 2 1] / 16 weighted mean of the finer level's
// 3x3 neighbourhood around the same point (indices clamped at the edges), so level-k samples
// stay on level-0 grid lines (Cohen-Or sec. 2: "samples stay on grid lines"). Max nodes: see the
// header; built bottom-up from the cells below and top-down from the coarser display levels.
#include "ig/pyramid.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>

namespace ig {
namespace {

inline int ceilHalf(int n) {
    return (n + 1) / 2;
}

void fillCellMax(PyramidLevel& level, LargeVector<std::uint16_t>& cellMax) {
    const int cw = level.width - 1, ch = level.height - 1;
    cellMax.resize(static_cast<std::size_t>(cw) * ch);
    tbb::parallel_for(tbb::blocked_range<int>(0, ch), [&](const tbb::blocked_range<int>& rows) {
        for (int cy = rows.begin(); cy < rows.end(); ++cy) {
            const std::uint16_t* a = level.heights + level.index(0, cy);
            const std::uint16_t* b = level.heights + level.index(0, cy + 1);
            cellMaxRow(a, b, cw, cellMax.data() + static_cast<std::size_t>(cy) * cw);
        }
    });
    adviseHugePages(cellMax.data(), cellMax.size() * sizeof(std::uint16_t));
    level.cellMax = cellMax.data();
}

}  // namespace

void TerrainPyramid::shape(int maxLevels, bool sparse) {
    PyramidLevel base;
    base.width = map_.width();
    base.height = map_.height();
    base.heights = map_.rawHeights().data();
    base.colors = map_.colors().data();
    base.cellMax = map_.cellMaxData();
    levels_.push_back(base);
    store_.emplace_back();
    if (map_.width() < 2 || map_.height() < 2) return;
    auto array16 = [&](std::size_t n) {
        return LargeVector<std::uint16_t>(n, LargeAllocator<std::uint16_t>(sparse));
    };
    // Display levels.
    while (maxLevels < 0 || levelCount() <= maxLevels) {
        const PyramidLevel& fine = levels_.back();
        const int cw = ceilHalf(fine.width - 1), ch = ceilHalf(fine.height - 1);
        if (cw < 2 || ch < 2) break;
        PyramidLevel coarse;
        coarse.width = cw + 1;
        coarse.height = ch + 1;
        coarse.shift = fine.shift + 1;
        LevelStore s;
        const std::size_t n = static_cast<std::size_t>(coarse.width) * coarse.height;
        s.heights = array16(n);
        s.colors = LargeVector<Rgb8>(n, LargeAllocator<Rgb8>(sparse));
        s.cellMax = array16(static_cast<std::size_t>(cw) * ch);
        coarse.heights = s.heights.data();
        coarse.colors = s.colors.data();
        coarse.cellMax = s.cellMax.data();
        store_.push_back(std::move(s));
        levels_.push_back(coarse);
    }
    // Node levels.
    nodes_.emplace_back();
    nodeW_.push_back(map_.width() - 1);
    nodeH_.push_back(map_.height() - 1);
    while (nodeW_.back() > 1 || nodeH_.back() > 1 || nodes_.size() < 2) {
        const int nw = ceilHalf(nodeW_.back()), nh = ceilHalf(nodeH_.back());
        nodes_.push_back(array16(static_cast<std::size_t>(nw) * nh));
        nodeW_.push_back(nw);
        nodeH_.push_back(nh);
    }
}

TerrainPyramid::TerrainPyramid(const TerrainMap& map, int maxLevels, Sparse) : map_(map) {
    shape(maxLevels, true);
}

TerrainPyramid::TerrainPyramid(const TerrainMap& map, int maxLevels) : map_(map) {
    shape(maxLevels, false);
    if (map.width() < 2 || map.height() < 2) return;

    // Display levels.
    for (int k = 1; k < levelCount(); ++k) {
        const PyramidLevel& fine = levels_[k - 1];
        PyramidLevel& coarse = levels_[k];
        LevelStore& s = store_[k];
        tbb::parallel_for(
            tbb::blocked_range<int>(0, coarse.height), [&](const tbb::blocked_range<int>& rows) {
                for (int j = rows.begin(); j < rows.end(); ++j) {
                    const std::uint16_t* hr[3];
                    const Rgb8* cr[3];
                    for (int b = 0; b < 3; ++b) {
                        const std::size_t row =
                            fine.index(0, std::clamp(2 * j + b - 1, 0, fine.height - 1));
                        hr[b] = fine.heights + row;
                        cr[b] = fine.colors + row;
                    }
                    const std::size_t o = coarse.index(0, j);
                    reduceDisplayRow(hr, cr, fine.width, coarse.width, s.heights.data() + o,
                                     s.colors.data() + o);
                }
            });
        adviseHugePages(s.heights.data(), s.heights.size() * sizeof(std::uint16_t));
        adviseHugePages(s.colors.data(), s.colors.size() * sizeof(Rgb8));
        fillCellMax(coarse, s.cellMax);
    }

    // Max nodes, bottom-up: the cells below and the display level of the same size.
    for (int j = 1; j < nodeLevelCount(); ++j) {
        const int nw = nodeW_[j], nh = nodeH_[j];
        const int fw = nodeW_[j - 1], fh = nodeH_[j - 1];
        LargeVector<std::uint16_t>& node = nodes_[j];
        auto finer = [&](int fx, int fy) -> std::uint16_t {
            return j == 1 ? map.cellMaxRaw(fx, fy)
                          : nodes_[j - 1][static_cast<std::size_t>(fy) * fw + fx];
        };
        const bool haveLevel = j < levelCount();
        tbb::parallel_for(tbb::blocked_range<int>(0, nh), [&](const tbb::blocked_range<int>& rows) {
            for (int ny = rows.begin(); ny < rows.end(); ++ny) {
                for (int nx = 0; nx < nw; ++nx) {
                    std::uint16_t m = 0;
                    for (int fy = 2 * ny; fy < std::min(2 * ny + 2, fh); ++fy) {
                        for (int fx = 2 * nx; fx < std::min(2 * nx + 2, fw); ++fx) {
                            m = std::max(m, finer(fx, fy));
                        }
                    }
                    if (haveLevel) m = std::max(m, levels_[j].cellMaxRaw(nx, ny));
                    node[static_cast<std::size_t>(ny) * nw + nx] = m;
                }
            }
        });
    }

    // Top-down: a node also lies inside one cell of every coarser display level.
    std::vector<std::uint16_t> up, upFiner;  // bound from display levels coarser than j
    for (int j = nodeLevelCount() - 1; j >= 1; --j) {
        const int nw = nodeW_[j], nh = nodeH_[j];
        upFiner.assign(static_cast<std::size_t>(nw) * nh, 0);
        if (j + 1 < nodeLevelCount()) {
            const bool haveLevel = j + 1 < levelCount();
            const int pw = nodeW_[j + 1];
            for (int ny = 0; ny < nh; ++ny) {
                for (int nx = 0; nx < nw; ++nx) {
                    const int px = nx >> 1, py = ny >> 1;
                    std::uint16_t m = up[static_cast<std::size_t>(py) * pw + px];
                    if (haveLevel) m = std::max(m, levels_[j + 1].cellMaxRaw(px, py));
                    upFiner[static_cast<std::size_t>(ny) * nw + nx] = m;
                }
            }
        }
        LargeVector<std::uint16_t>& node = nodes_[j];
        for (std::size_t i = 0; i < node.size(); ++i)
            node[i] = std::max(node[i], upFiner[i]);
        up.swap(upFiner);
    }
    // Stored complemented (nodeMaxRaw).
    for (std::size_t j = 1; j < nodes_.size(); ++j)
        for (std::uint16_t& v : nodes_[j])
            v = static_cast<std::uint16_t>(~v);
}

std::size_t TerrainPyramid::bytes() const {
    std::size_t total = 0;
    for (const LevelStore& s : store_) {
        total += s.heights.size() * sizeof(std::uint16_t) + s.colors.size() * sizeof(Rgb8) +
                 s.cellMax.size() * sizeof(std::uint16_t);
    }
    for (const auto& n : nodes_)
        total += n.size() * sizeof(std::uint16_t);
    return total;
}

}  // namespace ig
