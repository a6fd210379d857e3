// The quadratic field warp sixteen pixels at a time with AVX-512 (F, BW, DQ, VL, VBMI),
// bit-identical to the scalar kernel. Same arithmetic as the AVX2 kernel (warp_apply_avx2.cpp
// says why it matches bit for bit); the wider registers take the position lanes apart with one
// vpermt2d, test the interior with mask compares, split the taps into channels with one
// two-source byte permute (vpermt2b) per channel and row, and pack the output with truncating
// moves. Groups reaching outside the interior clamp and count edge samples in the lanes, with
// the scalar Sampler's exact 64-bit clamps and tests.
#include "prp/warp_apply_simd.hpp"

#if VIG_PRP_HAVE_AVX2

#include <array>
#include <cstring>

// GCC 12's AVX-512 intrinsics start some results from a deliberately undefined register
// (_mm512_undefined_*), which -Wuninitialized reports where they are inlined.
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic ignored "-Wuninitialized"
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#endif

namespace prp::detail {

namespace {

using namespace simd;

// Byte-permute indices of the red tap pairs (see pickR below); odd bytes get zeroed.
constexpr std::array<std::uint8_t, 64> pickRedBytes() {
    std::array<std::uint8_t, 64> b{};
    for (int k = 0; k < 16; ++k) {
        b[4 * k] = static_cast<std::uint8_t>(8 * k);
        b[4 * k + 2] = static_cast<std::uint8_t>(8 * k + 3);
    }
    return b;
}
alignas(64) constexpr std::array<std::uint8_t, 64> kPickR = pickRedBytes();

constexpr int kSlot16[16] = {0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15};

// Dword i of the result: dword (2 i + odd) of the 64-bit lanes a (pixels 0..7), b (8..15).
VIG_TARGET_AVX512 inline __m512i halves(__m512i a, __m512i b, bool odd) {
    const int o = odd ? 1 : 0;
    const __m512i idx =
        _mm512_setr_epi32(o, 2 + o, 4 + o, 6 + o, 8 + o, 10 + o, 12 + o, 14 + o, 16 + o, 18 + o,
                          20 + o, 22 + o, 24 + o, 26 + o, 28 + o, 30 + o);
    return _mm512_permutex2var_epi32(a, idx, b);
}

// A constant the compiler keeps in a register instead of rebuilding it in the loop.
VIG_TARGET_AVX512 inline __m512i pinned(int v) {
    __m512i r = _mm512_set1_epi32(v);
    __asm__("" : "+v"(r));
    return r;
}

// The kernel's constants, built once per field.
struct Constants {
    __m512i c128, c255, c256, c2pow15, gHighMask, yHighMask, greyRG, greyB, yRG, yB, yOffset,
        cOffset;

