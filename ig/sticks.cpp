// Sticks: encoding of voxel columns into the shared table, and the object layer's placement of
// models into object cells (docs/design/objects.md).
#include "ig/sticks.hpp"

#include "base/check.hpp"
#include "ig/error.hpp"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <limits>

namespace ig {

ObjectModel objectModelFromVox(const VoxFile& file, int index, const std::string& name) {
    if (index < 0 || static_cast<std::size_t>(index) >= file.models.size()) {
        throw InputError(name + ": model " + std::to_string(index) + " asked for, the file has " +
                         std::to_string(file.models.size()));
    }
    ObjectModel m;
    m.name = name;
    m.grid = file.models[static_cast<std::size_t>(index)];
    m.palette = file.palette;
    return m;
}

// ---- StickTable --------------------------------------------------------------------------------

std::uint32_t StickTable::addColumn(std::span<const Rgba8> colors,
                                    std::span<const std::uint8_t> present, float voxelHeight) {
    CHECK_EQ(colors.size(), present.size());
    CHECK_LE(colors.size(), std::size_t{4095});
    std::vector<std::uint32_t> list = {0, std::bit_cast<std::uint32_t>(voxelHeight), 0, 0};
    int lowest = -1, highest = 0;
    int types[3] = {0, 0, 0};
    const int n = static_cast<int>(colors.size());
    for (int z = 0; z < n;) {
        if (!present[static_cast<std::size_t>(z)]) {
            ++z;
            continue;
        }
        int end = z;
        bool opaque = true, same = true;
        while (end < n && present[static_cast<std::size_t>(end)]) {
            const Rgba8 c = colors[static_cast<std::size_t>(end)];
            opaque = opaque && c.a == 255;
            same = same && c == colors[static_cast<std::size_t>(z)];
            ++end;
        }
        const StickType type = !opaque ? StickType::Complex
                               : same  ? StickType::Uniform
                                       : StickType::Textured;
        list.push_back(static_cast<std::uint32_t>(type) | (static_cast<std::uint32_t>(z) << 8) |
                       (static_cast<std::uint32_t>(end - z) << 20));
        if (type == StickType::Uniform) {
            list.push_back(packRgba(colors[static_cast<std::size_t>(z)]));
        } else {
            for (int i = z; i < end; ++i)
                list.push_back(packRgba(colors[static_cast<std::size_t>(i)]));
        }
        ++types[static_cast<int>(type)];
        ++list[0];
        if (lowest < 0) lowest = z;
        highest = end;
        z = end;
    }
    if (list[0] == 0) return kNone;
    list[2] = std::bit_cast<std::uint32_t>(static_cast<float>(lowest) * voxelHeight);
    list[3] = std::bit_cast<std::uint32_t>(static_cast<float>(highest) * voxelHeight);
    std::string key;
    if (share_) {
        key.assign(reinterpret_cast<const char*>(list.data()), list.size() * sizeof(std::uint32_t));
        const auto it = index_.find(key);
        if (it != index_.end()) return it->second;
    }
    CHECK_LE(words_.size() + list.size(), std::size_t{0xfffffff0u}) << "stick table full";
    const auto offset = static_cast<std::uint32_t>(words_.size());
    words_.insert(words_.end(), list.begin(), list.end());
    if (share_) index_.emplace(std::move(key), offset);
    ++lists_;
    for (int t = 0; t < 3; ++t)
        runsByType_[t] += static_cast<std::size_t>(types[t]);
    return offset;
}

StickRun StickTable::run(std::uint32_t offset, int r) const {
    std::size_t pos = offset + kHeaderWords;
    for (int i = 0;; ++i) {
        const std::uint32_t h = words_[pos];
        StickRun run;
        run.type = static_cast<StickType>(h & 3u);
        run.first = static_cast<int>((h >> 8) & 0xfffu);
        run.count = static_cast<int>(h >> 20);
        run.values = &words_[pos + 1];
        if (i == r) return run;
        pos += 1 + (run.type == StickType::Uniform ? 1 : static_cast<std::size_t>(run.count));
    }
}

// ---- ObjectLayer -------------------------------------------------------------------------------

ObjectLayer::ObjectLayer(const TerrainMap& map, double cellSize, bool shareSticks)
    : map_(&map), table_(shareSticks) {
    CHECK(map.width() >= 2 && map.height() >= 2);
    CHECK(cellSize > 0.0 && std::isfinite(cellSize));
    k_ = static_cast<int>(std::clamp(std::lround(map.spacingX() / cellSize), 1L, 4096L));
    csx_ = map.spacingX() / k_;
    csy_ = map.spacingY() / k_;
    nx_ = static_cast<std::int64_t>(map.width() - 1) * k_;
    ny_ = static_cast<std::int64_t>(map.height() - 1) * k_;
    const std::size_t blocks = static_cast<std::size_t>(map.width() - 1) * (map.height() - 1);
    blockLo_.assign(blocks, std::numeric_limits<float>::infinity());
    blockHi_.assign(blocks, -std::numeric_limits<float>::infinity());
    minBottom_ = std::numeric_limits<float>::infinity();
    maxTop_ = -std::numeric_limits<float>::infinity();
}

std::vector<std::uint32_t>& ObjectLayer::columns(const ObjectModel& model, double scale) {
    // Without sharing, every copy encodes its own lists (what sharing saves is measured so).
    if (!table_.sharing()) columnCache_.clear();
    std::string key(sizeof(const void*) + sizeof(double), '\0');
    const void* ptr = &model;
    std::memcpy(key.data(), &ptr, sizeof ptr);
    std::memcpy(key.data() + sizeof ptr, &scale, sizeof scale);
    auto [it, fresh] = columnCache_.try_emplace(std::move(key));
    if (fresh) {
        it->second.assign(static_cast<std::size_t>(model.grid.sizeX) * model.grid.sizeY,
                          kUnencoded);
    }
    return it->second;
}

std::uint32_t ObjectLayer::column(const ObjectModel& model, double scale,
                                  std::vector<std::uint32_t>& cols, int x, int y) {
    std::uint32_t& c = cols[static_cast<std::size_t>(y) * model.grid.sizeX + x];
    if (c != kUnencoded) return c;
    const VoxModel& g = model.grid;
    std::vector<Rgba8> colors(static_cast<std::size_t>(g.sizeZ));
    std::vector<std::uint8_t> present(static_cast<std::size_t>(g.sizeZ));
    for (int z = 0; z < g.sizeZ; ++z) {
        present[static_cast<std::size_t>(z)] = model.present(x, y, z);
        colors[static_cast<std::size_t>(z)] = model.color(x, y, z);
    }
    c = table_.addColumn(colors, present, static_cast<float>(scale));
    return c;
}

void ObjectLayer::place(const ObjectModel& model, const Placement& p) {
    CHECK(std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z) &&
          std::isfinite(p.heading) && p.scale > 0.0 && std::isfinite(p.scale));
    CHECK(p.x >= 0.0 && p.y >= 0.0 && p.x <= map_->extentX() && p.y <= map_->extentY())
        << "placement at " << p.x << ", " << p.y;
    std::vector<std::uint32_t>& cols = columns(model, p.scale);
    const VoxModel& g = model.grid;
    // Model axes in the world: +y along the heading, +x to its right.
    const double s = std::sin(p.heading), c = std::cos(p.heading);
    const double halfX = 0.5 * g.sizeX, halfY = 0.5 * g.sizeY;
    const double r = p.scale * std::hypot(halfX, halfY);
    const auto lo = [](double v, double size) {
        return static_cast<std::int64_t>(std::floor(v / size - 0.5));
    };
    const std::int64_t cx0 = std::max<std::int64_t>(0, lo(p.x - r, csx_));
    const std::int64_t cy0 = std::max<std::int64_t>(0, lo(p.y - r, csy_));
    const std::int64_t cx1 = std::min<std::int64_t>(nx_ - 1, lo(p.x + r, csx_) + 1);
    const std::int64_t cy1 = std::min<std::int64_t>(ny_ - 1, lo(p.y + r, csy_) + 1);
    PlacedObject placed{p.id, model.name, p.x, p.y, p.z, p.heading, p.scale, p.z, 0};
    const std::size_t before = entries_.size();
    for (std::int64_t cy = cy0; cy <= cy1; ++cy) {
        for (std::int64_t cx = cx0; cx <= cx1; ++cx) {
            const double dx = (static_cast<double>(cx) + 0.5) * csx_ - p.x;
            const double dy = (static_cast<double>(cy) + 0.5) * csy_ - p.y;
            const double mx = (dx * c - dy * s) / p.scale + halfX;
            const double my = (dx * s + dy * c) / p.scale + halfY;
            if (!(mx >= 0.0 && my >= 0.0 && mx < g.sizeX && my < g.sizeY)) continue;
            const std::uint32_t stick =
                column(model, p.scale, cols, static_cast<int>(mx), static_cast<int>(my));
            if (stick == StickTable::kNone) continue;
            const auto baseZ = static_cast<float>(p.z);
            entries_.push_back({static_cast<std::uint64_t>(cy) * static_cast<std::uint64_t>(nx_) +
                                    static_cast<std::uint64_t>(cx),
                                ObjectCell{stick, baseZ, p.id}});
            const float bottom = baseZ + table_.bottom(stick), top = baseZ + table_.top(stick);
            const std::size_t b = blockIndex(static_cast<int>(cx / k_), static_cast<int>(cy / k_));
            blockLo_[b] = std::min(blockLo_[b], bottom);
            blockHi_[b] = std::max(blockHi_[b], top);
            minBottom_ = std::min(minBottom_, bottom);
            maxTop_ = std::max(maxTop_, top);
            placed.top = std::max(placed.top, static_cast<double>(top));
            ++placed.cells;
        }
    }
    if (entries_.size() != before) finished_ = false;
    objects_.push_back(std::move(placed));
}

