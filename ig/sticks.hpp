// Voxel objects as sticks (Cohen-Or et al. sec. 2, "Synthetic objects"): a model resampled into
// the cells of an object grid, each cell a list of vertical runs held in a shared stick table.
#pragma once

#include "base/check.hpp"
#include "ig/terrain.hpp"
#include "ig/vox.hpp"

#include <algorithm>
#include <bit>
#include <cstdint>
#include <span>
#include <string>
#include <unordered_map>
#include <vector>

namespace ig {

// A voxel model ready to place: a grid of palette indices (0 = empty) and its palette, whose
// alpha is each voxel's opacity (0: a transparent cavity inside the object).
struct ObjectModel {
    std::string name;
    VoxModel grid;
    std::array<Rgba8, 256> palette{};

    bool present(int x, int y, int z) const { return grid.at(x, y, z) != 0; }
    Rgba8 color(int x, int y, int z) const { return palette[grid.at(x, y, z)]; }
};

// Model `index` of a .vox file (InputError naming `name` when it has no such model).
ObjectModel objectModelFromVox(const VoxFile& file, int index, const std::string& name);

// Where and how large one copy of a model stands. The model's grid stands on its base centre
// (x, y) with its bottom at z, its +y axis along `heading` (radians clockwise from north, as a
// pose's yaw), each voxel `scale` metres on a side.
struct Placement {
    std::uint16_t id = 0;  // 1..65535 (0 is terrain or sky in the object-id image)
    double x = 0.0, y = 0.0, z = 0.0;
    double heading = 0.0;
    double scale = 1.0;
};

// ---- The stick table ---------------------------------------------------------------------------
// One flat array of 32-bit words. A cell's stick list starts at an offset into it:
//   word 0: number of runs; word 1: voxel height in metres (float bits); words 2 and 3: the
//   bottom of the lowest run and the top of the highest above the base, metres (float bits: a
//   ray's height range tested against them before any run is decoded);
//   per run, bottom to top: a header (bits 0-1 type, bits 8-19 first voxel above the base,
//   bits 20-31 voxel count), then its values: one RGBA (uniform), one RGBA per voxel
//   (textured: all opaque; complex: any opacity, alpha 0 a cavity).
// Identical lists are stored once (when sharing is on): every cell of every copy of a model at
// one scale whose column is the same points at the same words.
enum class StickType : std::uint8_t { Uniform = 0, Textured = 1, Complex = 2 };

inline std::uint32_t packRgba(Rgba8 c) {
    return c.r | (std::uint32_t{c.g} << 8) | (std::uint32_t{c.b} << 16) |
           (std::uint32_t{c.a} << 24);
}
inline Rgba8 unpackRgba(std::uint32_t w) {
    return Rgba8{static_cast<std::uint8_t>(w), static_cast<std::uint8_t>(w >> 8),
                 static_cast<std::uint8_t>(w >> 16), static_cast<std::uint8_t>(w >> 24)};
}

struct StickRun {
    StickType type = StickType::Uniform;
    int first = 0;  // voxels from the base to the run's bottom
    int count = 0;
    const std::uint32_t* values = nullptr;  // 1 (uniform) or `count` packed RGBA
    Rgba8 voxel(int k) const { return unpackRgba(values[type == StickType::Uniform ? 0 : k]); }
};

class StickTable {
  public:
    explicit StickTable(bool share = true) : share_(share) {}
    // Encodes the voxels of one column (bottom to top; a = 0 with `present` set is a cavity,
    // `present` false is empty space that splits runs) and returns its offset; an empty column
    // is not stored (returns kNone).
    static constexpr std::uint32_t kNone = 0xffffffffu;
    std::uint32_t addColumn(std::span<const Rgba8> colors, std::span<const std::uint8_t> present,
                            float voxelHeight);

    int runCount(std::uint32_t offset) const { return static_cast<int>(words_[offset]); }
    float voxelHeight(std::uint32_t offset) const {
        return std::bit_cast<float>(words_[offset + 1]);
    }
    // Run r of the list at `offset` (runs are visited in order, so this walks from the start).
    StickRun run(std::uint32_t offset, int r) const;
    // The runs bottom to top without walking from the start each time: firstRun, then nextRun
    // runCount - 1 times.
    StickRun firstRun(std::uint32_t offset) const {
        return decodeRun(&words_[offset + kHeaderWords]);
    }
    static StickRun nextRun(const StickRun& r) {
        return decodeRun(r.values + (r.type == StickType::Uniform ? 1 : r.count));
    }
    // Height of the list's top above its base, metres (its highest run's first + count voxels).
    float top(std::uint32_t offset) const { return std::bit_cast<float>(words_[offset + 3]); }
    // Bottom of the lowest run above its base, metres.
    float bottom(std::uint32_t offset) const { return std::bit_cast<float>(words_[offset + 2]); }
    static constexpr std::uint32_t kHeaderWords = 4;

