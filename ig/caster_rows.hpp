// The multiresolution caster's row batches (fast_column.hpp, RowsOutcome): N consecutive rays
// of one column cast together on N vector lanes, one template over the lane vector V (four or
// eight doubles). Every operation is the one-ray path's (linearRay), in the same order and
// precision, so every width gives the image rays one by one give.
//
// Included only by the row-batch objects, one per instruction set (caster_rows_avx2.cpp,
// caster_rows_avx512.cpp, each compiled with its instruction set's flags) and their scalar
// twins' (caster_rows_portable.cpp: the same template on portable lanes, compiled for none),
// after the lane primitives for V (caster_lanes.hpp and the object's own). The template lives in an
// anonymous namespace: its instances have internal linkage, so no other object can be handed them.
// What it calls from the rest of the caster is out of line, compiled for the baseline (climbsClear,
// FarMarch::linearFar); the shared inline code it uses (skipNodes, applyHaze, skyColor,
// std::min ...) is inlined, never emitted here (the objects are compiled at -O1 at least, and
// scripts/isa-symbols.sh checks that they define no weak symbol). See docs/design/multires.md,
// "One object per instruction set".
#pragma once

#include "ig/caster_lanes.hpp"
#include "ig/coherence.hpp"
#include "ig/far_march.hpp"
#include "ig/fast_column.hpp"
#include "ig/level0_march.hpp"
#include "ig/node_skip.hpp"
#include "ig/shading.hpp"

#include <cstddef>
#include <cstdint>
#include <cstring>
#include <limits>

namespace ig::fast {
namespace {

template <class V>
class RowBatches {
  public:
    using M = decltype(V{} < V{});
    static constexpr int kN = sizeof(V) / sizeof(double);

    // RowKernel::run and RowKernel::cast.
    static int run(const RowsCaster& rc, const ColumnContext& cc, ColumnState& st, int y,
                   int batches, Rgb8* colorOut, float* depthOut, std::size_t w, RowsOutcome& last) {
        return RowBatches(rc).runRows(cc, st, y, batches, colorOut, depthOut, w, last);
    }
    static RowsOutcome cast(const RowsCaster& rc, const ColumnContext& cc, ColumnState& st,
                            const double* rowY, Rgb8* c, double* tHit) {
        return RowBatches(rc).linearRows(cc, st, rowY, c, tHit);
    }

  private:
    explicit RowBatches(const RowsCaster& rc)
        : sky_(*rc.sky), pyramid_(rc.pyramid), skipNodes_(rc.skipNodes), far_(*rc.far) {}

    // The shared haze and quantization (shading.hpp).
    [[gnu::always_inline]] Rgb8 haze(float rgb[3], double t) const {
        applyHaze(sky_, rgb, t);
        return quantizeColor(rgb);
    }

    // Rays through image rows rowY[0 .. N) (bottom to top); see RowsOutcome.
    RowsOutcome linearRows(const ColumnContext& cc, ColumnState& st, const double* rowY, Rgb8* c,
                           double* tHit) const {
        V yy;
        std::memcpy(&yy, rowY, sizeof yy);
        return linearRowsAt(cc, st, yy, c, tHit);
    }
    // Batches of N rows down from image row y (one ray per pixel) while they go and at most
    // `batches` of them, each batch's pixels written to the column (colour and depth, row stride
    // w). The row the next batch would start at; `last` says why the run ended (kDone: the batch
    // limit or fewer than N rows left).
    int runRows(const ColumnContext& cc, ColumnState& st, int y, int batches, Rgb8* colorOut,
                float* depthOut, std::size_t w, RowsOutcome& last) const {
        // (y + 0.5) - l is y - l + 0.5 exactly.
        static constexpr double kLane[8] = {0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0};
        V lane;
        std::memcpy(&lane, kLane, sizeof lane);
        last = RowsOutcome::kDone;
        for (; batches > 0 && y >= kN - 1; --batches) {
            Rgb8 c[kN];
            double tHit[kN];
            last = linearRowsAt(cc, st, (static_cast<double>(y) + 0.5) - lane, c, tHit);
            if (last != RowsOutcome::kDone) break;
            for (int l = 0; l < kN; ++l) {
                const std::size_t idx = static_cast<std::size_t>(y - l) * w;
                colorOut[idx] = c[l];
                depthOut[idx] = tHit[l] >= 0.0 ? static_cast<float>(tHit[l]) : kSkyDepth;
            }
            y -= kN;
        }
        return y;
    }
    [[gnu::always_inline]] RowsOutcome linearRowsAt(const ColumnContext& cc, ColumnState& st, V yy,
                                                    Rgb8* c, double* tHit) const {
        constexpr int kAll = (1 << kN) - 1;
        const V dx = cc.base.x + yy * cc.down.x, dy = cc.base.y + yy * cc.down.y,
                dz = cc.base.z + yy * cc.down.z;
        const V gx = dx * cc.invSx, gy = dy * cc.invSy;
        const int mx = vmask((gx < 0.0 ? -gx : gx) >= (gy < 0.0 ? -gy : gy));
        if (mx != (st.prevMajorX ? kAll : 0)) return RowsOutcome::kOther;
        return st.prevMajorX ? linearRowsAxis<true>(cc, st, dx, dy, dz, gx, gy, c, tHit)
                             : linearRowsAxis<false>(cc, st, dx, dy, dz, gx, gy, c, tHit);
    }

