// The fast caster's level-0 march (Cohen-Or sec. 2.1): one ray of a column from where the ray
// below it stopped, grid line by grid line along the major axis, the minor coordinate in 32.32
// fixed point, each step tested against the cells' maxima and the reachable step solved exactly
// on the bilinear surface. What the scalar column kernel, the four-column packets and the
// clearance chain march with. Internal to the fast caster: it is compiled with its files'
// floating-point flags (no contraction), which the kernels' bit-for-bit equality needs.
#pragma once

#include "ig/surface_hit.hpp"
#include "ig/terrain.hpp"

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <limits>

namespace ig::fast {

// The eye in grid units (x / spacingX, y / spacingY; z in metres), and whether it is over the map.
struct EyeGrid {
    double gx, gy, z;
    bool inside;
    double zRaw;  // z in the map's raw height units
};

// Outcome of a coherent column march: a level-0 hit at u (cell and local coordinates for the
// colour), a stop at u (the ray left the map: sky), climbing above the map's highest point at
// u (sky, and so is every coherent ray above it in the column), the level-0 distance
// reached at u (go on with the multiresolution march), or a start outside the map (cast fresh).
struct ColumnMarch {
    enum Kind { kHit, kStop, kAbove, kFar, kFresh };
    Kind kind = kHit;
    double u = 0.0;
    int cx = 0, cy = 0;
    double fx = 0.0, fy = 0.0;
};

// Nearest integer (halves away from zero), inline (std::llround is a library call).
inline std::int64_t roundToInt64(double v) {
    return static_cast<std::int64_t>(v >= 0.0 ? v + 0.5 : v - 0.5);
}

// floor(v) for |v| < 2^62, inline (without SSE4.1 std::floor is a library call).
inline long floorToLong(double v) {
    const long t = static_cast<long>(v);
    return t > v ? t - 1 : t;
}

// What the per-pixel path reads of the map, fetched once per frame into plain values (the
// image writes, through byte pointers, would otherwise force the compiler to reload them).
struct MapView {
    const std::uint16_t* heights;
    const std::uint16_t* cellMax;
    const Rgb8* colors;
    int width, height;
    double scale, offset, invScale;
    double maxRaw;  // the map's highest point in raw height units
};

// Exact solve of one march step (the ray between major grid lines m and m + sgn, in minor cells
// ca..cb) on the level-0 bilinear surface, in the major-axis parameter s in [sBegin, sEnd].
// Heights are in raw units (the solve is linear in them): ray height ezr + rzr * u.
template <bool kMajorX>
struct StepSolver {
    const std::uint16_t* heights;
    const std::uint16_t* cellMax;
    int width;
    int sgn;
    double rn, rzr, ezr;

    // kOwnBound: test the piece against its own cell's bound first (when the step's bound
    // covered two cells, this piece may lie above its own).
    template <bool kOwnBound>
    [[gnu::always_inline]] bool piece(long m, int mc, int cn, std::int64_t n, double u, double s0,
                                      double s1, ColumnMarch& out) const {
        if (!(s0 < s1)) return false;
        const int cx = kMajorX ? mc : cn, cy = kMajorX ? cn : mc;
        const double za = ezr + rzr * (u + s0);
        if (kOwnBound) {
            const double zLow = rzr >= 0.0 ? za : za + rzr * (s1 - s0);
            if (zLow > cellMax[static_cast<std::size_t>(cy) * (width - 1) + cx]) return false;
        }
        const double nD = static_cast<double>(n) * (1.0 / 4294967296.0);
        const double majorLocal = static_cast<double>(m - mc);
        const std::uint16_t* s00 = heights + static_cast<std::size_t>(cy) * width + cx;
        const double h00 = s00[0], h10 = s00[1], h01 = s00[width], h11 = s00[width + 1];
        const double am = majorLocal + sgn * s0, an = nD + rn * s0 - cn;
        const double r = kMajorX
                             ? solveBilinear(h00, h10, h01, h11, am, an, sgn, rn, za, rzr, s1 - s0)
                             : solveBilinear(h00, h10, h01, h11, an, am, rn, sgn, za, rzr, s1 - s0);
        if (r < 0.0) return false;
        const double sh = s0 + r;
        out.kind = ColumnMarch::kHit;
        out.u = u + sh;
        out.cx = cx;
        out.cy = cy;
        const double fm = majorLocal + sgn * sh, fn = nD + rn * sh - cn;
        out.fx = kMajorX ? fm : fn;
        out.fy = kMajorX ? fn : fm;
        return true;
    }