    bool sharing() const { return share_; }
    std::size_t words() const { return words_.size(); }
    std::size_t lists() const { return lists_; }
    std::size_t bytes() const { return words_.size() * sizeof(std::uint32_t); }
    // Counts of runs by type, over the lists stored.
    std::size_t runsOfType(StickType t) const { return runsByType_[static_cast<int>(t)]; }

  private:
    static StickRun decodeRun(const std::uint32_t* header) {
        const std::uint32_t h = *header;
        return StickRun{static_cast<StickType>(h & 3u), static_cast<int>((h >> 8) & 0xfffu),
                        static_cast<int>(h >> 20), header + 1};
    }
    bool share_;
    std::vector<std::uint32_t> words_;
    std::unordered_map<std::string, std::uint32_t> index_;  // list bytes -> offset
    std::size_t lists_ = 0;
    std::size_t runsByType_[3] = {0, 0, 0};
};

// ---- The object layer --------------------------------------------------------------------------
// One object cell's content: its stick list, the world height of its base and the object's id.
struct ObjectCell {
    std::uint32_t stick = StickTable::kNone;
    float baseZ = 0.0f;
    std::uint16_t id = 0;
};

// What one placed object became.
struct PlacedObject {
    std::uint16_t id = 0;
    std::string model;
    double x = 0.0, y = 0.0, z = 0.0;  // base centre
    double heading = 0.0, scale = 1.0;
    double top = 0.0;  // highest point, metres
    int cells = 0;     // object cells it covers
};

// The box of one object's cells in a layer (every cell holding an entry with its id): for
// drawing objects by their screen footprint (ig/object_pass.*).
struct ObjectBox {
    std::int64_t cx0 = 0, cy0 = 0, cx1 = -1, cy1 = -1;  // object cells, inclusive
    float zLo = 0.0f, zHi = 0.0f;                       // lowest bottom, highest top, metres
    std::uint16_t id = 0;
    std::uint32_t rows = 0;    // first of its cy1 - cy0 + 1 row starts (ObjectLayer::boxCellsAt)
    std::uint32_t cells = 0;   // first of its cells' offsets from their row's start, row by row
    std::uint32_t ranges = 0;  // first of its cells' height ranges (ObjectLayer::boxColumnRanges)
    std::uint32_t lines = 0;   // first of its grid lines (ObjectLayer::boxLinesX)
    std::uint32_t filled = 0;  // its cells holding an entry of its id
};

// Objects over one terrain map, on an object grid that divides each terrain cell into k x k
// object cells (k = spacing / requested cell size, rounded, at least 1), origin at the map's
// south-west sample. Cells are kept sparse (sorted by cell, several objects may share one);
// each terrain cell keeps the lowest bottom and highest top of the sticks in it (dense), so a
// ray skips the terrain cells it passes above or below.
class ObjectLayer {
  public:
    // shareSticks false: every copy stores its own stick lists (for measurement).
    ObjectLayer(const TerrainMap& map, double cellSize, bool shareSticks = true);

    // Resamples `model` into the cells whose centres its rotated footprint covers (the voxel
    // column nearest each centre), once. The model's columns at one scale are encoded once
    // however many copies are placed. Copies must lie on the map (CHECKed; the scene loader
    // refuses others as bad input).
    void place(const ObjectModel& model, const Placement& p);
    // Sorts the cells; call once after the last place() and before any query (CHECKed).
    void finish();

    int subdivision() const { return k_; }
    double cellSizeX() const { return csx_; }
    double cellSizeY() const { return csy_; }
    std::int64_t cellsX() const { return nx_; }
    std::int64_t cellsY() const { return ny_; }
    const TerrainMap& map() const { return *map_; }

    // The entries of object cell (cx, cy), in placement order.
    std::span<const ObjectCell> cellsAt(std::int64_t cx, std::int64_t cy) const;
    // Lowest bottom and highest top (metres) of the sticks in terrain cell (bx, by);
    // bottom > top when it holds none.
    float blockBottom(int bx, int by) const { return blockLo_[blockIndex(bx, by)]; }
    float blockTop(int bx, int by) const { return blockHi_[blockIndex(bx, by)]; }
    float minBottom() const { return minBottom_; }
    float maxTop() const { return maxTop_; }
    bool empty() const { return keys_.empty() && entries_.empty(); }