    // One step of the N lanes (LaneStep: from major line A to B; B's sample sB; up: rn > 0;
    // invRn = 1 / rn): the active lanes under the surface at B get their hits at step k, between
    // A, the node where the track crosses a minor grid line if it does (marchLinear's
    // minorNode) and B. False when no lane is left active.
    [[gnu::always_inline]] static bool stepHits(M& active, const LaneStep<V>& step,
                                                const LineN<V>& sB, M up, V invRn, V& uHit,
                                                int& hitMask, std::uint64_t& steps) {
        const V iA = step.iA, dEdgeA = step.dEdgeA, nA = step.nA, zB = step.zB, above = step.above,
                below = step.below;
        const double uA = step.uA, uB = step.uB;
        const long k = step.k;
        const M hitNow = active & (below <= 0.0);
        const int hits = vmask(hitNow);
        if (hits == 0) return true;
        V at = uA + (uB - uA) * (above / (above - below));
        const M cross = hitNow & (sB.i != iA);
        if (vmask(cross) != 0) {
            const V dB = zB - (up ? sB.h0 : sB.h1);
            const V c = up ? sB.i : iA;
            const V sP = (c - nA) * invRn;
            const V diffP = dEdgeA + sP * (dB - dEdgeA);
            const V uP = uA + sP * (uB - uA);
            const V first = uA + (uP - uA) * (above / (above - diffP));
            const V second = uP + (uB - uP) * (diffP / (diffP - below));
            at = cross ? (diffP <= 0.0 ? first : second) : at;
        }
        uHit = hitNow ? at : uHit;
        hitMask |= hits;
        steps += static_cast<std::uint64_t>(__builtin_popcount(hits)) *
                 static_cast<std::uint64_t>(k + 1);
        active = active & ~hitNow;
        return vmask(active) != 0;
    }

