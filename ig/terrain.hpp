// Terrain map: a heightfield of integer heights with scale/offset and an RGB8 colour per sample.
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <span>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

namespace ig {

// Allocator for the maps' large arrays: a block of 4 MiB or more is aligned to 2 MiB and
// advised for transparent huge pages before anything touches it, so its pages fault in 2 MiB
// at a time (a march over a large map from DRAM with 4 KiB pages misses the TLB nearly every
// step). Smaller blocks come from operator new. See adviseHugePages.
void* allocateLarge(std::size_t bytes);
void deallocateLarge(void* p, std::size_t bytes) noexcept;
// Sparse blocks: address space reserved without backing (mmap, MAP_NORESERVE, 4 KiB pages),
// reading zero until written; only the pages written count as memory (releaseSparsePageRuns
// gives pages back: they read zero again).
void* allocateSparse(std::size_t bytes);
void deallocateSparse(void* p, std::size_t bytes) noexcept;

// Runs of whole pages of sparse blocks: [begin, begin + pages * 4 KiB), begin page-aligned.
struct PageRun {
    std::uintptr_t begin = 0;
    std::size_t pages = 0;
};
// Many runs at once. releaseSparsePageRuns gives their pages back (MADV_DONTNEED);
// populateSparsePageRuns backs them ahead of the writes that follow (MADV_POPULATE_WRITE: a
// page already backed keeps its bytes, a fresh one reads zero), one call for many pages instead
// of a fault per page. Where the kernel takes a list of ranges in one call (process_madvise on
// the calling process, Linux 6.13 and later) they go in batches of up to 1024 runs: giving
// pages back then costs a TLB shootdown across the process's threads per batch, not per run.
// Elsewhere each run is its own madvise; populating is skipped where the kernel lacks it
// (before Linux 5.14: the writes fault the pages in). Both return the runs given to a batched
// call (0 when every run went by madvise).
std::size_t releaseSparsePageRuns(const std::vector<PageRun>& runs) noexcept;
std::size_t populateSparsePageRuns(const std::vector<PageRun>& runs) noexcept;
// Whether the batched call is tried (default true); false: one madvise per run, the twin the
// tests compare with.
void setPageBatching(bool enabled);
// Sorted, distinct page addresses -> runs of adjacent pages.
void pageRuns(std::span<const std::uintptr_t> pages, std::vector<PageRun>& out);

// `sparse`: the vector's block is a sparse one and its elements are left as the fresh block
// holds them (zero bytes, which is what value-initialisation gives the map's element types):
// a sparse vector is sized once, at construction, and never grows.
template <class T>
struct LargeAllocator {
    using value_type = T;
    using propagate_on_container_move_assignment = std::true_type;
    using propagate_on_container_swap = std::true_type;
    using is_always_equal = std::false_type;
    bool sparse = false;
    LargeAllocator() = default;
    explicit LargeAllocator(bool sparseBlock) noexcept : sparse(sparseBlock) {}
    template <class U>
    LargeAllocator(const LargeAllocator<U>& o) noexcept : sparse(o.sparse) {}
    T* allocate(std::size_t n) {
        return static_cast<T*>(sparse ? allocateSparse(n * sizeof(T))
                                      : allocateLarge(n * sizeof(T)));
    }
    void deallocate(T* p, std::size_t n) noexcept {
        if (sparse) {
            deallocateSparse(p, n * sizeof(T));
        } else {
            deallocateLarge(p, n * sizeof(T));
        }
    }
    template <class U, class... Args>
    void construct(U* p, Args&&... args) {
        if constexpr (sizeof...(Args) == 0) {
            if (sparse) return;  // a fresh sparse block reads zero
        }
        ::new (static_cast<void*>(p)) U(std::forward<Args>(args)...);
    }
    // A copy is an ordinary vector.
    LargeAllocator select_on_container_copy_construction() const { return LargeAllocator(); }
    template <class U>
    bool operator==(const LargeAllocator<U>& o) const noexcept {
        return sparse == o.sparse;
    }
};

template <class T>
using LargeVector = std::vector<T, LargeAllocator<T>>;

struct Rgb8 {
    std::uint8_t r = 0, g = 0, b = 0;
    bool operator==(const Rgb8&) const = default;
};

// Where a map lies on the earth: the CRS coordinates of sample (0, 0) (the south-west one, in
// the CRS's units) and the CRS as WKT. Absent (NaN, empty) for maps without one (synthetic, PNG).
struct Georeference {
    double originX = std::numeric_limits<double>::quiet_NaN();
    double originY = std::numeric_limits<double>::quiet_NaN();
    std::string crs;
    bool present() const { return !crs.empty() && originX == originX && originY == originY; }
};

// A surface to stand on, for whoever reads the terrain outside a caster (the flight model's
// floor): a map, or the ground a paged map keeps for the other threads (ig/paged_ground.hpp).
class Ground {
  public:
    virtual ~Ground() = default;
    // Height of the ground at world (x, y), metres (on or above the terrain's surface); NaN
    // where there is none (an empty map).
    virtual double groundHeight(double x, double y) const = 0;
    // World extent of the ground: x in [0, extentX], y in [0, extentY].
    virtual double extentX() const = 0;
    virtual double extentY() const = 0;
    // Names the point the ground should keep its data around (a paged ground: its thread
    // follows it rather than the last point asked for); nothing for a map held whole.
    virtual void follow(double /*x*/, double /*y*/) const {}
    bool covers(double x, double y) const {
        return x >= 0.0 && y >= 0.0 && x <= extentX() && y <= extentY();
    }
};

// Cell and fraction of a world coordinate along an axis of n samples at `spacing`, clamped to
// the grid (the cell TerrainMap::surfaceHeight interpolates in).
inline void gridCellOf(double v, double spacing, int n, int& i, double& f) {
    const double g = std::clamp(v / spacing, 0.0, static_cast<double>(n - 1));
    i = std::min(static_cast<int>(g), std::max(n - 2, 0));
    f = g - i;
}
// The bilinear blend of a cell's four heights at fractions (fx, fy), as surfaceHeight takes it.
inline double bilinearHeight(double h00, double h10, double h01, double h11, double fx, double fy) {
    return (h00 * (1 - fx) + h10 * fx) * (1 - fy) + (h01 * (1 - fx) + h11 * fx) * fy;
}

// Grid convention (files): column i -> x = i * spacingX (east); row j with row 0 the north edge
// -> y = (rows - 1 - j) * spacingY (north); z = value * heightScale + heightOffset (up).
// In memory the rows are stored south first: sample (ix, iy) sits at x = ix * spacingX,
// y = iy * spacingY, index iy * width + ix. Loaders flip file rows accordingly.
class TerrainMap final : public Ground {
  public:
    TerrainMap() = default;
    // Allocates a width x height map filled with raw height 0 and black.
    TerrainMap(int width, int height, double spacingX, double spacingY, double heightScale,
               double heightOffset);
    // A map whose arrays are sparse blocks (allocateSparse): heights, colours and cell maxima
    // read zero until written and only the pages written take memory. Its height range and
    // slope bound are the given ones (what the whole map has), not computed: whoever fills it
    // (PagedTerrain) keeps the cell maxima consistent and never calls updateRange().
    static TerrainMap sparse(int width, int height, double spacingX, double spacingY,
                             double heightScale, double heightOffset, double minHeight,
                             double maxHeight, double maxSlope);