    VIG_TARGET_AVX512 Constants()
        : c128(pinned(128)),
          c255(pinned(255)),
          c256(pinned(256)),
          c2pow15(pinned(1 << 15)),
          gHighMask(pinned(0xff0000)),
          yHighMask(pinned(static_cast<int>(0xffff0000u))),
          greyRG(pinned(words(kGr, kGg))),
          greyB(pinned(kGb)),
          yRG(pinned(words(kYr, kYg))),
          yB(pinned(kYb)),
          yOffset(pinned((16 << 16) + (1 << 15))),
          cOffset(pinned((128 << 17) + (1 << 16))) {}
};

// Vertical step of the bilinear sample before its final shift (bits 16..23 hold the value):
// (top << 8) + (bot - top) fy + 2^15, one multiply (the multiplier ports are the busier ones).
VIG_TARGET_AVX512 inline __m512i lerpRows(__m512i top, __m512i bot, __m512i fy,
                                          const Constants& k) {
    return _mm512_add_epi32(_mm512_add_epi32(_mm512_slli_epi32(top, 8),
                                             _mm512_mullo_epi32(_mm512_sub_epi32(bot, top), fy)),
                            k.c2pow15);
}

VIG_TARGET_AVX512 inline __m512i gainOf(__m512i c, __m512i gain, const Constants& k) {
    const __m512i v = _mm512_srai_epi32(_mm512_add_epi32(_mm512_mullo_epi32(c, gain), k.c128), 8);
    return _mm512_min_epi32(v, k.c255);
}

VIG_TARGET_AVX512 inline __m512i greyOf16(__m512i rg, __m512i b, const Constants& k) {
    const __m512i v =
        _mm512_add_epi32(_mm512_madd_epi16(rg, k.greyRG), _mm512_madd_epi16(b, k.greyB));
    return _mm512_srli_epi32(_mm512_add_epi32(v, k.c128), 8);
}

VIG_TARGET_AVX512 inline __m128i load8(const std::uint8_t* p) {
    return _mm_loadl_epi64(reinterpret_cast<const __m128i*>(p));
}

// Four 8-byte loads into one 256-bit register as load2x2, with merge-masked broadcast loads
// (one instruction each, any vector register).
VIG_TARGET_AVX512 inline __m256i load2x2Masked(const std::uint8_t* base, Offsets2 lo, Offsets2 hi) {
    __m256i v = _mm256_castsi128_si256(load8(base + lo.first));
    v = _mm256_mask_broadcastq_epi64(v, 0x2, load8(base + lo.second));
    v = _mm256_mask_broadcastq_epi64(v, 0x4, load8(base + hi.first));
    return _mm256_mask_broadcastq_epi64(v, 0x8, load8(base + hi.second));
}

// 128-bit lanes holding pixels (p[0], p[1]), (p[2], p[3]), (p[4], p[5]), (p[6], p[7]).
VIG_TARGET_AVX512 inline __m512i load4x2(const std::uint8_t* base, const Offsets2* p) {
    return _mm512_inserti64x4(_mm512_castsi256_si512(load2x2Masked(base, p[0], p[1])),
                              load2x2Masked(base, p[2], p[3]), 1);
}

// Flattened: what it calls from the shared kernel header for the pixels the vector code leaves
// to the scalar code (writePixels, Sampler::sample) is inlined here, at every optimisation
// level (at -O1 the compiler emitted weak writePixels copies), so that no weak symbol is left
// for the linker to share with the baseline objects (scripts/isa-symbols.sh).
template <PixelFormat kFormat, bool kGain, bool kAgc>
[[gnu::flatten]] VIG_TARGET_AVX512 ApplyResult quadraticAvx512(const SourceView& source,
                                                               const Quadratic& q,
                                                               const FieldView& field, int gainQ8) {
    Sampler s(source);
    QuadraticRows rows{q};
    std::uint64_t luma = 0;
    const int width = field.width;
    const std::uint8_t* row0 = s.base;
    const std::uint8_t* row1 = s.base + s.rowBytes;
    const __m512i rowBytes = _mm512_set1_epi32(static_cast<int>(s.rowBytes));
    const __m512i limX = _mm512_set1_epi32(source.width - 3);
    const __m512i limY = _mm512_set1_epi32(source.height - 2);
    const __m512i lastX = _mm512_set1_epi32(source.width - 2);
    const __m512i lastY = limY;
    const __m512i zero = _mm512_setzero_si512();
    const __m512i maxX = _mm512_set1_epi64(s.maxX), maxY = _mm512_set1_epi64(s.maxY);
    const __m512i half = _mm512_set1_epi64(kHalf);
    const __m512i spanX = _mm512_set1_epi64(static_cast<long long>(s.spanX));
    const __m512i spanY = _mm512_set1_epi64(static_cast<long long>(s.spanY));
    const __m512i gain = _mm512_set1_epi32(gainQ8);
    const Constants kc;
    // Bytes 8 k + c and 8 k + c + 3 of (a, b): channel c of pixel k's taps (x0, x0 + 1), as the
    // two words of dword k.
    const __m512i pickR = _mm512_load_si512(kPickR.data());
    const __m512i pickG = _mm512_add_epi8(pickR, _mm512_set1_epi8(1));
    const __m512i pickB = _mm512_add_epi8(pickR, _mm512_set1_epi8(2));
    const __m512i pack3 = _mm512_broadcast_i32x4(
        _mm_setr_epi8(0, 1, 2, 4, 5, 6, 8, 9, 10, 12, 13, 14, -1, -1, -1, -1));
    const __m512i chromaRG = _mm512_broadcast_i32x4(
        _mm_setr_epi32(words(kCbR, kCbG), words(kCrR, kCrG), words(kCbR, kCbG), words(kCrR, kCrG)));
    const __m512i chromaB = _mm512_broadcast_i32x4(
        _mm_setr_epi32(words(kCbB, 0), words(kCrB, 0), words(kCbB, 0), words(kCrB, 0)));

    alignas(64) std::int64_t px[16], py[16], psx[16], psy[16];
    for (int line = 0; line < field.lines; ++line) {
        std::uint8_t* out = field.pixels + static_cast<std::size_t>(line) * field.stride;
        rows.start(field.firstLine + 2 * line + 0.5);
        // Lane k starts at pixel k and moves 16 pixels per step: x += sx, sx += 256 ddx with
        // sx = 16 dx + 120 ddx (wrapping arithmetic, as the lanes' adds).
        std::uint64_t x = static_cast<std::uint64_t>(rows.x);
        std::uint64_t y = static_cast<std::uint64_t>(rows.y);
        std::uint64_t dx = static_cast<std::uint64_t>(rows.dx);
        std::uint64_t dy = static_cast<std::uint64_t>(rows.dy);
        const std::uint64_t ddx = static_cast<std::uint64_t>(rows.ddx);
        const std::uint64_t ddy = static_cast<std::uint64_t>(rows.ddy);
        for (int k = 0; k < 16; ++k) {
            px[k] = static_cast<std::int64_t>(x);
            py[k] = static_cast<std::int64_t>(y);
            psx[k] = static_cast<std::int64_t>(16 * dx + 120 * ddx);
            psy[k] = static_cast<std::int64_t>(16 * dy + 120 * ddy);
            x += dx;
            dx += ddx;
            y += dy;
            dy += ddy;
        }
        __m512i xa = _mm512_load_si512(px), xb = _mm512_load_si512(px + 8);
        __m512i ya = _mm512_load_si512(py), yb = _mm512_load_si512(py + 8);
        // Lanes b are 8 pixels ahead of lanes a: their steps are 128 dd larger.
        __m512i sxa = _mm512_load_si512(psx), sya = _mm512_load_si512(psy);
        const __m512i ddx128 = _mm512_set1_epi64(static_cast<long long>(128 * ddx));
        const __m512i ddy128 = _mm512_set1_epi64(static_cast<long long>(128 * ddy));
        const __m512i ddx256 = _mm512_set1_epi64(static_cast<long long>(256 * ddx));
        const __m512i ddy256 = _mm512_set1_epi64(static_cast<long long>(256 * ddy));
        __m512i lumaSum = _mm512_setzero_si512();

        int i = 0;
        for (; i + 16 <= width; i += 16) {
            // Sample points: the lanes' own, or clamped to the frame where any is outside the
            // clamp-free interior (0 <= x0 <= w - 3, 0 <= y0 <= h - 2).
            __m512i cxa = xa, cxb = xb, cya = ya, cyb = yb;
            __m512i xi = halves(xa, xb, true), yi = halves(ya, yb, true);
            const __mmask16 inside =
                _mm512_mask_cmple_epu32_mask(_mm512_cmple_epu32_mask(xi, limX), yi, limY);
            bool lanes = true;
            if (inside != 0xffff) {
                // As Sampler::sample: clamp to [0, max], count the points beyond half a pixel
                // outside. Clamped taps reach x0 = w - 2, whose 8-byte load would pass the end
                // of the image on its last row: that corner stays with the scalar code.
                cxa = _mm512_min_epi64(_mm512_max_epi64(xa, zero), maxX);
                cxb = _mm512_min_epi64(_mm512_max_epi64(xb, zero), maxX);
                cya = _mm512_min_epi64(_mm512_max_epi64(ya, zero), maxY);
                cyb = _mm512_min_epi64(_mm512_max_epi64(yb, zero), maxY);
                xi = halves(cxa, cxb, true);
                yi = halves(cya, cyb, true);
                const __mmask16 corner =
                    _mm512_mask_cmpeq_epi32_mask(_mm512_cmpeq_epi32_mask(xi, lastX), yi, lastY);
                if (corner != 0) {
                    lanes = false;
                } else {
                    const __mmask8 ea = _mm512_cmpgt_epu64_mask(_mm512_add_epi64(xa, half), spanX) |
                                        _mm512_cmpgt_epu64_mask(_mm512_add_epi64(ya, half), spanY);
                    const __mmask8 eb = _mm512_cmpgt_epu64_mask(_mm512_add_epi64(xb, half), spanX) |
                                        _mm512_cmpgt_epu64_mask(_mm512_add_epi64(yb, half), spanY);
                    s.edge += static_cast<unsigned>(__builtin_popcount(ea)) +
                              static_cast<unsigned>(__builtin_popcount(eb));
                }
            }
            if (lanes) {
                const __m512i fx = _mm512_srli_epi32(halves(cxa, cxb, false), 24);
                const __m512i fy = _mm512_srli_epi32(halves(cya, cyb, false), 24);
                const __m512i wx =
                    _mm512_add_epi32(_mm512_sub_epi32(_mm512_slli_epi32(fx, 16), fx), kc.c256);
                const __m512i offset =
                    _mm512_add_epi32(_mm512_mullo_epi32(yi, rowBytes),
                                     _mm512_add_epi32(xi, _mm512_add_epi32(xi, xi)));
                const __m128i o0 = _mm512_castsi512_si128(offset);
                const __m128i o1 = _mm512_extracti32x4_epi32(offset, 1);
                const __m128i o2 = _mm512_extracti32x4_epi32(offset, 2);
                const __m128i o3 = _mm512_extracti32x4_epi32(offset, 3);
                // Taps of pixels 0..7 (a) and 8..15 (b), rows y0 (0) and y0 + 1 (1); one half
                // of the offsets at a time keeps them in general registers. The byte permutes
                // then pick each channel's tap pair of all 16 pixels as 16-bit words.
                __m512i a0, a1, b0, b1;
                {
                    const Offsets2 p[4] = {
                        Offsets2(_mm_cvtsi128_si64(o0)), Offsets2(_mm_extract_epi64(o0, 1)),
                        Offsets2(_mm_cvtsi128_si64(o1)), Offsets2(_mm_extract_epi64(o1, 1))};
                    a0 = load4x2(row0, p);
                    a1 = load4x2(row1, p);
                }
                {
                    const Offsets2 p[4] = {
                        Offsets2(_mm_cvtsi128_si64(o2)), Offsets2(_mm_extract_epi64(o2, 1)),
                        Offsets2(_mm_cvtsi128_si64(o3)), Offsets2(_mm_extract_epi64(o3, 1))};
                    b0 = load4x2(row0, p);
                    b1 = load4x2(row1, p);
                }
                constexpr __mmask64 kEven = 0x5555555555555555ull;
                const __m512i topR =
                    _mm512_madd_epi16(_mm512_maskz_permutex2var_epi8(kEven, a0, pickR, b0), wx);
                const __m512i topG =
                    _mm512_madd_epi16(_mm512_maskz_permutex2var_epi8(kEven, a0, pickG, b0), wx);
                const __m512i topB =
                    _mm512_madd_epi16(_mm512_maskz_permutex2var_epi8(kEven, a0, pickB, b0), wx);
                const __m512i botR =
                    _mm512_madd_epi16(_mm512_maskz_permutex2var_epi8(kEven, a1, pickR, b1), wx);
                const __m512i botG =
                    _mm512_madd_epi16(_mm512_maskz_permutex2var_epi8(kEven, a1, pickG, b1), wx);
                const __m512i botB =
                    _mm512_madd_epi16(_mm512_maskz_permutex2var_epi8(kEven, a1, pickB, b1), wx);
                const __m512i accR = lerpRows(topR, botR, fy, kc);
                const __m512i accG = lerpRows(topG, botG, fy, kc);
                const __m512i accB = lerpRows(topB, botB, fy, kc);
                __m512i r = _mm512_srli_epi32(accR, 16), b = _mm512_srli_epi32(accB, 16);
                __m512i gHigh;  // G << 16
                if constexpr (kGain) {
                    r = gainOf(r, gain, kc);
                    b = gainOf(b, gain, kc);
                    gHigh = _mm512_slli_epi32(gainOf(_mm512_srli_epi32(accG, 16), gain, kc), 16);
                } else {
                    gHigh = _mm512_and_si512(accG, kc.gHighMask);
                }
                const __m512i rg = _mm512_or_si512(r, gHigh);

                if constexpr (kFormat == PixelFormat::Uyvy) {
                    __m512i yv = _mm512_add_epi32(_mm512_madd_epi16(rg, kc.yRG), gHigh);
                    yv = _mm512_add_epi32(yv, _mm512_madd_epi16(b, kc.yB));
                    yv = _mm512_add_epi32(yv, kc.yOffset);
                    const __m512i rgSum = _mm512_add_epi32(
                        rg, _mm512_shuffle_epi32(rg, static_cast<_MM_PERM_ENUM>(0xb1)));
                    const __m512i bSum = _mm512_add_epi32(
                        b, _mm512_shuffle_epi32(b, static_cast<_MM_PERM_ENUM>(0xb1)));
                    __m512i c = _mm512_add_epi32(_mm512_madd_epi16(rgSum, chromaRG),
                                                 _mm512_madd_epi16(bSum, chromaB));
                    c = _mm512_srai_epi32(_mm512_add_epi32(c, kc.cOffset), 17);
                    // Words Cb Y0 Cr Y1 ..., truncated to bytes (all values are 16..240).
                    const __m512i words16 = _mm512_ternarylogic_epi32(c, yv, kc.yHighMask, 0xf8);
                    _mm256_storeu_si256(reinterpret_cast<__m256i*>(out),
                                        _mm512_cvtepi16_epi8(words16));
                    out += 32;
                    if constexpr (kAgc) lumaSum = _mm512_add_epi32(lumaSum, greyOf16(rg, b, kc));
                } else if constexpr (kFormat == PixelFormat::Rgb8) {
                    const __m512i rgb = _mm512_shuffle_epi8(
                        _mm512_ternarylogic_epi32(r, _mm512_srli_epi32(gHigh, 8),
                                                  _mm512_slli_epi32(b, 16), 0xfe),
                        pack3);
                    // 12 bytes per 128-bit lane, compacted to 48 bytes.
                    const __m512i packed = _mm512_permutexvar_epi32(
                        _mm512_setr_epi32(0, 1, 2, 4, 5, 6, 8, 9, 10, 12, 13, 14, 0, 0, 0, 0), rgb);
                    _mm512_mask_storeu_epi32(out, 0x0fff, packed);
                    out += 48;
                    if constexpr (kAgc) lumaSum = _mm512_add_epi32(lumaSum, greyOf16(rg, b, kc));
                } else {
                    const __m512i gv = greyOf16(rg, b, kc);
                    _mm_storeu_si128(reinterpret_cast<__m128i*>(out), _mm512_cvtepi32_epi8(gv));
                    out += 16;
                    if constexpr (kAgc) lumaSum = _mm512_add_epi32(lumaSum, gv);
                }
            } else {
                _mm512_store_si512(px, xa);
                _mm512_store_si512(px + 8, xb);
                _mm512_store_si512(py, ya);
                _mm512_store_si512(py + 8, yb);
                ArrayPositions pos{px, py, kSlot16};
                out = writePixels<kFormat, kGain, kAgc>(s, pos, 16, gainQ8, out, luma);
            }
            xa = _mm512_add_epi64(xa, sxa);
            xb = _mm512_add_epi64(xb, _mm512_add_epi64(sxa, ddx128));
            ya = _mm512_add_epi64(ya, sya);
            yb = _mm512_add_epi64(yb, _mm512_add_epi64(sya, ddy128));
            sxa = _mm512_add_epi64(sxa, ddx256);
            sya = _mm512_add_epi64(sya, ddy256);
        }
        if (i < width) {
            _mm512_store_si512(px, xa);
            _mm512_store_si512(px + 8, xb);
            _mm512_store_si512(py, ya);
            _mm512_store_si512(py + 8, yb);
            ArrayPositions pos{px, py, kSlot16};
            writePixels<kFormat, kGain, kAgc>(s, pos, width - i, gainQ8, out, luma);
        }
        if constexpr (kAgc) {
            luma += static_cast<std::uint32_t>(_mm512_reduce_add_epi32(lumaSum));
        }
    }
    return {s.edge, luma};
}

}  // namespace

VIG_TARGET_AVX512 void skyRowAvx512(const SkyRow& row, int n, double* t, std::uint8_t* above) {
    // OutsideFill::colorAt's operations in its order (this file is built without contraction).
    const __m512d half = _mm512_set_pd(7.5, 6.5, 5.5, 4.5, 3.5, 2.5, 1.5, 0.5);
    const __m512d sx = _mm512_set1_pd(row.sx), cx = _mm512_set1_pd(row.cx);
    const __m512d fz = _mm512_set1_pd(row.fz), rz = _mm512_set1_pd(row.rz);
    const __m512d vz = _mm512_set1_pd(row.vz), ff = _mm512_set1_pd(row.ff);
    const __m512d vv = _mm512_set1_pd(row.vv), zero = _mm512_setzero_pd();
    const __m512d one = _mm512_set1_pd(1.0);
    for (int k = 0; k < n; k += 8) {
        const __m512d x = _mm512_add_pd(_mm512_set1_pd(static_cast<double>(row.x0 + k)), half);
        const __m512d u = _mm512_sub_pd(_mm512_mul_pd(sx, x), cx);
        const __m512d dz = _mm512_sub_pd(_mm512_add_pd(fz, _mm512_mul_pd(u, rz)), vz);
        const __m512d len =
            _mm512_sqrt_pd(_mm512_add_pd(_mm512_add_pd(ff, _mm512_mul_pd(u, u)), vv));
        const __m512d c = _mm512_min_pd(_mm512_max_pd(_mm512_div_pd(dz, len), zero), one);
        _mm512_storeu_pd(t + k, _mm512_sqrt_pd(c));
        const __mmask8 up = _mm512_cmp_pd_mask(dz, zero, _CMP_GT_OQ);
        _mm_storel_epi64(reinterpret_cast<__m128i*>(above + k),
                         _mm_maskz_mov_epi8(static_cast<__mmask16>(up), _mm_set1_epi8(1)));
    }
}

ApplyResult applyQuadraticAvx512(const SourceView& source, const Quadratic& sourceFromOutput,
                                 const FieldView& field, int gainQ8, bool agc) {
    return dispatchKernel(field.format, gainQ8, agc, [&]<PixelFormat F, bool G, bool A>() {
        return quadraticAvx512<F, G, A>(source, sourceFromOutput, field, gainQ8);
    });
}

}  // namespace prp::detail

#endif  // VIG_PRP_HAVE_AVX2
