// The depth model's source-row projection eight pixels at a time with AVX2. Bit-identical to
// detail::projectRowScalar: the same float operations in the same order (multiplies and adds,
// no fused multiply-add; square root and division are correctly rounded in both), conversions
// by truncation in both, selections where the scalar code uses conditionals.
#include "prp/depth_warp.hpp"

#include "prp/warp_apply_kernel.hpp"

#if VIG_PRP_HAVE_AVX2

#include <immintrin.h>

#include <limits>

namespace prp::detail {

__attribute__((target("avx2"))) void projectRowAvx2(const DepthProjection& p, const float* depth,
                                                    int width, int y, int firstLine,
                                                    const ProjectedRow& out) {
    const float b = p.cy - (static_cast<float>(y) + 0.5f);
    const float bbff = b * b + p.f * p.f;
    const float rowR = p.m[1] * b + p.m[2] * p.f;
    const float rowU = p.m[4] * b + p.m[5] * p.f;
    const float rowW = p.m[7] * b + p.m[8] * p.f;
    const float aOff = 0.5f - p.cx;
    const float yc = static_cast<float>(y) + 0.5f;

    const __m256 vBbff = _mm256_set1_ps(bbff);
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
    const __m256 invSx = _mm256_set1_ps(p.invSx), invSy = _mm256_set1_ps(p.invSy);
    const __m256 ow = _mm256_set1_ps(static_cast<float>(p.outWidth));
    const __m256i vOutW = _mm256_set1_epi32(p.outWidth);
    const __m256i vParity = _mm256_set1_epi32(firstLine);
    const __m256 lineOff = _mm256_set1_ps(static_cast<float>(firstLine) - 0.5f);
    const __m256 lines = _mm256_set1_ps(static_cast<float>((p.outHeight - firstLine + 1) / 2));
    const __m256i lane = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);

    int x = 0;
    for (; x + 8 <= width; x += 8) {
        const __m256 d = _mm256_loadu_ps(depth + x);
        const __m256 xf = _mm256_cvtepi32_ps(_mm256_add_epi32(_mm256_set1_epi32(x), lane));
        const __m256 a = _mm256_add_ps(xf, vAOff);
        const __m256 len = _mm256_sqrt_ps(_mm256_add_ps(_mm256_mul_ps(a, a), vBbff));
        const __m256 terrain =
            _mm256_and_ps(_mm256_cmp_ps(d, inf, _CMP_LT_OQ), _mm256_cmp_ps(d, ninf, _CMP_GT_OQ));
        const __m256 isSky = _mm256_cmp_ps(d, inf, _CMP_EQ_OQ);
        const __m256 dd = _mm256_blendv_ps(one, d, terrain);
        const __m256 r =
            _mm256_add_ps(_mm256_mul_ps(dd, _mm256_add_ps(_mm256_mul_ps(m0, a), vRowR)),
                          _mm256_and_ps(_mm256_mul_ps(t0, len), terrain));
        const __m256 u =
            _mm256_add_ps(_mm256_mul_ps(dd, _mm256_add_ps(_mm256_mul_ps(m3, a), vRowU)),
                          _mm256_and_ps(_mm256_mul_ps(t1, len), terrain));
        const __m256 wl =
            _mm256_add_ps(_mm256_mul_ps(dd, _mm256_add_ps(_mm256_mul_ps(m6, a), vRowW)),
                          _mm256_and_ps(_mm256_mul_ps(t2, len), terrain));
        const __m256 inv = _mm256_div_ps(one, wl);
        const __m256 zInv = _mm256_mul_ps(len, inv);
        const __m256 qx = _mm256_add_ps(ox, _mm256_mul_ps(kx, _mm256_mul_ps(r, inv)));
        const __m256 qy = _mm256_sub_ps(oy, _mm256_mul_ps(ky, _mm256_mul_ps(u, inv)));
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
        _mm256_storeu_ps(
            out.sx + x,
            _mm256_add_ps(_mm256_add_ps(xf, half),
                          _mm256_mul_ps(_mm256_sub_ps(_mm256_add_ps(fx, half), qx), invSx)));
        _mm256_storeu_ps(
            out.sy + x,
            _mm256_add_ps(vYc, _mm256_mul_ps(_mm256_sub_ps(_mm256_add_ps(fy, half), qy), invSy)));
    }
    // The last width % 8 pixels: the scalar code.
    projectRowScalar(p, depth, x, width, y, firstLine, out);
}

}  // namespace prp::detail

#endif  // VIG_PRP_HAVE_AVX2
