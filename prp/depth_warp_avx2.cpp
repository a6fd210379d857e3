// The depth model's source-row projection eight pixels at a time with AVX2. Bit-identical to
// detail::projectRowScalar: the same float operations in the same order (multiplies and adds,
// no fused multiply-add; square root and division are correctly rounded in both), conversions
// by truncation in both, selections where the scalar code uses conditionals.
#include "prp/depth_warp.hpp"

#include "prp/warp_apply_kernel.hpp"

#if VIG_PRP_HAVE_AVX2

#include <immintrin.h>

#include <cstring>
#include <limits>

namespace prp::detail {

__attribute__((target("avx2"))) void scaleDepthRowAvx2(const DepthProjection& p, const float* depth,
                                                       int begin, int end, int y, float* scaled) {
    const float b = p.cy - (static_cast<float>(y) + 0.5f);
    const __m256 vBbff = _mm256_set1_ps(b * b + p.f * p.f);
    const __m256 vAOff = _mm256_set1_ps(0.5f - p.cx);
    const __m256 one = _mm256_set1_ps(1.0f);
    const __m256 inf = _mm256_set1_ps(std::numeric_limits<float>::infinity());
    const __m256 ninf = _mm256_set1_ps(-std::numeric_limits<float>::infinity());
    const __m256i lane = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
    int x = begin;
    for (; x + 8 <= end; x += 8) {
        const __m256 d = _mm256_loadu_ps(depth + x);
        const __m256 xf = _mm256_cvtepi32_ps(_mm256_add_epi32(_mm256_set1_epi32(x), lane));
        const __m256 a = _mm256_add_ps(xf, vAOff);
        const __m256 len = _mm256_sqrt_ps(_mm256_add_ps(_mm256_mul_ps(a, a), vBbff));
        const __m256 terrain =
            _mm256_and_ps(_mm256_cmp_ps(d, inf, _CMP_LT_OQ), _mm256_cmp_ps(d, ninf, _CMP_GT_OQ));
        _mm256_storeu_ps(scaled + x, _mm256_div_ps(_mm256_blendv_ps(one, d, terrain), len));
    }
    // The last (end - begin) % 8 pixels: the scalar code.
    scaleDepthRowScalar(p, depth, x, end, y, scaled);
}

__attribute__((target("avx2"))) void projectRowAvx2(const DepthProjection& p, const float* depth,
                                                    const float* scaled, int begin, int end, int y,
                                                    int firstLine, const ProjectedRow& out) {
    const float b = p.cy - (static_cast<float>(y) + 0.5f);
    const float rowR = p.m[1] * b + p.m[2] * p.f;
    const float rowU = p.m[4] * b + p.m[5] * p.f;
    const float rowW = p.m[7] * b + p.m[8] * p.f;
    const float aOff = 0.5f - p.cx;
    const float yc = static_cast<float>(y) + 0.5f;

    const __m256 vRowR = _mm256_set1_ps(rowR), vRowU = _mm256_set1_ps(rowU),
                 vRowW = _mm256_set1_ps(rowW);
    const __m256 m0 = _mm256_set1_ps(p.m[0]), m3 = _mm256_set1_ps(p.m[3]),
                 m6 = _mm256_set1_ps(p.m[6]);
    const __m256 t0 = _mm256_set1_ps(p.t[0]), t1 = _mm256_set1_ps(p.t[1]),
                 t2 = _mm256_set1_ps(p.t[2]);
    const __m256 vAOff = _mm256_set1_ps(aOff), vYc = _mm256_set1_ps(yc);
    const __m256 half = _mm256_set1_ps(0.5f), one = _mm256_set1_ps(1.0f),
                 zero = _mm256_setzero_ps();
    const __m256 inf = _mm256_set1_ps(std::numeric_limits<float>::infinity());
    const __m256 ninf = _mm256_set1_ps(-std::numeric_limits<float>::infinity());
    const __m256 sky = _mm256_set1_ps(kSkyInverseDepth), far = _mm256_set1_ps(1e6f);
    const __m256 ox = _mm256_set1_ps(p.ox), oy = _mm256_set1_ps(p.oy), kx = _mm256_set1_ps(p.kx),
                 ky = _mm256_set1_ps(p.ky);
    const __m256 j0 = _mm256_set1_ps(p.j[0]), j1 = _mm256_set1_ps(p.j[1]),
                 j2 = _mm256_set1_ps(p.j[2]), j3 = _mm256_set1_ps(p.j[3]);
    const __m256 ow = _mm256_set1_ps(static_cast<float>(p.outWidth));
    const __m256i vOutW = _mm256_set1_epi32(p.outWidth);
    const __m256i vParity = _mm256_set1_epi32(firstLine);
    const __m256 lineOff = _mm256_set1_ps(static_cast<float>(firstLine) - 0.5f);
    const __m256 lines = _mm256_set1_ps(static_cast<float>((p.outHeight - firstLine + 1) / 2));
    const __m256i lane = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);