    int width() const { return width_; }
    int height() const { return height_; }
    double spacingX() const { return spacingX_; }
    double spacingY() const { return spacingY_; }
    double heightScale() const { return heightScale_; }
    double heightOffset() const { return heightOffset_; }
    // World extent of the sample grid: x in [0, extentX], y in [0, extentY].
    double extentX() const override { return (width_ - 1) * spacingX_; }
    double extentY() const override { return (height_ - 1) * spacingY_; }
    bool empty() const { return width_ == 0 || height_ == 0; }

    std::uint16_t raw(int ix, int iy) const { return heights_[index(ix, iy)]; }
    double heightAt(int ix, int iy) const { return raw(ix, iy) * heightScale_ + heightOffset_; }
    Rgb8 colorAt(int ix, int iy) const { return colors_[index(ix, iy)]; }
    void setRaw(int ix, int iy, std::uint16_t v) { heights_[index(ix, iy)] = v; }
    void setColor(int ix, int iy, Rgb8 c) { colors_[index(ix, iy)] = c; }

    // Bilinear surface height at world (x, y); clamps to the map's edge.
    double surfaceHeight(double x, double y) const;
    // surfaceHeight(); NaN for an empty map.
    double groundHeight(double x, double y) const override {
        return empty() ? std::numeric_limits<double>::quiet_NaN() : surfaceHeight(x, y);
    }
    // Bilinear colour at world (x, y), components 0..255; clamps to the map's edge.
    void surfaceColor(double x, double y, float rgb[3]) const;