    template <bool kMajorX>
    [[gnu::always_inline]] RowsOutcome linearRowsAxis(const ColumnContext& cc, ColumnState& st,
                                                      V dx, V dy, V dz, V gx, V gy, Rgb8* c,
                                                      double* tHit) const {
        constexpr int kLanes = kN, kAll = (1 << kLanes) - 1, kTop = kLanes - 1;
        const MapView& mv = *cc.mv;
        const V zero = V{} + 0.0;
        const V gm = kMajorX ? gx : gy, gn = kMajorX ? gy : gx;
        const int sgn = st.prevSgn;
        const V len = vsqrt(dx * dx + dy * dy + dz * dz);
        const V absGm = gm < 0.0 ? -gm : gm;
        if (vmask(sgn > 0 ? gm > 0.0 : gm <= 0.0) != kAll) return RowsOutcome::kOther;
        if (vmask(absGm > 1e-9 * len) != kAll) return RowsOutcome::kOther;
        const V inv = 1.0 / absGm;
        const V rn = gn * inv, rz = dz * inv;
        // Each lane against the ray below the batch.
        {
            const double sMinor = kMajorX ? cc.spacingY : cc.spacingX;
            const V dRn = rn - st.prevRn;
            const V gap = dRn < 0.0 ? -dRn : dRn, climb = rz - st.prevRz;
            M clearLanes;
            testClimb(climb, cc.maxSlope, sMinor, gap, clearLanes);
            const int clear = vmask(clearLanes);
            if (clear != kAll) {
                // The local bounds for the lanes the map's bound did not clear.
                for (int l = 0; l < kLanes; ++l) {
                    if (!((clear >> l) & 1) && !climbsClear(cc, st, kMajorX, rn[l], rz[l]))
                        return RowsOutcome::kOther;
                }
            }
        }
        const double em = kMajorX ? cc.eg.gx : cc.eg.gy, en = kMajorX ? cc.eg.gy : cc.eg.gx;
        const int w = mv.width;
        const int majorCount = kMajorX ? w : mv.height, minorCount = kMajorX ? mv.height : w;
        const double uStart = st.prevU;
        const double gm0 = em + sgn * uStart;
        const long m = sgn > 0 ? floorToLong(gm0) : -floorToLong(-gm0);
        const double u = (m - em) * sgn;
        // Sky where the ray below climbed over the map's highest point (these climb faster) or,
        // from inside the map, left it through the far side (these leave where it did).
        const bool pastEnd = u >= 0.0 && (sgn > 0 ? m > majorCount - 1 : m < 0) && cc.eg.inside;
        if (st.prevAbove || pastEnd) {
            for (int l = 0; l < kLanes; ++l) {
                tHit[l] = -1.0;
                c[l] = skyColor(sky_, dz[l] / len[l]);
            }
            st.prevRn = rn[kTop];
            st.prevRz = rz[kTop];
            return RowsOutcome::kDone;
        }
        if (!(u >= 0.0) || m < 0 || m > majorCount - 1) return RowsOutcome::kOther;
        const double lastN = minorCount - 1.0;
        const V nA = en + rn * u;
        if (vmask(nA >= 0.0 && nA <= lastN) != kAll) return RowsOutcome::kOther;
        const V lastCell = zero + (minorCount - 2.0);
        const V dzr = rz * mv.invScale;
        const M rising = dzr >= 0.0;
        V zA = cc.eg.zRaw + dzr * u;
        const LineN<V> s0 = sampleLine<kMajorX>(mv, m, nA, lastN);
        V above = zA - s0.h;
        // Line A's cell, its sample on the side the track moves to, its minor coordinate.
        const M up = rn > 0.0;
        V iA = s0.i, dEdgeA = zA - (up ? s0.h1 : s0.h0), nLine = nA;
        const V invRn = 1.0 / rn;
        const double majorSteps = sgn > 0 ? majorCount - 1.0 - m : static_cast<double>(m);
        V nearSteps = zero + 1099511627776.0;  // 2^40
        if (cc.multires) {
            const V uNear = cc.d0 / (vsqrt(dx * dx + dy * dy) * inv);
            nearSteps = vmax(zero, -vfloor(u - uNear));
        }
        // Past the level-0 distance already: the rows go one by one (coherently, linearFar).
        if (vmask(nearSteps <= 0.0) != 0) return RowsOutcome::kFar;
        const V total = vmin(nearSteps, zero + majorSteps);
        // Per lane: the hit (uHit >= 0) or where it stopped (uEnd) and how; set where a lane ends
        // other than by a hit (endedMask), the rest only where some lane did not hit.
        enum : int { kLaneHit, kLaneStop, kLaneAbove, kLaneFar };
        int kind[kLanes];
        double uEnd[kLanes];
        int endedMask = 0;
        std::uint64_t steps = 0;
        V uHit = zero - 1.0;
        M active = above > 0.0;
        // The lanes that hit: under the surface at the start line, or in the loops below.
        int hitMask = kAll & ~vmask(active);
        if (hitMask) {
            for (int l = 0; l < kLanes; ++l) {
                if ((hitMask >> l) & 1) {
                    uHit[l] = u;
                    ++steps;
                }
            }
        }
        double uA = u;
        long k = 0;
        // Steps no lane can end on but by a hit (with a margin for rounding): neither past its
        // step count, nor off a minor side, nor over the map's highest point while climbing.
        const V absRn = rn < 0.0 ? -rn : rn;
        const V toSide = rn > 0.0 ? lastN - nA : nA;
        const V huge = zero + 1e300;
        // (1e-6 of a cell kept from the side, beyond rounding, where the track is nearly along
        // the major axis: the loop's samples must not go below the first row or column.)
        const V sideSteps = absRn > 0.0 ? (toSide - 1e-6) / absRn - 2.0 : huge;
        const V topSteps = dzr > 0.0        ? (mv.maxRaw - cc.eg.zRaw) / dzr - u - 2.0
                           : zA > mv.maxRaw ? zero
                                            : huge;
        const V bound = vmin(total, vmin(sideSteps, topSteps));
        double safe = bound[0];
        for (int l = 1; l < kLanes; ++l)
            safe = std::min(safe, bound[l]);
        const long kSafe = safe > 0.0 ? static_cast<long>(safe) : 0;
        // Line B as a double (exact: an integer below 2^31), and u there.
        const double sgnD = sgn;
        double lineD = static_cast<double>(m) + sgnD;
        long lineB = m + sgn;
        // Where the batch has gone some lines without ending, it tries to pass whole max-height
        // nodes at a time (rays grazing far over the terrain would otherwise sample every line).
        long tryAt = skipNodes_ ? kSkipAfter : kSafe, retry = kSkipRetry;
        int skipLevel = kSkipFirstLevel;
        for (; k < kSafe; ++k, lineD += sgnD, lineB += sgn) {
            if (k >= tryAt) {
                // The active lanes' fan: its lowest height slope and its minor slopes.
                const V inf = zero + std::numeric_limits<double>::infinity();
                const V dzrA = active ? dzr : inf, rnLo = active ? rn : inf,
                        rnHi = active ? rn : -inf;
                double lowSlope = dzrA[0], lo = rnLo[0], hi = rnHi[0];
                for (int l = 1; l < kLanes; ++l) {
                    lowSlope = std::min(lowSlope, dzrA[l]);
                    lo = std::min(lo, rnLo[l]);
                    hi = std::max(hi, rnHi[l]);
                }
                const long lines =
                    skipNodes<kMajorX>(*pyramid_, skipLevel, lineB - sgn, sgn, kSafe - k,
                                       RayFan{em, en, cc.eg.zRaw, lowSlope, lo, hi});
                if (lines > 0) {
                    // Line A moves on by `lines`: the loop's values there, as it would have them.
                    k += lines;
                    lineB += sgn * lines;
                    lineD = static_cast<double>(lineB);
                    const int act = __builtin_popcount(vmask(active));
                    steps += static_cast<std::uint64_t>(act) -
                             static_cast<std::uint64_t>(act) * static_cast<std::uint64_t>(lines);
                    uA = (static_cast<double>(lineB - sgn) - em) * sgnD;
                    nLine = en + rn * uA;
                    zA = cc.eg.zRaw + dzr * uA;
                    const LineN<V> sA = sampleLine<kMajorX>(mv, lineB - sgn, nLine, lastN);
                    above = zA - sA.h;
                    iA = sA.i;
                    dEdgeA = zA - (up ? sA.h1 : sA.h0);
                    if (k >= kSafe) break;
                    retry = kSkipRetry;
                } else {
                    tryAt = k + retry;
                    retry *= 2;
                }
            }
            const double uB = (lineD - em) * sgnD;
            const V nB = en + rn * uB;
            const V zB = cc.eg.zRaw + dzr * uB;
            const LineN<V> sB = sampleLine<kMajorX>(mv, lineB, nB, lastN);
            const V below = zB - sB.h;
            if (!stepHits(active, LaneStep<V>{iA, dEdgeA, nLine, zB, above, below, uA, uB, k}, sB,
                          up, invRn, uHit, hitMask, steps)) {
                break;
            }
            above = below;
            uA = uB;
            zA = zB;
            nLine = nB;
            iA = sB.i;
            dEdgeA = zB - (up ? sB.h1 : sB.h0);
        }
        for (; vmask(active) != 0; ++k, lineD += sgnD, lineB += sgn) {
            const double kd = static_cast<double>(k);
            const M exhausted = active && kd >= total;
            const M far = exhausted && total == nearSteps && nearSteps < majorSteps + 1.0;
            const double uB = (lineD - em) * sgnD;
            const V nB = en + rn * uB;
            const M leave = active && !exhausted && !(nB >= 0.0 && nB <= lastN);
            const M over = active && !exhausted && !leave && rising && zA > mv.maxRaw;
            const int ended = vmask(exhausted || leave || over);
            if (ended) {
                endedMask |= ended;
                for (int l = 0; l < kLanes; ++l) {
                    if (!((ended >> l) & 1)) continue;
                    kind[l] = far[l] ? kLaneFar : over[l] ? kLaneAbove : kLaneStop;
                    uEnd[l] = std::max(uA, uStart);
                    steps += static_cast<std::uint64_t>(exhausted[l] ? k : k + 1);
                }
                active = active && !(exhausted || leave || over);
                if (vmask(active) == 0) break;
            }
            const V zB = cc.eg.zRaw + dzr * uB;
            const LineN<V> sB =
                sampleLine<kMajorX>(mv, lineB, vmax(zero, vmin(nB, zero + lastN)), lastN);
            const V below = zB - sB.h;
            stepHits(active, LaneStep<V>{iA, dEdgeA, nLine, zB, above, below, uA, uB, k}, sB, up,
                     invRn, uHit, hitMask, steps);
            above = below;
            uA = uB;
            zA = zB;
            nLine = nB;
            iA = sB.i;
            dEdgeA = zB - (up ? sB.h1 : sB.h0);
        }
        // Colours of the hits.
        const V pm = em + sgn * uHit, pn = en + rn * uHit;
        const M hitLane = uHit >= 0.0;
        const V cm = hitLane ? vmax(zero, vmin(vfloor(pm), zero + (majorCount - 2.0))) : zero;
        const V cn = hitLane ? vmax(zero, vmin(vfloor(pn), lastCell)) : zero;
        const V fm = hitLane ? pm - cm : zero, fn = hitLane ? pn - cn : zero;
        V rgb[3];
        cellColors(mv, kMajorX ? cm : cn, kMajorX ? cn : cm, kMajorX ? fm : fn, kMajorX ? fn : fm,
                   rgb);
        const V t = uHit * len * inv;
        if (vmask(hitLane) == kAll && !hazeInKernel(sky_)) {
            // All lanes hit, no haze drawn here (the common case): quantize on the lanes, as
            // quantizeColor().
            quantizeLanes(rgb, c);
            std::memcpy(tHit, &t, sizeof t);
            st.prevU = uHit[kTop];
            st.prevAbove = false;
            st.prevRn = rn[kTop];
            st.prevRz = rz[kTop];
            st.steps += steps;
            return RowsOutcome::kDone;
        }
        for (int l = 0; l < kLanes; ++l) {
            if ((hitMask >> l) & 1) {
                kind[l] = kLaneHit;
            } else if (!((endedMask >> l) & 1)) {
                kind[l] = kLaneStop;
                uEnd[l] = uStart;
            }
            tHit[l] = -1.0;
            if (kind[l] == kLaneHit) {
                tHit[l] = t[l];
                float f[3] = {static_cast<float>(rgb[0][l]), static_cast<float>(rgb[1][l]),
                              static_cast<float>(rgb[2][l])};
                c[l] = haze(f, tHit[l]);
                uEnd[l] = uHit[l];
            } else if (kind[l] == kLaneFar) {
                // From where the lane below stopped when it climbs clear of that one too (with
                // the map's slope bound): the far march stays coherent.
                double from = uEnd[l];
                if (l > 0 && kind[l - 1] != kLaneStop && uEnd[l - 1] > from) {
                    const double sMinor = kMajorX ? cc.spacingY : cc.spacingX;
                    if (climbsClearOf(rz[l] - rz[l - 1], cc.maxSlope, sMinor,
                                      std::abs(rn[l] - rn[l - 1])))
                        from = uEnd[l - 1];
                }
                bool overTop = false;
                far_.linearFar(cc, dx[l], dy[l], dz[l], len[l], inv[l], kMajorX, sgn, rn[l], rz[l],
                               from, uEnd[l], overTop, steps, c[l], tHit[l]);
                if (overTop) kind[l] = kLaneAbove;
            } else {
                c[l] = skyColor(sky_, dz[l] / len[l]);
            }
        }
        st.prevU = uEnd[kTop];
        st.prevAbove = kind[kTop] == kLaneAbove;
        st.prevRn = rn[kTop];
        st.prevRz = rz[kTop];
        st.steps += steps;
        return RowsOutcome::kDone;
    }

    const SkyModel& sky_;
    const TerrainPyramid* pyramid_;
    bool skipNodes_;
    const FarMarch& far_;
};

}  // namespace
}  // namespace ig::fast