    int x = begin;
    for (; x + 8 <= end; x += 8) {
        const __m256 d = _mm256_loadu_ps(depth + x);
        const __m256 sc = _mm256_loadu_ps(scaled + x);
        const __m256 xf = _mm256_cvtepi32_ps(_mm256_add_epi32(_mm256_set1_epi32(x), lane));
        const __m256 a = _mm256_add_ps(xf, vAOff);
        const __m256 terrain =
            _mm256_and_ps(_mm256_cmp_ps(d, inf, _CMP_LT_OQ), _mm256_cmp_ps(d, ninf, _CMP_GT_OQ));
        const __m256 isSky = _mm256_cmp_ps(d, inf, _CMP_EQ_OQ);
        const __m256 r =
            _mm256_add_ps(_mm256_mul_ps(sc, _mm256_add_ps(_mm256_mul_ps(m0, a), vRowR)),
                          _mm256_and_ps(t0, terrain));
        const __m256 u =
            _mm256_add_ps(_mm256_mul_ps(sc, _mm256_add_ps(_mm256_mul_ps(m3, a), vRowU)),
                          _mm256_and_ps(t1, terrain));
        const __m256 w =
            _mm256_add_ps(_mm256_mul_ps(sc, _mm256_add_ps(_mm256_mul_ps(m6, a), vRowW)),
                          _mm256_and_ps(t2, terrain));
        const __m256 zInv = _mm256_div_ps(one, w);
        const __m256 qx = _mm256_add_ps(ox, _mm256_mul_ps(kx, _mm256_mul_ps(r, zInv)));
        const __m256 qy = _mm256_sub_ps(oy, _mm256_mul_ps(ky, _mm256_mul_ps(u, zInv)));
        const __m256 line = _mm256_mul_ps(_mm256_sub_ps(qy, lineOff), half);
        __m256 inside = _mm256_and_ps(_mm256_or_ps(terrain, isSky),
                                      _mm256_and_ps(_mm256_cmp_ps(zInv, zero, _CMP_GT_OQ),
                                                    _mm256_cmp_ps(zInv, far, _CMP_LT_OQ)));
        inside = _mm256_and_ps(inside, _mm256_and_ps(_mm256_cmp_ps(qx, zero, _CMP_GE_OQ),
                                                     _mm256_cmp_ps(qx, ow, _CMP_LT_OQ)));
        inside = _mm256_and_ps(inside, _mm256_and_ps(_mm256_cmp_ps(line, zero, _CMP_GE_OQ),
                                                     _mm256_cmp_ps(line, lines, _CMP_LT_OQ)));
        const __m256i in = _mm256_castps_si256(inside);
        const __m256i ix = _mm256_and_si256(_mm256_cvttps_epi32(qx), in);
        const __m256i iy = _mm256_and_si256(_mm256_cvttps_epi32(line), in);
        const __m256i index = _mm256_add_epi32(_mm256_mullo_epi32(iy, vOutW), ix);
        _mm256_storeu_si256(reinterpret_cast<__m256i*>(out.index + x),
                            _mm256_blendv_epi8(_mm256_set1_epi32(-1), index, in));
        _mm256_storeu_ps(out.zInv + x, _mm256_blendv_ps(sky, zInv, terrain));
        const __m256 fx = _mm256_cvtepi32_ps(ix);
        const __m256 fy = _mm256_cvtepi32_ps(_mm256_add_epi32(_mm256_slli_epi32(iy, 1), vParity));
        const __m256 dx = _mm256_sub_ps(_mm256_add_ps(fx, half), qx);
        const __m256 dy = _mm256_sub_ps(_mm256_add_ps(fy, half), qy);
        _mm256_storeu_ps(
            out.sx + x, _mm256_add_ps(_mm256_add_ps(xf, half),
                                      _mm256_add_ps(_mm256_mul_ps(j0, dx), _mm256_mul_ps(j1, dy))));
        _mm256_storeu_ps(out.sy + x, _mm256_add_ps(vYc, _mm256_add_ps(_mm256_mul_ps(j2, dx),
                                                                      _mm256_mul_ps(j3, dy))));
    }
    // The last (end - begin) % 8 pixels: the scalar code.
    projectRowScalar(p, depth, scaled, x, end, y, firstLine, out);
}

