#include "ig/terrain.hpp"

#include <sys/mman.h>
#include <sys/syscall.h>
#include <sys/uio.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <new>

#ifndef MADV_COLLAPSE
#define MADV_COLLAPSE 25  // Linux 6.1; older C libraries lack the name
#endif
#ifndef MADV_POPULATE_WRITE
#define MADV_POPULATE_WRITE 23  // Linux 5.14
#endif

namespace ig {

namespace {
std::atomic<bool> gHugePageAdvice{true};
std::atomic<bool> gPageBatching{true};
// Whether this kernel took process_madvise with each advice on the calling process: -1 not
// tried yet, 0 refused (then never tried again), 1 taken.
std::atomic<int> gBatchedRelease{-1};
std::atomic<int> gBatchedPopulate{-1};
std::atomic<bool> gPopulateRefused{false};

constexpr std::size_t kSparsePage = 4096;
constexpr std::size_t kMaxBatch = 1024;  // IOV_MAX on Linux

// One madvise per run; false where the kernel refuses the advice itself.
bool adviseEach(const std::vector<PageRun>& runs, std::size_t first, int advice) {
    for (std::size_t i = first; i < runs.size(); ++i) {
        if (madvise(reinterpret_cast<void*>(runs[i].begin), runs[i].pages * kSparsePage, advice) !=
                0 &&
            errno == EINVAL) {
            return false;
        }
    }
    return true;
}

// The runs in batches by process_madvise on this process; returns the runs it advised, after
// which the rest go by madvise (a kernel that refuses the call, or a batch cut short).
std::size_t adviseBatched(const std::vector<PageRun>& runs, int advice, std::atomic<int>& taken) {
    if (runs.empty() || !gPageBatching.load() || taken.load() == 0) return 0;
#if defined(SYS_process_madvise) && defined(SYS_pidfd_open)
    // Opened per call: a forked renderer process is a process of its own.
    const int pidfd = static_cast<int>(syscall(SYS_pidfd_open, getpid(), 0));
    if (pidfd < 0) {
        taken.store(0);
        return 0;
    }
    iovec iov[kMaxBatch];
    std::size_t done = 0;
    while (done < runs.size()) {
        const std::size_t n = std::min(kMaxBatch, runs.size() - done);
        std::size_t bytes = 0;
        for (std::size_t i = 0; i < n; ++i) {
            iov[i].iov_base = reinterpret_cast<void*>(runs[done + i].begin);
            iov[i].iov_len = runs[done + i].pages * kSparsePage;
            bytes += iov[i].iov_len;
        }
        const long r = syscall(SYS_process_madvise, pidfd, iov, n, advice, 0u);
        if (r < 0) {
            // Before Linux 6.13 only a few advices are taken (EINVAL); no pidfd support, or
            // none allowed (ENOSYS, EPERM, ESRCH): the rest by madvise, and no more tries.
            if (done == 0) taken.store(0);
            break;
        }
        taken.store(1);
        if (static_cast<std::size_t>(r) != bytes) {
            // Cut short: the runs wholly advised count, the others go by madvise.
            std::size_t whole = 0, sum = 0;
            while (whole < n && sum + iov[whole].iov_len <= static_cast<std::size_t>(r))
                sum += iov[whole++].iov_len;
            done += whole;
            break;
        }
        done += n;
    }
    close(pidfd);
    return done;
#else
    (void)advice;
    taken.store(0);
    return 0;
#endif
}
}  // namespace

void setPageBatching(bool enabled) {
    gPageBatching.store(enabled);
}

void pageRuns(std::span<const std::uintptr_t> pages, std::vector<PageRun>& out) {
    out.clear();
    for (std::size_t i = 0; i < pages.size();) {
        std::size_t j = i + 1;
        while (j < pages.size() && pages[j] == pages[j - 1] + kSparsePage)
            ++j;
        out.push_back(PageRun{pages[i], j - i});
        i = j;
    }
}

std::size_t releaseSparsePageRuns(const std::vector<PageRun>& runs) noexcept {
    const std::size_t batched = adviseBatched(runs, MADV_DONTNEED, gBatchedRelease);
    adviseEach(runs, batched, MADV_DONTNEED);
    return batched;
}

std::size_t populateSparsePageRuns(const std::vector<PageRun>& runs) noexcept {
    if (gPopulateRefused.load()) return 0;
    const std::size_t batched = adviseBatched(runs, MADV_POPULATE_WRITE, gBatchedPopulate);
    // A kernel without MADV_POPULATE_WRITE: the writes fault the pages in, as they would.
    if (!adviseEach(runs, batched, MADV_POPULATE_WRITE)) gPopulateRefused.store(true);
    return batched;
}

void setHugePageAdvice(bool enabled) {
    gHugePageAdvice.store(enabled);
}

void adviseHugePages(const void* data, std::size_t bytes) {
    constexpr std::uintptr_t kHuge = std::uintptr_t{2} << 20;
    if (!gHugePageAdvice.load() || bytes < 2 * kHuge) return;
    // Only whole 2 MiB pages inside the range; the kernel ignores what it cannot honour.
    const auto begin = (reinterpret_cast<std::uintptr_t>(data) + kHuge - 1) & ~(kHuge - 1);
    const auto end = (reinterpret_cast<std::uintptr_t>(data) + bytes) & ~(kHuge - 1);
    if (end <= begin) return;
    void* p = reinterpret_cast<void*>(begin);
    if (madvise(p, end - begin, MADV_HUGEPAGE) == 0) madvise(p, end - begin, MADV_COLLAPSE);
}

void* allocateLarge(std::size_t bytes) {
    constexpr std::size_t kHuge = std::size_t{2} << 20;
    if (bytes < 2 * kHuge) return ::operator new(bytes);
    const std::size_t rounded = (bytes + kHuge - 1) & ~(kHuge - 1);
    void* p = std::aligned_alloc(kHuge, rounded);
    if (!p) throw std::bad_alloc();
    if (gHugePageAdvice.load()) madvise(p, rounded, MADV_HUGEPAGE);
    return p;
}

void deallocateLarge(void* p, std::size_t bytes) noexcept {
    constexpr std::size_t kHuge = std::size_t{2} << 20;
    if (bytes < 2 * kHuge) {
        ::operator delete(p);
    } else {
        std::free(p);
    }
}

void* allocateSparse(std::size_t bytes) {
    if (bytes == 0) bytes = 1;
    void* p = mmap(nullptr, bytes, PROT_READ | PROT_WRITE,
                   MAP_PRIVATE | MAP_ANONYMOUS | MAP_NORESERVE, -1, 0);
    if (p == MAP_FAILED) throw std::bad_alloc();
    // 4 KiB pages: memory follows the tiles written, not 2 MiB around each.
    madvise(p, bytes, MADV_NOHUGEPAGE);
    return p;
}

void deallocateSparse(void* p, std::size_t bytes) noexcept {
    if (p) munmap(p, bytes == 0 ? 1 : bytes);
}

TerrainMap TerrainMap::sparse(int width, int height, double spacingX, double spacingY,
                              double heightScale, double heightOffset, double minHeight,
                              double maxHeight, double maxSlope) {
    TerrainMap m;
    m.width_ = width;
    m.height_ = height;
    m.spacingX_ = spacingX;
    m.spacingY_ = spacingY;
    m.heightScale_ = heightScale;
    m.heightOffset_ = heightOffset;
    m.minHeight_ = minHeight;
    m.maxHeight_ = maxHeight;
    m.maxSlope_ = maxSlope;
    const std::size_t n = static_cast<std::size_t>(width) * static_cast<std::size_t>(height);
    m.heights_ = LargeVector<std::uint16_t>(n, LargeAllocator<std::uint16_t>(true));
    m.colors_ = LargeVector<Rgb8>(n, LargeAllocator<Rgb8>(true));
    m.cellMax_ = LargeVector<std::uint16_t>(
        static_cast<std::size_t>(std::max(width - 1, 0)) * std::max(height - 1, 0) + 2,
        LargeAllocator<std::uint16_t>(true));
    return m;
}

TerrainMap::TerrainMap(int width, int height, double spacingX, double spacingY, double heightScale,
                       double heightOffset)
    : width_(width),
      height_(height),
      spacingX_(spacingX),
      spacingY_(spacingY),
      heightScale_(heightScale),
      heightOffset_(heightOffset),
      heights_(static_cast<std::size_t>(width) * static_cast<std::size_t>(height), 0),
      colors_(heights_.size()) {
    updateRange();
}

void TerrainMap::updateRange() {
    if (heights_.empty()) {
        maxHeight_ = minHeight_ = heightOffset_;
        return;
    }
    // Two spare entries after the last cell: four-byte vector gathers of a cell's bound stay
    // inside the array.
    cellMax_.assign(
        static_cast<std::size_t>(std::max(width_ - 1, 0)) * std::max(height_ - 1, 0) + 2, 0);
    // Over a cell the bilinear surface's x-slope lies between its two edge slopes (likewise y),
    // so the largest sample difference along each axis bounds the gradient.
    int maxDx = 0, maxDy = 0;
    for (int cy = 0; cy + 1 < height_; ++cy) {
        for (int cx = 0; cx + 1 < width_; ++cx) {
            const int h00 = raw(cx, cy), h10 = raw(cx + 1, cy);
            const int h01 = raw(cx, cy + 1), h11 = raw(cx + 1, cy + 1);
            cellMax_[static_cast<std::size_t>(cy) * (width_ - 1) + cx] =
                static_cast<std::uint16_t>(std::max({h00, h10, h01, h11}));
            maxDx = std::max({maxDx, std::abs(h10 - h00), std::abs(h11 - h01)});
            maxDy = std::max({maxDy, std::abs(h01 - h00), std::abs(h11 - h10)});
        }
    }
    const double gx = maxDx * std::abs(heightScale_) / spacingX_;
    const double gy = maxDy * std::abs(heightScale_) / spacingY_;
    maxSlope_ = std::sqrt(gx * gx + gy * gy);
    auto [lo, hi] = std::minmax_element(heights_.begin(), heights_.end());
    const double a = *lo * heightScale_ + heightOffset_;
    const double b = *hi * heightScale_ + heightOffset_;
    minHeight_ = std::min(a, b);
    maxHeight_ = std::max(a, b);
    adviseHugePages(heights_.data(), heights_.size() * sizeof(std::uint16_t));
    adviseHugePages(colors_.data(), colors_.size() * sizeof(Rgb8));
    adviseHugePages(cellMax_.data(), cellMax_.size() * sizeof(std::uint16_t));
}

double TerrainMap::surfaceHeight(double x, double y) const {
    int ix, iy;
    double fx, fy;
    gridCellOf(x, spacingX_, width_, ix, fx);
    gridCellOf(y, spacingY_, height_, iy, fy);
    const int ix1 = std::min(ix + 1, width_ - 1), iy1 = std::min(iy + 1, height_ - 1);
    return bilinearHeight(heightAt(ix, iy), heightAt(ix1, iy), heightAt(ix, iy1),
                          heightAt(ix1, iy1), fx, fy);
}

void TerrainMap::surfaceColor(double x, double y, float rgb[3]) const {
    int ix, iy;
    double fx, fy;
    gridCellOf(x, spacingX_, width_, ix, fx);
    gridCellOf(y, spacingY_, height_, iy, fy);
    const int ix1 = std::min(ix + 1, width_ - 1), iy1 = std::min(iy + 1, height_ - 1);
    const Rgb8 c00 = colorAt(ix, iy), c10 = colorAt(ix1, iy);
    const Rgb8 c01 = colorAt(ix, iy1), c11 = colorAt(ix1, iy1);
    const double w00 = (1 - fx) * (1 - fy), w10 = fx * (1 - fy), w01 = (1 - fx) * fy, w11 = fx * fy;
    rgb[0] = static_cast<float>(w00 * c00.r + w10 * c10.r + w01 * c01.r + w11 * c11.r);
    rgb[1] = static_cast<float>(w00 * c00.g + w10 * c10.g + w01 * c01.g + w11 * c11.g);
    rgb[2] = static_cast<float>(w00 * c00.b + w10 * c10.b + w01 * c01.b + w11 * c11.b);
}

void TerrainMap::shadeFromHeights(double sunAzimuth, double sunElevation) {
    const double lx = std::sin(sunAzimuth) * std::cos(sunElevation);
    const double ly = std::cos(sunAzimuth) * std::cos(sunElevation);
    const double lz = std::sin(sunElevation);
    const double range = std::max(maxHeight_ - minHeight_, 1e-9);
    for (int iy = 0; iy < height_; ++iy) {
        for (int ix = 0; ix < width_; ++ix) {
            const int x0 = std::max(ix - 1, 0), x1 = std::min(ix + 1, width_ - 1);
            const int y0 = std::max(iy - 1, 0), y1 = std::min(iy + 1, height_ - 1);
            const double dzdx =
                (heightAt(x1, iy) - heightAt(x0, iy)) / std::max((x1 - x0) * spacingX_, 1e-12);
            const double dzdy =
                (heightAt(ix, y1) - heightAt(ix, y0)) / std::max((y1 - y0) * spacingY_, 1e-12);
            // Normal (-dz/dx, -dz/dy, 1), normalised.
            const double inv = 1.0 / std::sqrt(dzdx * dzdx + dzdy * dzdy + 1.0);
            const double lambert = std::max(0.0, (-dzdx * lx - dzdy * ly + lz) * inv);
            const double light = 0.25 + 0.75 * lambert;
            // Albedo by elevation: low green, mid brown, high near-white.
            const double t = (heightAt(ix, iy) - minHeight_) / range;
            const double r = t < 0.5 ? 70 + 140 * t : 140 + 200 * (t - 0.5);
            const double g = t < 0.5 ? 120 + 40 * t : 140 + 180 * (t - 0.5);
            const double b = t < 0.5 ? 60 + 40 * t : 80 + 300 * (t - 0.5);
            auto q = [&](double v) {
                return static_cast<std::uint8_t>(std::clamp(v * light, 0.0, 255.0) + 0.5);
            };
            colors_[index(ix, iy)] = Rgb8{q(r), q(g), q(b)};
        }
    }
}

}  // namespace ig
