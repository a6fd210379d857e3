// The multiresolution caster's far march (far_march.hpp).
#include "ig/far_march.hpp"

#include "ig/multires_march.hpp"

#include <cmath>
#include <limits>
#include <utility>

namespace ig::fast {

namespace {

// Lines a far ray samples before it skips down the max-height nodes.
constexpr long kFarLines = 16;

// Height (raw) of a level's surface where it crosses major line `line` at minor coordinate
// `n` (both in the level's grid units), linear along the line.
template <bool kMajorX>
[[gnu::always_inline]] inline double lineSample(const PyramidLevel& l, long line, double n) {
    const int minorCount = kMajorX ? l.height : l.width;
    const int i = std::min(static_cast<int>(n), minorCount - 2);
    const double f = n - i;
    const std::ptrdiff_t minorStride = kMajorX ? l.width : 1;
    const std::uint16_t* p =
        l.heights + (kMajorX ? line + static_cast<std::ptrdiff_t>(i) * l.width
                             : line * static_cast<std::ptrdiff_t>(l.width) + i);
    const double h0 = p[0];
    return h0 + f * (static_cast<double>(p[minorStride]) - h0);
}

}  // namespace

void FarMarch::linearFar(const ColumnContext& cc, double dx, double dy, double dz, double len,
                         double inv, bool majorX, int sgn, double rn, double rz, double uStart,
                         double& uStop, bool& above, std::uint64_t& steps, Rgb8& c,
                         double& tHit) const {
    const glm::dvec3 d(dx, dy, dz);
    const double hs = std::sqrt(d.x * d.x + d.y * d.y) * inv;  // metres per major unit
    // Far rays may pass over long stretches of terrain between hits (a row's hit moves by
    // many cells there): after a few lines without a hit they skip down the max-height
    // nodes, which bound every display level and so any blend of two.
    const double lenPerU = len * inv;
    double from = uStart;
    FarHit f = majorX ? marchLinearFar<true>(cc, sgn, rn, rz, hs, from, kFarLines, steps)
                      : marchLinearFar<false>(cc, sgn, rn, rz, hs, from, kFarLines, steps);
    if (f.kind == ColumnMarch::kFar) {
        const TerrainRay ray(map_, cc.eye, d);
        double t0, t1;
        const double tFrom = f.u * lenPerU;
        if (!clipToMapBox(map_, ray, t0, t1) || !(t1 > tFrom)) {
            uStop = f.u;
            above = false;
            tHit = -1.0;
            c = skyColor(sky_, d.z / len);
            return;
        }
        const double t = skipEmptySpace(pyramid_, ray, std::max(t0, tFrom), t1, steps);
        if (t < 0.0) {
            // Nothing met up to where the ray leaves the map box: through its top (every
            // ray above does too) or a side.
            uStop = std::max(f.u, t1 / lenPerU);
            above = ray.dir.z >= 0.0 && ray.origin.z + t1 * ray.dir.z >= map_.maxHeight();
            tHit = -1.0;
            c = skyColor(sky_, d.z / len);
            return;
        }
        from = std::max(f.u, t / lenPerU);
        f = majorX ? marchLinearFar<true>(cc, sgn, rn, rz, hs, from, -1, steps)
                   : marchLinearFar<false>(cc, sgn, rn, rz, hs, from, -1, steps);
    }
    uStop = std::max(f.u, from);
    above = f.kind == ColumnMarch::kAbove;
    tHit = -1.0;
    if (f.kind != ColumnMarch::kHit) {
        c = skyColor(sky_, d.z / len);
        return;
    }
    tHit = f.u * len * inv;
    float rgb[3];
    const double s = 1.0 / (1 << f.level);
    levelColor(pyramid_.level(f.level), f.gx * s, f.gy * s, rgb);
    if (f.weight > 0.0) {
        float p[3];
        levelColor(pyramid_.level(f.level + 1), 0.5 * f.gx * s, 0.5 * f.gy * s, p);
        const float w = static_cast<float>(f.weight);
        for (int i = 0; i < 3; ++i)
            rgb[i] += (p[i] - rgb[i]) * w;
    }
    c = haze(rgb, tHit);
}

// The band march from uStart; with budget >= 0, after that many lines it stops (kind kFar)
// at u, up to which the ray is clear.
template <bool kMajorX>
FarMarch::FarHit FarMarch::marchLinearFar(const ColumnContext& cc, int sgn, double rn, double rz,
                                          double hs, double uStart, long budget,
                                          std::uint64_t& steps) const {
    FarHit out;
    out.u = uStart;
    if (!(hs > 0.0)) return out;
    const MapView& mv = *cc.mv;
    const double em = kMajorX ? cc.eg.gx : cc.eg.gy, en = kMajorX ? cc.eg.gy : cc.eg.gx;
    const double dzr = rz * mv.invScale;
    const bool rising = dzr >= 0.0;
    int k = 0;
    double dk = cc.d0;
    while (k < topLevel_ && uStart * hs >= 2.0 * dk) {
        ++k;
        dk *= 2.0;
    }
    double u = uStart;
    std::uint64_t count = 0;
    for (;;) {
        const PyramidLevel& l = pyramid_.level(k);
        const PyramidLevel* p = k < topLevel_ ? &pyramid_.level(k + 1) : nullptr;
        const double size = static_cast<double>(1 << k), invSize = 1.0 / size;
        const double uEnd = p ? 2.0 * dk / hs : std::numeric_limits<double>::infinity();
        const int majorCount = kMajorX ? l.width : l.height;
        const int minorCount = kMajorX ? l.height : l.width;
        // The first line of this level at or after u.
        const double gm = (em + sgn * u) * invSize;
        long line = sgn > 0 ? -floorToLong(-gm) : floorToLong(gm);
        double ul = ((line * size) - em) * sgn;
        double n = (en + rn * ul) * invSize;
        auto surface = [&](long ln, double nn, double uu) {
            const double hk = lineSample<kMajorX>(l, ln, nn);
            if (!p) return std::pair{hk, 0.0};
            const double w = std::clamp(uu * hs / dk - 1.0, 0.0, 1.0);
            if (w == 0.0) return std::pair{hk, 0.0};
            const double hp = levelSurface<kMajorX>(*p, 0.5 * ln, 0.5 * nn);
            return std::pair{hk + w * (hp - hk), w};
        };
        double zr = cc.eg.zRaw + dzr * ul;
        double above = 0.0, weight = 0.0, uA = ul - size;
        bool started = false, first = true;
        if (u < ul && line >= 0 && line <= majorCount - 1) {
            // Node A is the start itself (inside the map), on the blended surface there.
            const double gmu = (em + sgn * u) * invSize, gnu = (en + rn * u) * invSize;
            if (gmu >= 0.0 && gmu <= majorCount - 1.0 && gnu >= 0.0 && gnu <= minorCount - 1.0) {
                double h = levelSurface<kMajorX>(l, gmu, gnu), w = 0.0;
                if (p) {
                    w = std::clamp(u * hs / dk - 1.0, 0.0, 1.0);
                    if (w > 0.0) h += w * (levelSurface<kMajorX>(*p, 0.5 * gmu, 0.5 * gnu) - h);
                }
                above = cc.eg.zRaw + dzr * u - h;
                weight = w;
                uA = u;
                started = true;
                first = false;
                if (above <= 0.0) {
                    steps += count + 1;
                    out.kind = ColumnMarch::kHit;
                    out.u = u;
                    out.level = k;
                    out.weight = w;
                    const double gmHit = em + sgn * u, gnHit = en + rn * u;
                    out.gx = kMajorX ? gmHit : gnHit;
                    out.gy = kMajorX ? gnHit : gmHit;
                    return out;
                }
            }
        }
        // Steps are skipped where the ray passes over the max-height nodes that bound this
        // band's two levels (node level k + 1, or k at the top band).
        const int j = std::max(p ? k + 1 : k, 1);
        const bool skip = j < pyramid_.nodeLevelCount();
        const int shift = j - k;
        const int lastNm = skip ? (kMajorX ? pyramid_.nodesX(j) : pyramid_.nodesY(j)) - 1 : 0;
        const int lastNn = skip ? (kMajorX ? pyramid_.nodesY(j) : pyramid_.nodesX(j)) - 1 : 0;
        for (;;) {
            ++count;
            if (budget >= 0 && static_cast<long>(count) > budget && !first) {
                // Clear up to the previous line.
                steps += count;
                out.kind = ColumnMarch::kFar;
                out.u = std::max(u, ul - size);
                return out;
            }
            if (line < 0 || line > majorCount - 1 || !(n >= 0.0) || n > minorCount - 1.0) {
                steps += count;
                out.kind = ColumnMarch::kStop;
                out.u = ul;
                return out;
            }
            if (rising && zr > mv.maxRaw) {
                steps += count;
                out.kind = ColumnMarch::kAbove;
                out.u = ul;
                return out;
            }
            if (skip && !first) {
                // The piece of ray since the previous line, against the nodes under it.
                const double zLow = rising ? zr - dzr * size : zr;
                const double nPrev = n - rn;
                const int cm = static_cast<int>(sgn > 0 ? line - 1 : line) >> shift;
                const int na = std::min(static_cast<int>(std::min(n, nPrev)) >> shift, lastNn);
                const int nb = std::min(static_cast<int>(std::max(n, nPrev)) >> shift, lastNn);
                const int nm = std::min(cm, lastNm);
                int bound = 0;
                for (int c = std::max(na, 0); c <= nb; ++c)
                    bound = std::max<int>(bound, kMajorX ? pyramid_.nodeMaxRaw(j, nm, c)
                                                         : pyramid_.nodeMaxRaw(j, c, nm));
                if (zLow > bound) {
                    started = false;
                    if (ul >= uEnd) break;
                    line += sgn;
                    ul += size;
                    n += rn;
                    zr += dzr * size;
                    continue;
                }
                if (!started) {
                    // The previous line, passed over without a sample: the ray is above it.
                    const auto [ha, wa] = surface(line - sgn, nPrev, ul - size);
                    above = zr - dzr * size - ha;
                    weight = wa;
                    uA = ul - size;
                    started = true;
                }
            }
            first = false;
            const auto [h, w] = surface(line, n, ul);
            const double diff = zr - h;
            if (diff <= 0.0) {
                const double f = started ? above / (above - diff) : 1.0;
                // Between the previous node (a line, or the start) and this line.
                steps += count;
                out.kind = ColumnMarch::kHit;
                out.u = started ? uA + f * (ul - uA) : ul;
                out.level = k;
                out.weight = started ? weight + f * (w - weight) : w;
                const double gmHit = em + sgn * out.u, gnHit = en + rn * out.u;
                out.gx = kMajorX ? gmHit : gnHit;
                out.gy = kMajorX ? gnHit : gmHit;
                return out;
            }
            if (ul >= uEnd) break;
            above = diff;
            weight = w;
            uA = ul;
            started = true;
            line += sgn;
            ul += size;
            n += rn;
            zr += dzr * size;
        }
        u = ul;
        ++k;
        dk *= 2.0;
    }
}

}  // namespace ig::fast