namespace {

// One field-camera axis of the gather's reprojection: dist ((ma a + mb b) + mf) + len t.
__attribute__((target("avx2"))) inline __m256 gatherAxis(__m256 dist, __m256 a, __m256 b,
                                                         __m256 len, __m256 ma, __m256 mb,
                                                         __m256 mf, __m256 t) {
    return _mm256_add_ps(
        _mm256_mul_ps(dist,
                      _mm256_add_ps(_mm256_add_ps(_mm256_mul_ps(ma, a), _mm256_mul_ps(mb, b)), mf)),
        _mm256_mul_ps(len, t));
}

// Hardware gathers (vgatherdps, vpgatherdq) or one load per lane (the indices stored, the lanes
// inserted): the same values either way.
constexpr bool kHardwareGathers = true;

__attribute__((target("avx2"))) inline std::int64_t load64(const float* at) {
    std::int64_t v;
    std::memcpy(&v, at, sizeof v);
    return v;
}

// rows[o] for the eight indices `o`.
__attribute__((target("avx2"))) inline __m256 gatherOne(const float* rows, __m256i o) {
    if constexpr (kHardwareGathers) return _mm256_i32gather_ps(rows, o, 4);
    alignas(32) std::int32_t i[8];
    _mm256_store_si256(reinterpret_cast<__m256i*>(i), o);
    return _mm256_setr_ps(rows[i[0]], rows[i[1]], rows[i[2]], rows[i[3]], rows[i[4]], rows[i[5]],
                          rows[i[6]], rows[i[7]]);
}

// rows[o] and rows[o + 1] for the eight indices `o`: the left and right taps of a row.
__attribute__((target("avx2"))) inline void gatherPairs(const float* rows, __m256i o, __m256& left,
                                                        __m256& right) {
    __m256 lo, hi;
    if constexpr (kHardwareGathers) {
        const auto* base = reinterpret_cast<const long long*>(rows);
        lo = _mm256_castsi256_ps(_mm256_i32gather_epi64(base, _mm256_castsi256_si128(o), 4));
        hi = _mm256_castsi256_ps(_mm256_i32gather_epi64(base, _mm256_extracti128_si256(o, 1), 4));
    } else {
        alignas(32) std::int32_t i[8];
        _mm256_store_si256(reinterpret_cast<__m256i*>(i), o);
        lo = _mm256_castsi256_ps(_mm256_setr_epi64x(load64(rows + i[0]), load64(rows + i[1]),
                                                    load64(rows + i[2]), load64(rows + i[3])));
        hi = _mm256_castsi256_ps(_mm256_setr_epi64x(load64(rows + i[4]), load64(rows + i[5]),
                                                    load64(rows + i[6]), load64(rows + i[7])));
    }
    // Lanes come out as 0 1 4 5 | 2 3 6 7; the 64-bit permute puts them in order.
    left = _mm256_castpd_ps(
        _mm256_permute4x64_pd(_mm256_castps_pd(_mm256_shuffle_ps(lo, hi, _MM_SHUFFLE(2, 0, 2, 0))),
                              _MM_SHUFFLE(3, 1, 2, 0)));
    right = _mm256_castpd_ps(
        _mm256_permute4x64_pd(_mm256_castps_pd(_mm256_shuffle_ps(lo, hi, _MM_SHUFFLE(3, 1, 3, 1))),
                              _MM_SHUFFLE(3, 1, 2, 0)));
}

// G groups of eight pixels from x on, their steps interleaved: each group's chain of gathers,
// square roots and divisions is serial, so independent groups keep the core busy.
template <int G>
__attribute__((target("avx2"))) inline int gatherGroups(const DepthProjection& p,
                                                        const GatherLine& l, const float* depth,
                                                        int width, int height, int x,
                                                        std::int32_t* px, std::int32_t* py,
                                                        std::uint8_t* unsettled, float* distOut) {
    const __m256 ff = _mm256_set1_ps(p.f * p.f);
    const __m256 m2f = _mm256_set1_ps(p.m[2] * p.f), m5f = _mm256_set1_ps(p.m[5] * p.f),
                 m8f = _mm256_set1_ps(p.m[8] * p.f);
    const __m256 m0 = _mm256_set1_ps(p.m[0]), m1 = _mm256_set1_ps(p.m[1]),
                 m3 = _mm256_set1_ps(p.m[3]), m4 = _mm256_set1_ps(p.m[4]),
                 m6 = _mm256_set1_ps(p.m[6]), m7 = _mm256_set1_ps(p.m[7]);
    const __m256 t0 = _mm256_set1_ps(p.t[0]), t1 = _mm256_set1_ps(p.t[1]),
                 t2 = _mm256_set1_ps(p.t[2]);
    const __m256 vcx = _mm256_set1_ps(p.cx), vcy = _mm256_set1_ps(p.cy);
    const __m256 ox = _mm256_set1_ps(p.ox), oy = _mm256_set1_ps(p.oy), kx = _mm256_set1_ps(p.kx),
                 ky = _mm256_set1_ps(p.ky);
    const __m256 xMax = _mm256_set1_ps(static_cast<float>(width - 1)),
                 yMax = _mm256_set1_ps(static_cast<float>(height - 1));
    const __m256 xMaxFull = xMax, yMaxFull = yMax;
    const __m256i xLast = _mm256_set1_epi32(width - 2), yLast = _mm256_set1_epi32(height - 2);
    const __m256i vWidth = _mm256_set1_epi32(width);
    const __m256 half = _mm256_set1_ps(0.5f), one = _mm256_set1_ps(1.0f),
                 zero = _mm256_setzero_ps();
    const __m256 parallax = _mm256_set1_ps(gatherParallaxScale(p));
    const __m256 settle = _mm256_set1_ps(kGatherSettledPx);
    const __m256 edge = _mm256_set1_ps(kGatherEdgePx);
    const __m256 far = _mm256_set1_ps(kGatherFar);
    const __m256 absMask = _mm256_castsi256_ps(_mm256_set1_epi32(0x7fffffff));
    const __m256 lo = _mm256_set1_ps(-16384.0f), hi = _mm256_set1_ps(16384.0f);
    const __m256 scale = _mm256_set1_ps(0x1p16f);
    const __m256i pointHalf = _mm256_set1_epi32(kPointHalf);
    const __m256 row = _mm256_set1_ps(l.row);
    const __m256 x0 = _mm256_set1_ps(l.x0), x1 = _mm256_set1_ps(l.x1), x2 = _mm256_set1_ps(l.x2),
                 x2x2 = _mm256_set1_ps(l.x2x2), xy0 = _mm256_set1_ps(l.xy0),
                 xy1 = _mm256_set1_ps(l.xy1);
    const __m256 y0 = _mm256_set1_ps(l.y0), y1 = _mm256_set1_ps(l.y1), y2 = _mm256_set1_ps(l.y2),
                 y2x2 = _mm256_set1_ps(l.y2x2), yy0 = _mm256_set1_ps(l.yy0),
                 yy1 = _mm256_set1_ps(l.yy1);
    const __m256i lane = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);