void ObjectLayer::finish() {
    std::stable_sort(entries_.begin(), entries_.end(),
                     [](const Entry& a, const Entry& b) { return a.key < b.key; });
    // Merges the new entries with the cells already finished (stable: earlier placements first).
    std::vector<std::uint64_t> keys;
    std::vector<ObjectCell> cells;
    keys.reserve(keys_.size() + entries_.size());
    cells.reserve(keys.capacity());
    std::size_t i = 0, j = 0;
    while (i < keys_.size() || j < entries_.size()) {
        if (j == entries_.size() || (i < keys_.size() && keys_[i] <= entries_[j].key)) {
            keys.push_back(keys_[i]);
            cells.push_back(cells_[i++]);
        } else {
            keys.push_back(entries_[j].key);
            cells.push_back(entries_[j++].cell);
        }
    }
    keys_ = std::move(keys);
    cells_ = std::move(cells);
    entries_.clear();
    entries_.shrink_to_fit();
    finished_ = true;
    indexBoxes();
}

void ObjectLayer::indexBoxes() {
    // Each id's cell range and height range, then each box row's first entry and each box
    // cell's first entry (from a walk along the row's sorted keys).
    std::vector<std::int32_t> boxOf(65536, -1);
    boxes_.clear();
    const auto nx = static_cast<std::uint64_t>(nx_);
    for (std::size_t i = 0; i < keys_.size(); ++i) {
        const ObjectCell& c = cells_[i];
        const auto cx = static_cast<std::int64_t>(keys_[i] % nx);
        const auto cy = static_cast<std::int64_t>(keys_[i] / nx);
        const float lo = c.baseZ + table_.bottom(c.stick), hi = c.baseZ + table_.top(c.stick);
        std::int32_t& b = boxOf[c.id];
        if (b < 0) {
            b = static_cast<std::int32_t>(boxes_.size());
            boxes_.push_back(ObjectBox{cx, cy, cx, cy, lo, hi, c.id, 0, 0});
            continue;
        }
        ObjectBox& box = boxes_[static_cast<std::size_t>(b)];
        box.cx0 = std::min(box.cx0, cx);
        box.cx1 = std::max(box.cx1, cx);
        box.cy0 = std::min(box.cy0, cy);
        box.cy1 = std::max(box.cy1, cy);
        box.zLo = std::min(box.zLo, lo);
        box.zHi = std::max(box.zHi, hi);
    }
    std::sort(boxes_.begin(), boxes_.end(),
              [](const ObjectBox& a, const ObjectBox& b) { return a.id < b.id; });
    rowStarts_.clear();
    cellOffsets_.clear();
    columnRanges_.clear();
    boxLines_.clear();
    for (ObjectBox& box : boxes_) {
        box.lines = static_cast<std::uint32_t>(boxLines_.size());
        for (std::int64_t i = box.cx0; i <= box.cx1 + 1; ++i)
            boxLines_.push_back(objectGridLine(i, k_, map_->spacingX(), csx_));
        for (std::int64_t i = box.cy0; i <= box.cy1 + 1; ++i)
            boxLines_.push_back(objectGridLine(i, k_, map_->spacingY(), csy_));
        box.ranges = static_cast<std::uint32_t>(columnRanges_.size());
        const auto cellsInBox =
            static_cast<std::size_t>((box.cx1 - box.cx0 + 1) * (box.cy1 - box.cy0 + 1));
        for (std::size_t i = 0; i < cellsInBox; ++i) {
            columnRanges_.push_back(std::numeric_limits<float>::infinity());
            columnRanges_.push_back(-std::numeric_limits<float>::infinity());
        }
        box.rows = static_cast<std::uint32_t>(rowStarts_.size());
        box.cells = static_cast<std::uint32_t>(cellOffsets_.size());
        bool fits = true;
        for (std::int64_t cy = box.cy0; cy <= box.cy1; ++cy) {
            const std::uint64_t row = static_cast<std::uint64_t>(cy) * nx;
            const auto start = static_cast<std::size_t>(
                std::lower_bound(keys_.begin(), keys_.end(),
                                 row + static_cast<std::uint64_t>(box.cx0)) -
                keys_.begin());
            rowStarts_.push_back(static_cast<std::uint32_t>(start));
            std::size_t i = start;
            for (std::int64_t cx = box.cx0; cx <= box.cx1; ++cx) {
                while (i < keys_.size() && keys_[i] < row + static_cast<std::uint64_t>(cx))
                    ++i;
                fits = fits && i - start <= 0xffffu;
                cellOffsets_.push_back(static_cast<std::uint16_t>(i - start));
            }
        }
        if (!fits) {
            cellOffsets_.resize(box.cells);
            box.cells = kNoCellIndex;
        }
    }
    // Each box cell's height range over its entries of the box's id.
    std::vector<std::int32_t> boxById(65536, -1);
    for (std::size_t b = 0; b < boxes_.size(); ++b)
        boxById[boxes_[b].id] = static_cast<std::int32_t>(b);
    for (std::size_t i = 0; i < keys_.size(); ++i) {
        const ObjectCell& c = cells_[i];
        const ObjectBox& box = boxes_[static_cast<std::size_t>(boxById[c.id])];
        const auto cx = static_cast<std::int64_t>(keys_[i] % nx);
        const auto cy = static_cast<std::int64_t>(keys_[i] / nx);
        float* r =
            columnRanges_.data() + box.ranges +
            2 * static_cast<std::size_t>((cy - box.cy0) * (box.cx1 - box.cx0 + 1) + (cx - box.cx0));
        r[0] = std::min(r[0], c.baseZ + table_.bottom(c.stick));
        r[1] = std::max(r[1], c.baseZ + table_.top(c.stick));
    }
    for (ObjectBox& box : boxes_) {
        const float* r = columnRanges_.data() + box.ranges;
        const auto cells =
            static_cast<std::size_t>((box.cx1 - box.cx0 + 1) * (box.cy1 - box.cy0 + 1));
        box.filled = 0;
        for (std::size_t i = 0; i < cells; ++i)
            box.filled += r[2 * i] <= r[2 * i + 1];
    }
}