    // Raw storage, rows south first.
    const LargeVector<std::uint16_t>& rawHeights() const { return heights_; }
    LargeVector<std::uint16_t>& rawHeights() { return heights_; }
    const LargeVector<Rgb8>& colors() const { return colors_; }
    LargeVector<Rgb8>& colors() { return colors_; }

    // Highest and lowest surface heights in metres, and the per-cell maxima below (all
    // recomputed by updateRange(): call it after changing heights).
    double maxHeight() const { return maxHeight_; }
    double minHeight() const { return minHeight_; }
    void updateRange();
    // Lowers the lowest height to `z` (metres) where it lies above: the box the casters clip
    // rays to then reaches down to z (a bound, not a sample; updateRange() resets it).
    void extendFloor(double z) { minHeight_ = std::min(minHeight_, z); }
    // Samples the source had no data for, filled by the loader (0 for most maps).
    std::size_t filledSamples() const { return filledSamples_; }
    void setFilledSamples(std::size_t n) { filledSamples_ = n; }
    // The map's georeference (loaders of georeferenced rasters and databases set it).
    const Georeference& georeference() const { return georef_; }
    void setGeoreference(Georeference g) { georef_ = std::move(g); }

    // Raw maximum of the four samples of cell (cx, cy), cx in [0, width-2], cy in [0, height-2]:
    // a conservative bound on the bilinear surface over the cell. Stored (width-1) per row.
    std::uint16_t cellMaxRaw(int cx, int cy) const {
        return cellMax_[static_cast<std::size_t>(cy) * (width_ - 1) + cx];
    }
    // The cell maxima, (width-1) per row, followed by two spare entries.
    const std::uint16_t* cellMaxData() const { return cellMax_.data(); }
    std::uint16_t* cellMaxData() { return cellMax_.data(); }
    // Raises cell (cx, cy)'s maximum to at least `raw`, and the map's highest height with it
    // (objects standing on the map; updateRange() drops what was raised).
    void raiseCellMaxRaw(int cx, int cy, std::uint16_t raw) {
        std::uint16_t& m = cellMax_[static_cast<std::size_t>(cy) * (width_ - 1) + cx];
        if (raw > m) m = raw;
        maxHeight_ = std::max(maxHeight_, raw * heightScale_ + heightOffset_);
    }
    // Bound on the gradient magnitude of the bilinear surface anywhere on the map (m per m).
    double maxSlope() const { return maxSlope_; }

    // Shades the map in place from its heights: a grey-green albedo lit by a sun at the given
    // azimuth (clockwise from north) and elevation, radians. Used when no colour image is given.
    void shadeFromHeights(double sunAzimuth = 5.5, double sunElevation = 0.7);

    std::size_t index(int ix, int iy) const {
        return static_cast<std::size_t>(iy) * static_cast<std::size_t>(width_) + ix;
    }

  private:
    int width_ = 0, height_ = 0;
    double spacingX_ = 1.0, spacingY_ = 1.0;
    double heightScale_ = 1.0, heightOffset_ = 0.0;
    double maxHeight_ = 0.0, minHeight_ = 0.0, maxSlope_ = 0.0;
    LargeVector<std::uint16_t> heights_;
    LargeVector<Rgb8> colors_;
    LargeVector<std::uint16_t> cellMax_;
    std::size_t filledSamples_ = 0;
    Georeference georef_;
};

// Whether (x, y) lies within the map's own size of the map; positions further off are taken for
// a mistake of coordinates (UTM or degrees instead of metres from the map's south-west sample).
inline bool nearMap(const TerrainMap& map, double x, double y) {
    const double far = std::max(map.extentX(), map.extentY());
    return x > -far && y > -far && x < map.extentX() + far && y < map.extentY() + far;
}

// Asks the kernel to back [data, data + bytes) with transparent huge pages, collapsing what is
// already populated, where the kernel supports it; a no-op for small ranges or when turned off.
// Large maps are marched from DRAM, where 4 KiB pages make nearly every step a TLB miss.
void adviseHugePages(const void* data, std::size_t bytes);
// Turns adviseHugePages on or off process-wide (on by default; for measurements).
void setHugePageAdvice(bool enabled);

}  // namespace ig
