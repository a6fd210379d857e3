// The discrete ray march shared by the naive and fast casters: one step per grid line crossed
// along the ray's major axis (Cohen-Or sec. 2.1), the minor coordinate carried in 32.32 fixed
// point. A step is tested against the per-cell maxima of the (at most two) cells it crosses, so
// no feature between grid lines is stepped over, and the hit is solved exactly in that step.
#pragma once

#include "ig/surface_hit.hpp"
#include "ig/terrain.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>

namespace ig {

namespace detail {

// Solves the piece [ta, tb] of one step, which lies in major cell `mc` and minor cells ca..cb
// (|cb - ca| <= 1 as the minor axis moves at most one cell per step).
template <bool kMajorX>
inline double solveStep(const TerrainMap& map, const TerrainRay& ray, int mc, int ca, int cb,
                        double ta, double tb) {
    auto cell = [&](int minor, double a, double b) {
        return kMajorX ? solveCell(map, ray, mc, minor, a, b)
                       : solveCell(map, ray, minor, mc, a, b);
    };
    if (ca == cb) return cell(ca, ta, tb);
    if (ca - cb > 1 || cb - ca > 1) return exactHitInRange(map, ray, ta, tb);
    // Split where the ray crosses the minor grid line between the two cells.
    const double gon = kMajorX ? ray.goy : ray.gox, gdn = kMajorX ? ray.gdy : ray.gdx;
    const double line = ca < cb ? cb : ca;
    const double tSplit = std::clamp((line - gon) / gdn, ta, tb);
    const double t = cell(ca, ta, tSplit);
    return t >= 0.0 ? t : cell(cb, tSplit, tb);
}

template <bool kMajorX>
double marchAxis(const TerrainMap& map, const TerrainRay& ray, double tStart, double tEnd,
                 std::uint64_t& steps) {
    const std::uint16_t* __restrict__ cellMax = map.cellMaxData();
    const int w = map.width(), h = map.height();
    const std::size_t cellStride = static_cast<std::size_t>(w - 1);
    const int majorCount = kMajorX ? w : h, minorCount = kMajorX ? h : w;
    const int lastMajorCell = majorCount - 2, lastMinorCell = minorCount - 2;
    const double gom = kMajorX ? ray.gox : ray.goy, gdm = kMajorX ? ray.gdx : ray.gdy;
    const double gon = kMajorX ? ray.goy : ray.gox, gdn = kMajorX ? ray.gdy : ray.gdx;
    const int sgn = gdm > 0 ? 1 : -1;
    const double dtm = 1.0 / std::abs(gdm);
    auto minorCell = [lastMinorCell](double g) {
        const int c = static_cast<int>(std::floor(g));
        return c < 0 ? 0 : (c > lastMinorCell ? lastMinorCell : c);
    };

    // The piece before the first grid line at or after tStart.
    const double gm0 = gom + tStart * gdm;
    long m = static_cast<long>(sgn > 0 ? std::ceil(gm0) : std::floor(gm0));
    double tm = std::max((m - gom) / gdm, tStart);
    if (tm > tStart) {
        const double te = std::min(tm, tEnd);
        const int mc = std::clamp(static_cast<int>(sgn > 0 ? m - 1 : m), 0, lastMajorCell);
        const double t = solveStep<kMajorX>(map, ray, mc, minorCell(gon + tStart * gdn),
                                            minorCell(gon + te * gdn), tStart, te);
        if (t >= 0.0) return t;
    }

    constexpr double kFix = 4294967296.0;  // 2^32
    std::int64_t n = static_cast<std::int64_t>(std::llround((gon + tm * gdn) * kFix));
    const std::int64_t dn = static_cast<std::int64_t>(std::llround(gdn * dtm * kFix));
    const double invScale = 1.0 / map.heightScale();
    double zr = (ray.origin.z + tm * ray.dir.z - map.heightOffset()) * invScale;
    const double dzr = ray.dir.z * dtm * invScale;
    const double maxRaw = (map.maxHeight() - map.heightOffset()) * invScale;
    const bool rising = dzr >= 0.0;

    // Each step covers the ray from grid line m to m + sgn: at most two cells, whose four-sample
    // maxima bound the surface there. Only a step that may reach the surface is solved exactly.
    std::uint64_t count = 0;
    while (m + sgn >= 0 && m + sgn < majorCount && tm < tEnd) {
        const std::int64_t na = n >> 32, nb = (n + dn) >> 32;
        if (na < 0 || nb < 0 || na >= minorCount || nb >= minorCount) break;
        const int ca = na > lastMinorCell ? lastMinorCell : static_cast<int>(na);
        const int cb = nb > lastMinorCell ? lastMinorCell : static_cast<int>(nb);
        const int mc = static_cast<int>(sgn > 0 ? m : m - 1);
        const std::size_t ia = kMajorX ? static_cast<std::size_t>(ca) * cellStride + mc
                                       : static_cast<std::size_t>(mc) * cellStride + ca;
        const std::size_t ib = kMajorX ? static_cast<std::size_t>(cb) * cellStride + mc
                                       : static_cast<std::size_t>(mc) * cellStride + cb;
        const double bound = cellMax[ia] > cellMax[ib] ? cellMax[ia] : cellMax[ib];
        const double zLow = rising ? zr : zr + dzr;
        ++count;
        if (zLow <= bound) {
            const double t = solveStep<kMajorX>(map, ray, mc, ca, cb, tm, std::min(tm + dtm, tEnd));
            if (t >= 0.0) {
                steps += count;
                return t;
            }
        } else if (rising && zr > maxRaw) {
            steps += count;
            return -1.0;
        }
        m += sgn;
        n += dn;
        zr += dzr;
        tm += dtm;
    }
    steps += count;
    // What is left inside the map (at most about one step).
    return tm < tEnd ? exactHitInRange(map, ray, tm, tEnd) : -1.0;
}

}  // namespace detail

// First hit at or after tStart (up to tEnd, the end of the ray's map-box interval); negative
// when the ray leaves the map or rises above it first. Adds the grid lines visited to `steps`.
inline double marchRay(const TerrainMap& map, const TerrainRay& ray, double tStart, double tEnd,
                       std::uint64_t& steps) {
    if (!(tStart <= tEnd)) return -1.0;
    if (std::abs(ray.gdx) >= std::abs(ray.gdy)) {
        if (ray.gdx == 0.0) return exactHitInRange(map, ray, tStart, tEnd);
        return detail::marchAxis<true>(map, ray, tStart, tEnd, steps);
    }
    return detail::marchAxis<false>(map, ray, tStart, tEnd, steps);
}

}  // namespace ig