    const __m256 allOnes = _mm256_castsi256_ps(_mm256_set1_epi32(-1));
    int count = 0;
    __m256 qx[G], sx[G], sy[G], jxx[G], jxy[G], jyx[G], jyy[G], valid[G], distFirst[G], dist[G],
        dMin[G], dMax[G], rx[G], ry[G], settled[G];
    for (int g = 0; g < G; ++g) {
        qx[g] = _mm256_add_ps(
            _mm256_cvtepi32_ps(_mm256_add_epi32(_mm256_set1_epi32(x + 8 * g), lane)), half);
        sx[g] =
            _mm256_add_ps(x0, _mm256_mul_ps(qx[g], _mm256_add_ps(x1, _mm256_mul_ps(qx[g], x2))));
        sy[g] =
            _mm256_add_ps(y0, _mm256_mul_ps(qx[g], _mm256_add_ps(y1, _mm256_mul_ps(qx[g], y2))));
        jxx[g] = _mm256_add_ps(x1, _mm256_mul_ps(qx[g], x2x2));
        jxy[g] = _mm256_add_ps(xy0, _mm256_mul_ps(qx[g], xy1));
        jyx[g] = _mm256_add_ps(y1, _mm256_mul_ps(qx[g], y2x2));
        jyy[g] = _mm256_add_ps(yy0, _mm256_mul_ps(qx[g], yy1));
        valid[g] = allOnes;
        distFirst[g] = dist[g] = dMin[g] = dMax[g] = rx[g] = ry[g] = zero;
    }
    for (int step = 0; step < kGatherSteps; ++step) {
        for (int g = 0; g < G; ++g) {
            // max/min return their second operand on NaN, as the scalar twin's conditionals.
            if (step == 0) {
                const __m256i ix =
                    _mm256_cvttps_epi32(_mm256_min_ps(_mm256_max_ps(sx[g], zero), xMaxFull));
                const __m256i iy =
                    _mm256_cvttps_epi32(_mm256_min_ps(_mm256_max_ps(sy[g], zero), yMaxFull));
                const __m256 nearest =
                    gatherOne(depth, _mm256_add_epi32(_mm256_mullo_epi32(iy, vWidth), ix));
                valid[g] = _mm256_and_ps(valid[g], _mm256_cmp_ps(nearest, zero, _CMP_GT_OQ));
                dist[g] = _mm256_min_ps(nearest, far);
                distFirst[g] = dist[g];
            } else {
                const __m256 fx =
                    _mm256_min_ps(_mm256_max_ps(_mm256_sub_ps(sx[g], half), zero), xMax);
                const __m256 fy =
                    _mm256_min_ps(_mm256_max_ps(_mm256_sub_ps(sy[g], half), zero), yMax);
                const __m256i ix = _mm256_min_epi32(_mm256_cvttps_epi32(fx), xLast);
                const __m256i iy = _mm256_min_epi32(_mm256_cvttps_epi32(fy), yLast);
                const __m256 wx = _mm256_sub_ps(fx, _mm256_cvtepi32_ps(ix));
                const __m256 wy = _mm256_sub_ps(fy, _mm256_cvtepi32_ps(iy));
                const __m256i o = _mm256_add_epi32(_mm256_mullo_epi32(iy, vWidth), ix);
                // Both taps of a row in one 8-byte element: four per gather.
                __m256 g00, g01, g10, g11;
                gatherPairs(depth, o, g00, g01);
                gatherPairs(depth + width, o, g10, g11);
                valid[g] =
                    _mm256_and_ps(valid[g], _mm256_and_ps(_mm256_cmp_ps(g00, zero, _CMP_GT_OQ),
                                                          _mm256_cmp_ps(g01, zero, _CMP_GT_OQ)));
                valid[g] =
                    _mm256_and_ps(valid[g], _mm256_and_ps(_mm256_cmp_ps(g10, zero, _CMP_GT_OQ),
                                                          _mm256_cmp_ps(g11, zero, _CMP_GT_OQ)));
                const __m256 d00 = _mm256_min_ps(g00, far), d01 = _mm256_min_ps(g01, far),
                             d10 = _mm256_min_ps(g10, far), d11 = _mm256_min_ps(g11, far);
                const __m256 top = _mm256_add_ps(d00, _mm256_mul_ps(wx, _mm256_sub_ps(d01, d00)));
                const __m256 bottom =
                    _mm256_add_ps(d10, _mm256_mul_ps(wx, _mm256_sub_ps(d11, d10)));
                dist[g] = _mm256_add_ps(top, _mm256_mul_ps(wy, _mm256_sub_ps(bottom, top)));
                dMin[g] = _mm256_min_ps(_mm256_min_ps(d00, d01), _mm256_min_ps(d10, d11));
                dMax[g] = _mm256_max_ps(_mm256_max_ps(d00, d01), _mm256_max_ps(d10, d11));
            }
            const __m256 a = _mm256_sub_ps(sx[g], vcx);
            const __m256 b = _mm256_sub_ps(vcy, sy[g]);
            const __m256 len = _mm256_sqrt_ps(
                _mm256_add_ps(_mm256_add_ps(_mm256_mul_ps(a, a), _mm256_mul_ps(b, b)), ff));
            const __m256 r = gatherAxis(dist[g], a, b, len, m0, m1, m2f, t0);
            const __m256 u = gatherAxis(dist[g], a, b, len, m3, m4, m5f, t1);
            const __m256 w = gatherAxis(dist[g], a, b, len, m6, m7, m8f, t2);
            valid[g] = _mm256_and_ps(valid[g], _mm256_cmp_ps(w, zero, _CMP_GT_OQ));
            const __m256 inv = _mm256_div_ps(one, w);
            rx[g] =
                _mm256_sub_ps(qx[g], _mm256_add_ps(ox, _mm256_mul_ps(kx, _mm256_mul_ps(r, inv))));
            ry[g] = _mm256_sub_ps(row, _mm256_sub_ps(oy, _mm256_mul_ps(ky, _mm256_mul_ps(u, inv))));
            sx[g] = _mm256_add_ps(
                sx[g], _mm256_add_ps(_mm256_mul_ps(jxx[g], rx[g]), _mm256_mul_ps(jxy[g], ry[g])));
            sy[g] = _mm256_add_ps(
                sy[g], _mm256_add_ps(_mm256_mul_ps(jyx[g], rx[g]), _mm256_mul_ps(jyy[g], ry[g])));
        }
    }
    for (int g = 0; g < G; ++g) {
        settled[g] = _mm256_and_ps(
            valid[g],
            _mm256_and_ps(_mm256_cmp_ps(_mm256_and_ps(rx[g], absMask), settle, _CMP_LE_OQ),
                          _mm256_cmp_ps(_mm256_and_ps(ry[g], absMask), settle, _CMP_LE_OQ)));
        settled[g] = _mm256_and_ps(
            settled[g],
            _mm256_cmp_ps(_mm256_mul_ps(_mm256_sub_ps(dMax[g], dMin[g]), parallax),
                          _mm256_mul_ps(edge, _mm256_mul_ps(dMin[g], dMax[g])), _CMP_LE_OQ));
        settled[g] = _mm256_andnot_ps(
            _mm256_cmp_ps(_mm256_mul_ps(_mm256_sub_ps(dist[g], distFirst[g]), parallax),
                          _mm256_mul_ps(edge, _mm256_mul_ps(distFirst[g], dist[g])), _CMP_GT_OQ),
            settled[g]);
        const __m256 cx = _mm256_min_ps(_mm256_max_ps(sx[g], lo), hi);
        const __m256 cy = _mm256_min_ps(_mm256_max_ps(sy[g], lo), hi);
        _mm256_storeu_si256(
            reinterpret_cast<__m256i*>(px + x + 8 * g),
            _mm256_sub_epi32(_mm256_cvttps_epi32(_mm256_mul_ps(cx, scale)), pointHalf));
        _mm256_storeu_si256(
            reinterpret_cast<__m256i*>(py + x + 8 * g),
            _mm256_sub_epi32(_mm256_cvttps_epi32(_mm256_mul_ps(cy, scale)), pointHalf));
        const int settledBits = _mm256_movemask_ps(settled[g]);
        for (int i = 0; i < 8; ++i)
            unsettled[x + 8 * g + i] = static_cast<std::uint8_t>(((settledBits >> i) & 1) ^ 1);
        _mm256_storeu_ps(distOut + x + 8 * g, dist[g]);
        count += 8 - __builtin_popcount(static_cast<unsigned>(settledBits));
    }
    return count;
}

}  // namespace

__attribute__((target("avx2"))) int gatherLineAvx2(const DepthProjection& p, const GatherLine& l,
                                                   const float* depth, int width, int height,
                                                   int begin, int end, std::int32_t* px,
                                                   std::int32_t* py, std::uint8_t* unsettled,
                                                   float* dist) {
    int count = 0;
    int x = begin;
    for (; x + 32 <= end; x += 32)
        count += gatherGroups<4>(p, l, depth, width, height, x, px, py, unsettled, dist);
    for (; x + 8 <= end; x += 8)
        count += gatherGroups<1>(p, l, depth, width, height, x, px, py, unsettled, dist);
    // The last (end - begin) % 8 pixels: the scalar code.
    return count + gatherLineScalar(p, l, depth, width, height, x, end, px, py, unsettled, dist);
}

}  // namespace prp::detail

#endif  // VIG_PRP_HAVE_AVX2