    // One box per object id present (by increasing id), kept by finish().
    const std::vector<ObjectBox>& boxes() const { return boxes_; }
    // The entries of object cell (cx, cy), which must lie in `box` (DCHECKed), found from the
    // box's own index instead of a search of every cell: entries of any id.
    std::span<const ObjectCell> boxCellsAt(const ObjectBox& box, std::int64_t cx,
                                           std::int64_t cy) const {
        DCHECK(cx >= box.cx0 && cx <= box.cx1 && cy >= box.cy0 && cy <= box.cy1);
        const auto r = static_cast<std::size_t>(cy - box.cy0);
        const std::uint64_t key = static_cast<std::uint64_t>(cy) * static_cast<std::uint64_t>(nx_) +
                                  static_cast<std::uint64_t>(cx);
        std::size_t first = rowStarts_[box.rows + r];
        if (box.cells != kNoCellIndex) {
            first += cellOffsets_[box.cells + r * static_cast<std::size_t>(box.cx1 - box.cx0 + 1) +
                                  static_cast<std::size_t>(cx - box.cx0)];
        } else {
            first = static_cast<std::size_t>(
                std::lower_bound(keys_.begin() + static_cast<std::ptrdiff_t>(first), keys_.end(),
                                 key) -
                keys_.begin());
        }
        std::size_t end = first;
        while (end < keys_.size() && keys_[end] == key)
            ++end;
        return {cells_.data() + first, end - first};
    }

    // The height range of each cell of `box` (row by row over its rectangle, cx fastest): the
    // lowest baseZ + bottom and highest baseZ + top (float, as the walk's per-entry test computes
    // them) of the cell's entries with the box's id; +inf, -inf where it holds none. A ray whose
    // height range over a cell misses the cell's range meets none of its entries' sticks.
    const float* boxColumnRanges(const ObjectBox& box) const {
        return columnRanges_.data() + box.ranges;
    }

    // The x coordinates (metres) of the grid lines of `box`'s columns cx0 .. cx1 + 1 (line i is
    // the west edge of object cell cx0 + i), and the y coordinates of its rows' lines
    // cy0 .. cy1 + 1, each as traceObjects' walk places it (objectGridLine): the walk through the
    // box reads a line instead of working it out from the terrain cell and the cell within it.
    const double* boxLinesX(const ObjectBox& box) const { return boxLines_.data() + box.lines; }
    const double* boxLinesY(const ObjectBox& box) const {
        return boxLinesX(box) + (box.cx1 - box.cx0 + 2);
    }

    const StickTable& table() const { return table_; }
    const std::vector<PlacedObject>& objects() const { return objects_; }
    std::size_t cellEntries() const { return keys_.size(); }
    // Bytes of the table, the cell entries, the boxes and the per-terrain-cell ranges.
    std::size_t bytes() const;
    std::size_t cellBytes() const;
    std::size_t boxBytes() const;  // the boxes and their row index

  private:
    struct Entry {
        std::uint64_t key;  // cy * nx + cx
        ObjectCell cell;
    };
    std::size_t blockIndex(int bx, int by) const {
        return static_cast<std::size_t>(by) * static_cast<std::size_t>(map_->width() - 1) + bx;
    }
    // Encoded columns of a model at a scale: offsets per (x, y) column, each encoded when a
    // placement first uses it (kUnencoded before).
    static constexpr std::uint32_t kUnencoded = 0xfffffffeu;
    std::vector<std::uint32_t>& columns(const ObjectModel& model, double scale);
    void indexBoxes();
    std::uint32_t column(const ObjectModel& model, double scale, std::vector<std::uint32_t>& cols,
                         int x, int y);

    const TerrainMap* map_;
    int k_ = 1;
    double csx_ = 1.0, csy_ = 1.0;
    std::int64_t nx_ = 0, ny_ = 0;
    StickTable table_;
    std::vector<Entry> entries_;       // placed since the last finish()
    std::vector<std::uint64_t> keys_;  // sorted cell keys (cy * nx + cx), and their cells
    std::vector<ObjectCell> cells_;
    std::vector<float> blockLo_, blockHi_;
    float minBottom_ = 0.0f, maxTop_ = 0.0f;
    std::vector<PlacedObject> objects_;
    std::vector<ObjectBox> boxes_;
    std::vector<std::uint32_t> rowStarts_;  // per box row: first entry at or after its cx0
    // Per box cell: its first entry - its row's start (a box whose rows hold more entries than
    // 16 bits count has none, kNoCellIndex, and searches its rows).
    std::vector<std::uint16_t> cellOffsets_;
    std::vector<float> columnRanges_;  // per box cell: lo, hi (boxColumnRanges)
    std::vector<double> boxLines_;     // per box: its x lines, then its y lines (boxLinesX)
    static constexpr std::uint32_t kNoCellIndex = 0xffffffffu;
    std::unordered_map<std::string, std::vector<std::uint32_t>> columnCache_;
    bool finished_ = true;
};

// Raises the map's cell maxima (and its highest height) to cover every stick top of `layer`, so
// that the max-height pyramid built afterwards bounds the objects too (a march never skips an
// object). Only for a map that carries objects: a map without is left bit for bit as it was.
void includeStickTops(TerrainMap& map, const ObjectLayer& layer);

// Grid line i of the object grid along one axis (metres from the map's origin), as the exact
// walk places it: the terrain cell's edge (i / k) * spacing plus (i mod k) object cells of
// `cell` metres. Defined with the walk (ig/object_trace.cpp, built without fused multiply-adds)
// so that every user computes the same double.
double objectGridLine(std::int64_t i, std::int64_t k, double spacing, double cell);

}  // namespace ig