std::span<const ObjectCell> ObjectLayer::cellsAt(std::int64_t cx, std::int64_t cy) const {
    DCHECK(finished_);
    const std::uint64_t key = static_cast<std::uint64_t>(cy) * static_cast<std::uint64_t>(nx_) +
                              static_cast<std::uint64_t>(cx);
    const auto it = std::lower_bound(keys_.begin(), keys_.end(), key);
    auto end = it;
    while (end != keys_.end() && *end == key)
        ++end;
    return {cells_.data() + (it - keys_.begin()), static_cast<std::size_t>(end - it)};
}

std::size_t ObjectLayer::cellBytes() const {
    return keys_.size() * (sizeof(std::uint64_t) + sizeof(ObjectCell));
}

std::size_t ObjectLayer::boxBytes() const {
    return boxes_.size() * sizeof(ObjectBox) + rowStarts_.size() * sizeof(std::uint32_t) +
           cellOffsets_.size() * sizeof(std::uint16_t) + columnRanges_.size() * sizeof(float) +
           boxLines_.size() * sizeof(double);
}

std::size_t ObjectLayer::bytes() const {
    return table_.bytes() + cellBytes() + boxBytes() +
           (blockLo_.size() + blockHi_.size()) * sizeof(float);
}

void includeStickTops(TerrainMap& map, const ObjectLayer& layer) {
    CHECK_EQ(&layer.map(), &map);
    if (layer.empty()) return;
    const double scale = map.heightScale(), offset = map.heightOffset();
    CHECK_GT(scale, 0.0);
    for (int by = 0; by + 1 < map.height(); ++by) {
        for (int bx = 0; bx + 1 < map.width(); ++bx) {
            const float top = layer.blockTop(bx, by);
            if (!(top > -std::numeric_limits<float>::infinity())) continue;
            const double raw = std::ceil((top - offset) / scale);
            map.raiseCellMaxRaw(bx, by, static_cast<std::uint16_t>(std::clamp(raw, 0.0, 65535.0)));
        }
    }
}

}  // namespace ig
