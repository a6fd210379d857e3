// The fast caster's four-column packets (the single level's avx2 kernel, caster_fast.hpp).
//
// Four adjacent columns cast together, row by row, with AVX2: the rays' set-up, the
// coherent march's set-up, the exact solve of the steps they reach and the colour run on
// four lanes; each lane's bound scan is its own scalar loop. A row is cast this way when all
// four rays are coherent on the same major axis and direction. A lane that ends without a
// hit (past the map's far edge, over its highest point) ends here too, one that reaches
// the level-0 distance goes on into the multiresolution march; one that leaves through a
// minor side of the map is cast again from its unchanged state by castRay, as are the rows
// where some ray is not coherent (bottom ray, restart, sky above the map's top). Every
// operation is the scalar path's, in the same order and precision (no fused multiply-add),
// so the image is bit for bit the one column at a time gives.
//
// The AVX2 code carries per-function target attributes: this object is compiled for the
// baseline (its inline helpers stay baseline code), and its AVX2 functions run only where
// chooseKernel found AVX2.
#include "ig/caster_fast.hpp"
#include "ig/coherence.hpp"

#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>

namespace ig::fast {

#if VIG_CASTER_PACKETS

namespace {

// One lane's bound scan (marchCoherent's inner loop) from step k on, and how it ended.
struct LaneScan {
    std::int64_t n, dn;  // minor coordinate at the step's start (32.32) and per step
    double zLow, dzr;    // the step's lowest ray height and its change per step (raw)
    std::ptrdiff_t ia;   // cell-max index of the step's first cell
    int ca;              // its minor cell
    std::int64_t k, total;
    // Of the reached step: its second cell and the next step's minor coordinate.
    int cb;
    std::ptrdiff_t ib;
    std::int64_t next;
};

enum class ScanEnd { kReach, kLeave, kExhausted, kClimb };

template <bool kMajorX>
[[gnu::always_inline]] inline ScanEnd scanLane(const MapView& mv, LaneScan& q,
                                               std::int64_t minorLimit, int lastMinorCell,
                                               std::ptrdiff_t minorStride,
                                               std::ptrdiff_t majorStep) {
    const std::uint16_t* __restrict__ cellMax = mv.cellMax;
    const bool rising = q.dzr >= 0.0;
    std::int64_t n = q.n, k = q.k;
    std::ptrdiff_t ia = q.ia;
    int ca = q.ca;
    double zLow = q.zLow;
    ScanEnd end = ScanEnd::kExhausted;
    for (; k < q.total; ++k) {
        const std::int64_t next = n + q.dn;
        if (static_cast<std::uint64_t>(next) > static_cast<std::uint64_t>(minorLimit)) {
            end = ScanEnd::kLeave;
            break;
        }
        const int cb = std::min(static_cast<int>(next >> 32), lastMinorCell);
        const std::ptrdiff_t ib = ia + (cb - ca) * minorStride;
        if (zLow <= std::max(cellMax[ia], cellMax[ib])) {
            q.cb = cb;
            q.ib = ib;
            q.next = next;
            end = ScanEnd::kReach;
            break;
        }
        if (rising && zLow > mv.maxRaw) {
            end = ScanEnd::kClimb;
            break;
        }
        n = next;
        ca = cb;
        ia = ib + majorStep;
        zLow += q.dzr;
    }
    q.n = n;
    q.k = k;
    q.ia = ia;
    q.ca = ca;
    q.zLow = zLow;
    return end;
}

// roundToInt64 on four lanes, as an integer-valued double (exact below 2^53).
[[gnu::always_inline]] VIG_CASTER_AVX2 inline V4 vroundAway(V4 v) {
    const V4 h = v >= 0.0 ? v + 0.5 : v - 0.5;
    return reinterpret_cast<V4>(
        _mm256_round_pd(reinterpret_cast<__m256d>(h), _MM_FROUND_TO_ZERO | _MM_FROUND_NO_EXC));
}

// Two adjacent 16-bit samples at idx and idx + 1, four lanes.
[[gnu::always_inline]] VIG_CASTER_AVX2 inline void gatherPair(const std::uint16_t* base, V4 idx,
                                                              V4& first, V4& second) {
    const __m128i g = gather32<2>(base, idx);
    first = toV4(_mm_and_si128(g, _mm_set1_epi32(0xFFFF)));
    second = toV4(_mm_srli_epi32(g, 16));
}

// solveBilinear on four lanes, the same operations in the same order.
[[gnu::always_inline]] VIG_CASTER_AVX2 inline V4 solveBilinear4(V4 h00, V4 h10, V4 h01, V4 h11,
                                                                V4 ua, V4 va, V4 du, V4 dv, V4 za,
                                                                V4 dz, V4 len) {
    const V4 a = h10 - h00, b = h01 - h00, c = h00 - h10 - h01 + h11;
    const V4 C = za - (h00 + a * ua + b * va + c * ua * va);
    const V4 B = dz - (a * du + b * dv + c * (ua * dv + va * du));
    const V4 A = -c * du * dv;
    const V4 disc = B * B - 4.0 * A * C;
    const V4 zero = V4{} + 0.0;
    const V4 sq = vsqrt(vmax(disc, zero));
    // One division: C / (0.5 * (sq - B)) where B < 0, (-0.5 * (B + sq)) / A elsewhere.
    const M4 negB = B < 0.0;
    const V4 root0 = (negB ? C : -0.5 * (B + sq)) / (negB ? 0.5 * (sq - B) : A);
    V4 root = zero - 1.0;
    root = disc >= 0.0 && (negB || A < 0.0) ? root0 : root;
    const V4 endHit = C + B * len + A * len * len <= 0.0 ? len : zero - 1.0;
    root = root >= 0.0 && root <= len ? root : endHit;
    return C <= 0.0 ? zero : root;
}

// What a lane's march is about.
struct PacketRay {
    V4 sgn, rn, rzr;  // major sign, minor cells and raw height per major unit
    double ezr;       // eye height, raw units
};

// StepSolver::piece on the lanes in `active`: the piece [s0, s1] of the step from major
// line m (major cell mc) in minor cell cn; sets `got` and the hit (u, cell, local
// coordinates) of the lanes whose piece meets the surface.
template <bool kMajorX>
[[gnu::always_inline]] VIG_CASTER_AVX2 inline void piece4(const MapView& mv, const PacketRay& ray,
                                                          M4 active, M4 ownBound, V4 m, V4 mc,
                                                          V4 cn, V4 n, V4 u, V4 s0, V4 s1, M4& got,
                                                          V4& outU, V4& outCx, V4& outCy, V4& outFx,
                                                          V4& outFy) {
    active = active && s0 < s1;
    if (!vmask(active)) return;
    const V4 cx = kMajorX ? mc : cn, cy = kMajorX ? cn : mc;
    const V4 zero = V4{} + 0.0;
    const V4 cell = active ? cy * static_cast<double>(mv.width) + cx : zero;
    V4 h00, h10, h01, h11;
    gatherPair(mv.heights, cell, h00, h10);
    gatherPair(mv.heights, cell + static_cast<double>(mv.width), h01, h11);
    const V4 za = ray.ezr + ray.rzr * (u + s0);
    if (vmask(ownBound)) {
        const V4 bound = toV4(_mm_and_si128(
            gather32<2>(mv.cellMax, active ? cy * static_cast<double>(mv.width - 1) + cx : zero),
            _mm_set1_epi32(0xFFFF)));
        const V4 zLow = ray.rzr >= 0.0 ? za : za + ray.rzr * (s1 - s0);
        active = active && !(ownBound && zLow > bound);
    }
    const V4 nD = n * (1.0 / 4294967296.0);
    const V4 majorLocal = m - mc;
    const V4 am = majorLocal + ray.sgn * s0, an = nD + ray.rn * s0 - cn;
    const V4 r =
        kMajorX ? solveBilinear4(h00, h10, h01, h11, am, an, ray.sgn, ray.rn, za, ray.rzr, s1 - s0)
                : solveBilinear4(h00, h10, h01, h11, an, am, ray.rn, ray.sgn, za, ray.rzr, s1 - s0);
    const M4 hit = active && r >= 0.0;
    const V4 sh = s0 + r;
    const V4 fm = majorLocal + ray.sgn * sh, fn = nD + ray.rn * sh - cn;
    outU = hit ? u + sh : outU;
    outCx = hit ? cx : outCx;
    outCy = hit ? cy : outCy;
    outFx = hit ? (kMajorX ? fm : fn) : outFx;
    outFy = hit ? (kMajorX ? fn : fm) : outFy;
    got = got || hit;
}

}  // namespace

void FastCaster::renderPacketUnit(const MapView& mv, const Camera& camera, double d0, int unit,
                                  RenderedFrame& frame, UnitCounters& counters) const {
    const int w = camera.intrinsics().width;
    const int x0 = 4 * unit;
    if (x0 + 4 <= w) {
        renderPacket(mv, camera, d0, x0, frame, counters);
    } else {
        for (int x = x0; x < w; ++x)
            renderColumn(mv, camera, d0, x, frame, counters);
    }
}

template <bool kMajorX>
[[gnu::always_inline]] inline VIG_CASTER_AVX2 void FastCaster::packetRow(
    const ColumnContext* cc, ColumnState* st, V4 dx, V4 dy, V4 dz, V4 len, int sgnI, Rgb8* c,
    double* tHit, bool* done) const {
    const MapView& mv = *cc[0].mv;
    const EyeGrid& eg = cc[0].eg;
    const V4 zero = V4{} + 0.0, one = V4{} + 1.0;
    const V4 sgn = zero + static_cast<double>(sgnI);
    const V4 gx = dx * cc[0].invSx, gy = dy * cc[0].invSy;
    const V4 gm = kMajorX ? gx : gy, gn = kMajorX ? gy : gx;
    const V4 inv = 1.0 / (gm < 0.0 ? -gm : gm);
    const V4 rn = gn * inv, rz = dz * inv;
    V4 prevRn, prevRz, prevU;
    for (int l = 0; l < 4; ++l) {
        prevRn[l] = st[l].prevRn;
        prevRz[l] = st[l].prevRz;
        prevU[l] = st[l].prevU;
        done[l] = false;
    }
    const V4 dRn = rn - prevRn;
    const double sMinor = kMajorX ? cc[0].spacingY : cc[0].spacingX;
    M4 coherent;
    testClimb(V4(rz - prevRz), cc[0].maxSlope, sMinor, V4(dRn < 0.0 ? -dRn : dRn), coherent);
    if (vmask(coherent) != 15) {
        for (int l = 0; l < 4; ++l)
            coherent[l] = climbsClear(cc[l], st[l], kMajorX, rn[l], rz[l]) ? -1 : 0;
    }
    V4 uNear = zero + std::numeric_limits<double>::infinity();
    if (cc[0].multires) uNear = cc[0].d0 / (vsqrt(dx * dx + dy * dy) * inv);
    // marchCoherent's set-up.
    const int majorCount = kMajorX ? mv.width : mv.height;
    const int minorCount = kMajorX ? mv.height : mv.width;
    const double lastMinorCell = minorCount - 2;
    const double em = kMajorX ? eg.gx : eg.gy, en = kMajorX ? eg.gy : eg.gx;
    const V4 gm0 = em + sgn * prevU;
    const V4 fl = vfloor(sgnI > 0 ? gm0 : -gm0);
    const V4 m = sgnI > 0 ? fl : -fl;
    const V4 u = (m - em) * sgn;
    constexpr double kFix = 4294967296.0, kInvFix = 1.0 / 4294967296.0;
    V4 n = vroundAway((en + rn * u) * kFix);
    const V4 dn = vroundAway(rn * kFix);
    const double minorLimit = (minorCount - 1.0) * kFix;
    const V4 dzr = rz * mv.invScale;
    const V4 zr = eg.zRaw + dzr * u;
    const M4 ok = coherent && m >= 0.0 && m <= majorCount - 1.0 && n >= 0.0 && n <= minorLimit;
    if (!vmask(ok)) return;
    const V4 majorSteps = sgnI > 0 ? majorCount - 1.0 - m : m;
    const V4 nearSteps = uNear < 1e12 ? vmax(zero, -vfloor(u - uNear)) : zero + 1099511627776.0;
    const V4 total = vmin(majorSteps, nearSteps);
    const M4 far = total == nearSteps && nearSteps < majorSteps + 1.0;
    const V4 mc0 = m + (sgnI > 0 ? 0.0 : -1.0);
    const V4 sBegin0 = prevU - u;
    const V4 zLow = dzr >= 0.0 ? zr : zr + dzr;
    const double stride = mv.width - 1.0;
    const double minorStride = kMajorX ? stride : 1.0;
    const double majorStep = kMajorX ? sgnI : sgnI * stride;
    const V4 ca0 = vmin(vfloor(n * kInvFix), zero + lastMinorCell);
    const V4 ia0 = kMajorX ? ca0 * stride + mc0 : mc0 * stride + ca0;
    const PacketRay ray{sgn, rn, dzr, eg.zRaw};
    M4 failed = !ok, hit = {}, stop = {}, above = {}, farEnd = {};
    V4 endU = zero;  // where a lane that ended without a hit (sky) ended
    V4 hitU = zero, hitCx = zero, hitCy = zero, hitFx = zero, hitFy = zero;
    V4 stepsV = zero;
    // The bound scan runs per lane (scalar loops of a few instructions a step keep the
    // processor busier than masked lock step); the solve of the reached steps on four lanes.
    LaneScan lane[4];
    bool pending[4];
    const int okMask = vmask(ok);
    for (int l = 0; l < 4; ++l) {
        pending[l] = (okMask >> l) & 1;
        lane[l] = LaneScan{static_cast<std::int64_t>(n[l]),
                           static_cast<std::int64_t>(dn[l]),
                           zLow[l],
                           dzr[l],
                           static_cast<std::ptrdiff_t>(ia0[l]),
                           static_cast<int>(ca0[l]),
                           0,
                           static_cast<std::int64_t>(total[l]),
                           0,
                           0,
                           0};
    }
    const auto limit = static_cast<std::int64_t>(minorCount - 1) << 32;
    const auto mStride = static_cast<std::ptrdiff_t>(minorStride);
    const auto mStep = static_cast<std::ptrdiff_t>(majorStep);
    for (;;) {
        M4 parked = {};
        for (int l = 0; l < 4; ++l) {
            if (!pending[l]) continue;
            LaneScan& q = lane[l];
            const ScanEnd e =
                scanLane<kMajorX>(mv, q, limit, static_cast<int>(lastMinorCell), mStride, mStep);
            pending[l] = false;
            if (e == ScanEnd::kReach) {
                parked[l] = -1;
                continue;
            }
            if (e == ScanEnd::kLeave) {
                failed[l] = -1;
            } else if (e == ScanEnd::kExhausted && far[l]) {
                // Reached the level-0 distance: the multiresolution march goes on from there.
                farEnd[l] = -1;
                endU[l] = u[l] + static_cast<double>(q.k);
                stepsV[l] = static_cast<double>(q.k);
            } else {
                endU[l] = u[l] + static_cast<double>(q.k);
                stepsV[l] = static_cast<double>(e == ScanEnd::kClimb ? q.k + 1 : q.k);
                (e == ScanEnd::kClimb ? above : stop)[l] = -1;
            }
        }
        if (!vmask(parked)) break;
        // The exact solve of each parked lane's step (StepSolver::solve).
        V4 k, ns, ca, cb;
        for (int l = 0; l < 4; ++l) {
            k[l] = static_cast<double>(lane[l].k);
            ns[l] = static_cast<double>(lane[l].n);
            ca[l] = lane[l].ca;
            cb[l] = lane[l].cb;
        }
        const V4 mK = m + sgn * k;
        const V4 mcK = mc0 + sgn * k;
        const V4 uK = u + k;
        const V4 sBegin = k == 0.0 ? sBegin0 : zero;
        const M4 split = ca != cb;
        const V4 nD = ns * kInvFix;
        const V4 line = ca < cb ? cb : ca;
        const V4 sSplit = vclamp01((line - nD) / rn);
        M4 got = {};
        piece4<kMajorX>(mv, ray, parked, split, mK, mcK, ca, ns, uK,
                        split ? vmax(sBegin, zero) : sBegin, split ? sSplit : one, got, hitU, hitCx,
                        hitCy, hitFx, hitFy);
        piece4<kMajorX>(mv, ray, parked && split && !got, split, mK, mcK, cb, ns, uK,
                        vmax(sBegin, sSplit), one, got, hitU, hitCx, hitCy, hitFx, hitFy);
        hit = hit || got;
        stepsV = got ? k + 1.0 : stepsV;
        // A lane whose step held no hit scans on from the next step.
        for (int l = 0; l < 4; ++l) {
            if (!parked[l] || got[l]) continue;
            LaneScan& q = lane[l];
            q.n = q.next;
            q.ca = q.cb;
            q.ia = q.ib + mStep;
            q.zLow += q.dzr;
            ++q.k;
            pending[l] = true;
        }
    }
    const int hitMask = vmask(hit), stopMask = vmask(stop || above), aboveMask = vmask(above);
    const int failMask = vmask(failed), farMask = vmask(farEnd);
    V4 rgb[3];
    if (hitMask) {
        cellColors(mv, hit ? hitCx : zero, hit ? hitCy : zero, hitFx, hitFy, rgb);
    }
    const V4 lenPerU = len * inv;
    for (int l = 0; l < 4; ++l) {
        if ((failMask >> l) & 1) continue;
        ColumnState& q = st[l];
        q.steps += static_cast<std::uint64_t>(stepsV[l]);
        q.prevRn = rn[l];
        q.prevRz = rz[l];
        if ((hitMask >> l) & 1) {
            tHit[l] = hitU[l] * lenPerU[l];
            float f[3] = {static_cast<float>(rgb[0][l]), static_cast<float>(rgb[1][l]),
                          static_cast<float>(rgb[2][l])};
            c[l] = haze(f, tHit[l]);
            q.prevU = hitU[l];
        } else if ((stopMask >> l) & 1) {
            c[l] = skyColor(options_.sky, dz[l] / len[l]);
            q.prevU = endU[l];
            q.prevAbove = (aboveMask >> l) & 1;
        } else if ((farMask >> l) & 1) {
            ColumnMarch r;
            r.kind = ColumnMarch::kFar;
            r.u = endU[l];
            continueFar(cc[l], glm::dvec3{dx[l], dy[l], dz[l]}, lenPerU[l], r, q, c[l], tHit[l]);
        }
        done[l] = true;
    }
}

VIG_CASTER_AVX2 void FastCaster::renderPacket(const MapView& mv, const Camera& camera, double d0,
                                              int x0, RenderedFrame& frame,
                                              UnitCounters& counters) const {
    const int w = camera.intrinsics().width, h = camera.intrinsics().height;
    ColumnContext cc[4];
    ColumnState st[4];
    V4 bx, by, bz;
    for (int l = 0; l < 4; ++l) {
        cc[l] = columnContext(mv, camera, d0, x0 + l);
        startColumn(camera, cc[l], st[l]);
        bx[l] = cc[l].base.x;
        by[l] = cc[l].base.y;
        bz[l] = cc[l].base.z;
    }
    const glm::dvec3 down = cc[0].down;
    for (int y = h - 1; y >= 0; --y) {
        const double yy = y + 0.5;
        const V4 dx = bx + yy * down.x, dy = by + yy * down.y, dz = bz + yy * down.z;
        const V4 len = vsqrt(dx * dx + dy * dy + dz * dz);
        const V4 gx = dx * cc[0].invSx, gy = dy * cc[0].invSy;
        const M4 majorX = (gx < 0.0 ? -gx : gx) >= (gy < 0.0 ? -gy : gy);
        const int mx = vmask(majorX);
        const V4 gm = majorX ? gx : gy;
        const int pos = vmask(gm > 0.0);
        const int big = vmask((gm < 0.0 ? -gm : gm) > 1e-9 * len);
        Rgb8 c[4];
        double tHit[4] = {-1.0, -1.0, -1.0, -1.0};
        bool done[4] = {false, false, false, false};
        bool lanesOk = (mx == 0 || mx == 15) && (pos == 0 || pos == 15) && big == 15;
        for (int l = 0; l < 4 && lanesOk; ++l) {
            lanesOk = st[l].havePrev && !st[l].prevAbove && st[l].prevMajorX == (mx == 15) &&
                      st[l].prevSgn == (pos == 15 ? 1 : -1);
        }
        if (lanesOk) {
            if (mx == 15) {
                packetRow<true>(cc, st, dx, dy, dz, len, pos == 15 ? 1 : -1, c, tHit, done);
            } else {
                packetRow<false>(cc, st, dx, dy, dz, len, pos == 15 ? 1 : -1, c, tHit, done);
            }
        }
        const std::size_t row = static_cast<std::size_t>(y) * w + x0;
        for (int l = 0; l < 4; ++l) {
            if (!done[l]) {
                const glm::dvec3 d = cc[l].base + yy * cc[l].down;
                castRay(cc[l], d, st[l], c[l], tHit[l]);
            }
            frame.color[row + l] = c[l];
            frame.depth[row + l] = tHit[l] >= 0.0 ? static_cast<float>(tHit[l]) : kSkyDepth;
        }
    }
    for (int l = 0; l < 4; ++l) {
        counters.steps += st[l].steps;
        counters.restarts += st[l].restarts;
    }
}

#endif  // VIG_CASTER_PACKETS

}  // namespace ig::fast