    // Split where the step crosses the minor grid line between ca and cb.
    [[gnu::always_inline]] bool solve(long m, int mc, int ca, int cb, std::int64_t n, double u,
                                      double sBegin, double sEnd, ColumnMarch& out) const {
        if (ca == cb) return piece<false>(m, mc, ca, n, u, sBegin, sEnd, out);
        const double nD = static_cast<double>(n) * (1.0 / 4294967296.0);
        const double line = ca < cb ? cb : ca;
        const double sSplit = std::clamp((line - nD) / rn, 0.0, sEnd);
        return piece<true>(m, mc, ca, n, u, std::max(sBegin, 0.0), sSplit, out) ||
               piece<true>(m, mc, cb, n, u, std::max(sBegin, sSplit), sEnd, out);
    }
};

// Bilinear colour of level-0 cell (cx, cy) at local (fx, fy) (as TerrainMap::surfaceColor).
inline void cellColor(const MapView& mv, int cx, int cy, double fx, double fy, float rgb[3]) {
    fx = std::clamp(fx, 0.0, 1.0);
    fy = std::clamp(fy, 0.0, 1.0);
    const Rgb8* row0 = mv.colors + static_cast<std::size_t>(cy) * mv.width + cx;
    const Rgb8* row1 = row0 + mv.width;
    const double w00 = (1 - fx) * (1 - fy), w10 = fx * (1 - fy), w01 = (1 - fx) * fy, w11 = fx * fy;
    rgb[0] =
        static_cast<float>(w00 * row0[0].r + w10 * row0[1].r + w01 * row1[0].r + w11 * row1[1].r);
    rgb[1] =
        static_cast<float>(w00 * row0[0].g + w10 * row0[1].g + w01 * row1[0].g + w11 * row1[1].g);
    rgb[2] =
        static_cast<float>(w00 * row0[0].b + w10 * row0[1].b + w01 * row1[0].b + w11 * row1[1].b);
}

// The coherent march of one ray in major-axis form from u = uStart: grid line by grid line
// (as marchRay), the minor coordinate in 32.32 fixed point, z incremental (raw height units);
// the reachable step solved exactly. No per-ray box clip, normalisation or division.
template <bool kMajorX>
[[gnu::always_inline]] inline ColumnMarch marchCoherent(const MapView& mv, const EyeGrid& eg,
                                                        int sgn, double rn, double rz,
                                                        double uStart, double uNear,
                                                        std::uint64_t& steps) {
    const std::uint16_t* __restrict__ cellMax = mv.cellMax;
    const int w = mv.width;
    const std::size_t stride = static_cast<std::size_t>(w - 1);
    const int majorCount = kMajorX ? w : mv.height, minorCount = kMajorX ? mv.height : w;
    const int lastMinorCell = minorCount - 2;
    const double em = kMajorX ? eg.gx : eg.gy, en = kMajorX ? eg.gy : eg.gx;
    ColumnMarch out;
    out.u = uStart;
    // The grid line at or before the start (in the direction of travel).
    const double gm0 = em + sgn * uStart;
    long m = sgn > 0 ? floorToLong(gm0) : -floorToLong(-gm0);
    if (m < 0 || m > majorCount - 1) {
        const bool ahead = sgn > 0 ? m < 0 : m > majorCount - 1;
        out.kind = ahead || !eg.inside ? ColumnMarch::kFresh : ColumnMarch::kStop;
        return out;
    }
    double u = (m - em) * sgn;
    constexpr double kFix = 4294967296.0;  // 2^32
    std::int64_t n = roundToInt64((en + rn * u) * kFix);
    const std::int64_t dn = roundToInt64(rn * kFix);
    const std::int64_t minorLimit = static_cast<std::int64_t>(minorCount - 1) << 32;
    const double ezr = eg.zRaw;
    const double dzr = rz * mv.invScale;
    double zr = ezr + dzr * u;
    const double maxRaw = mv.maxRaw;
    const bool rising = dzr >= 0.0;
    if (n < 0 || n > minorLimit) {
        out.kind = !eg.inside ? ColumnMarch::kFresh : ColumnMarch::kStop;
        return out;
    }
    // Whole steps before the ray reaches the major end or the level-0 distance; a step that
    // would leave the minor range ends the loop (then one last partial step).
    constexpr std::int64_t kMany = std::int64_t{1} << 40;
    const std::int64_t majorSteps = sgn > 0 ? majorCount - 1 - m : m;
    std::int64_t nearSteps = kMany;
    if (uNear < 1e12) nearSteps = std::max<long>(0, -floorToLong(u - uNear));
    const std::int64_t total = std::min(majorSteps, nearSteps);
    const int mc0 = static_cast<int>(m) + (sgn > 0 ? 0 : -1);
    // The first step is solved from uStart on: before it the ray is known to be clear (and
    // the grid line may lie behind the eye).
    const double sBegin0 = uStart - u;
    // The cell-max index of (major cell mc, minor cell c) is mc * majorStride + c *
    // minorStride; the next step's first cell is this step's second one, one major cell on.
    const std::ptrdiff_t minorStride = kMajorX ? static_cast<std::ptrdiff_t>(stride) : 1;
    const std::ptrdiff_t majorStep = kMajorX ? sgn : sgn * static_cast<std::ptrdiff_t>(stride);
    int ca = std::min(static_cast<int>(n >> 32), lastMinorCell);
    std::ptrdiff_t ia = kMajorX ? static_cast<std::ptrdiff_t>(ca) * stride + mc0
                                : static_cast<std::ptrdiff_t>(mc0) * stride + ca;
    // The lower end of the step's piece of ray (its start when rising, else its end).
    double zLow = rising ? zr : zr + dzr;
    // Step k runs from major grid line m + sgn * k (u + k) to the next one.
    std::int64_t k = 0;
    bool leavesMinor = false;
    for (;;) {
        // Scan for the next step the ray may reach (the hot loop: bound test only).
        std::int64_t next = 0;
        int cb = 0;
        std::ptrdiff_t ib = 0;
        bool reach = false;
        for (; k < total; ++k) {
            next = n + dn;
            if (static_cast<std::uint64_t>(next) > static_cast<std::uint64_t>(minorLimit)) {
                leavesMinor = true;
                break;
            }
            cb = std::min(static_cast<int>(next >> 32), lastMinorCell);
            ib = ia + (cb - ca) * minorStride;
            if (zLow <= std::max(cellMax[ia], cellMax[ib])) {
                reach = true;
                break;
            }
            if (rising && zLow > maxRaw) {
                steps += static_cast<std::uint64_t>(k + 1);
                out.kind = ColumnMarch::kAbove;
                out.u = u + static_cast<double>(k);
                return out;
            }
            n = next;
            ca = cb;
            ia = ib + majorStep;
            zLow += dzr;
        }
        if (!reach) break;
        const StepSolver<kMajorX> solver{mv.heights, cellMax, w, sgn, rn, dzr, ezr};
        const int step = static_cast<int>(k);
        if (solver.solve(m + sgn * step, mc0 + sgn * step, ca, cb, n, u + static_cast<double>(k),
                         k == 0 ? sBegin0 : 0.0, 1.0, out)) {
            steps += static_cast<std::uint64_t>(k + 1);
            return out;
        }
        n = next;
        ca = cb;
        ia = ib + majorStep;
        zLow += dzr;
        ++k;
    }
    steps += static_cast<std::uint64_t>(k);
    out.u = u + static_cast<double>(k);
    if (!leavesMinor) {
        out.kind = total == nearSteps && nearSteps < majorSteps + 1 ? ColumnMarch::kFar
                                                                    : ColumnMarch::kStop;
        return out;
    }
    // The ray leaves through a minor edge part-way through this step: solve up to there.
    out.kind = ColumnMarch::kStop;
    ++steps;
    const double edge = n + dn < 0 ? 0.0 : minorCount - 1.0;
    const double nD = static_cast<double>(n) * (1.0 / kFix);
    const double sEnd = std::clamp((edge - nD) / rn, 0.0, 1.0);
    const int cb = n + dn < 0 ? 0 : lastMinorCell;
    const int step = static_cast<int>(k);
    const StepSolver<kMajorX> solver{mv.heights, cellMax, w, sgn, rn, dzr, ezr};
    if (solver.solve(m + sgn * step, mc0 + sgn * step, ca, cb, n, out.u, k == 0 ? sBegin0 : 0.0,
                     sEnd, out)) {
        return out;
    }
    out.kind = ColumnMarch::kStop;
    out.u = u + static_cast<double>(k);
    return out;
}

}  // namespace ig::fast
