// The quadratic field warp eight pixels at a time with AVX2, bit-identical to the scalar kernel.
//
// Why it matches bit for bit:
// - Source points: each lane keeps the scalar recurrence's 64-bit point of its own pixel and
//   moves 8 pixels per step, x += 8 dx + 28 ddx (dx being that pixel's first difference, so the
//   step itself grows by 64 ddx). Integer addition is associative (and wraps the same way), so
//   every lane holds exactly the scalar's value at its pixel.
// - Bilinear: the scalar result is (sum of the taps' (256 - f, f) weight products + 2^15) >> 16
//   with no intermediate rounding; the horizontal taps are one _mm256_madd_epi16 per channel,
//   the vertical step the same exact 32-bit sum.
// - Colour: the same integer BT.601 formulas; kYg > 32767 does not fit a signed 16-bit madd
//   word, so it is applied as kYg - 65536 and G << 16 added back.
// - A group with any lane outside the clamp-free interior (0 <= x0 <= w - 3,
//   0 <= y0 <= h - 2), and the row's last width % 8 pixels, go through the scalar code on the
//   lanes' own points, which clamps and counts edge samples exactly as the scalar kernel does.
//   Interior samples are never edge samples, so the count is the same.
// The x0 <= w - 3 bound keeps the 8-byte loads of the taps (x0, x0 + 1) inside the image.
#include "prp/warp_apply_simd.hpp"

#if VIG_PRP_HAVE_AVX2

#include <cstring>
#include <type_traits>

namespace prp::detail {

namespace {

using namespace simd;

// Eight copies of a constant, loaded from memory: the empty asm hides the value from the
// compiler, which would otherwise rebuild it in the loop with a broadcast (a shuffle-unit uop).
template <int kValue>
struct Splat8 {
    alignas(32) static constexpr std::int32_t lanes[8] = {kValue, kValue, kValue, kValue,
                                                          kValue, kValue, kValue, kValue};
};
template <int kValue>
VIG_TARGET_AVX2 inline __m256i splat() {
    __m256i v = _mm256_load_si256(reinterpret_cast<const __m256i*>(Splat8<kValue>::lanes));
    __asm__("" : "+x"(v));
    return v;
}

// Lane slots of the 8 pixels of a group in the two 64-bit position registers: register a
// holds pixels 0, 1, 4, 5 and b holds 2, 3, 6, 7, so that one _mm256_shuffle_ps of (a, b)
// gives a dword per pixel in natural order.
constexpr int kSlot[8] = {0, 1, 4, 5, 2, 3, 6, 7};

// Vertical step of the bilinear sample before its final shift: top (256 - fy) + bot fy + 2^15
// (= (top << 8) + (bot - top) fy + 2^15); the value is in bits 16..23.
VIG_TARGET_AVX2 inline __m256i lerpRows(__m256i top, __m256i bot, __m256i fy, __m256i fy1) {
    return _mm256_add_epi32(
        _mm256_add_epi32(_mm256_mullo_epi32(top, fy1), _mm256_mullo_epi32(bot, fy)),
        splat<1 << 15>());
}

// min(255, (c gain + 128) >> 8) as the scalar applyGain.
VIG_TARGET_AVX2 inline __m256i gainOf(__m256i c, __m256i gain) {
    const __m256i v =
        _mm256_srai_epi32(_mm256_add_epi32(_mm256_mullo_epi32(c, gain), splat<128>()), 8);
    return _mm256_min_epi32(v, splat<255>());
}

// Full-range grey of 8 pixels given RG = R | G << 16 and B (dwords).
VIG_TARGET_AVX2 inline __m256i greyOf8(__m256i rg, __m256i b) {
    const __m256i v = _mm256_add_epi32(_mm256_madd_epi16(rg, splat<words(kGr, kGg)>()),
                                       _mm256_madd_epi16(b, splat<kGb>()));
    return _mm256_srli_epi32(_mm256_add_epi32(v, splat<128>()), 8);
}

VIG_TARGET_AVX2 inline __m256i load(const std::int64_t* p) {
    return _mm256_load_si256(reinterpret_cast<const __m256i*>(p));
}

VIG_TARGET_AVX2 inline void store(std::int64_t* p, __m256i v) {
    _mm256_store_si256(reinterpret_cast<__m256i*>(p), v);
}

// Sum of the 8 dword lanes.
VIG_TARGET_AVX2 inline std::uint64_t sumLanes(__m256i v) {
    alignas(32) std::uint32_t lanes[8];
    _mm256_store_si256(reinterpret_cast<__m256i*>(lanes), v);
    std::uint64_t sum = 0;
    for (const std::uint32_t l : lanes)
        sum += l;
    return sum;
}

// Integer parts (high dwords) of the 64-bit lanes a (pixels 0, 1, 4, 5), b (2, 3, 6, 7), in
// pixel order.
VIG_TARGET_AVX2 inline __m256i highDwords(__m256i a, __m256i b) {
    return _mm256_castps_si256(
        _mm256_shuffle_ps(_mm256_castsi256_ps(a), _mm256_castsi256_ps(b), _MM_SHUFFLE(3, 1, 3, 1)));
}

// 8-bit fractions (top byte of the low dwords) of the same lanes, in pixel order.
VIG_TARGET_AVX2 inline __m256i fractions(__m256i a, __m256i b) {
    return _mm256_srli_epi32(
        _mm256_castps_si256(_mm256_shuffle_ps(_mm256_castsi256_ps(a), _mm256_castsi256_ps(b),
                                              _MM_SHUFFLE(2, 0, 2, 0))),
        24);
}

// Source points of the quadratic: each lane keeps the scalar recurrence's point of its pixel.
struct QuadraticLanes {
    QuadraticRows rows;
    __m256i xa, xb, ya, yb;  // 64-bit points of pixels 0, 1, 4, 5 (a) and 2, 3, 6, 7 (b)
    __m256i sxa, sya, ddx16, ddy16, ddx64, ddy64;

    VIG_TARGET_AVX2 void start(int frameLine) {
        alignas(32) std::int64_t px[8], py[8], psx[8], psy[8];
        rows.start(frameLine + 0.5);
        // Lane k starts at pixel k of the scalar recurrence (wrapping arithmetic, as the lanes'
        // adds) and moves 8 pixels per step: x += sx, sx += 64 ddx with sx = 8 dx + 28 ddx.
        std::uint64_t x = static_cast<std::uint64_t>(rows.x);
        std::uint64_t y = static_cast<std::uint64_t>(rows.y);
        std::uint64_t dx = static_cast<std::uint64_t>(rows.dx);
        std::uint64_t dy = static_cast<std::uint64_t>(rows.dy);
        const std::uint64_t ddx = static_cast<std::uint64_t>(rows.ddx);
        const std::uint64_t ddy = static_cast<std::uint64_t>(rows.ddy);
        for (int k = 0; k < 8; ++k) {
            px[kSlot[k]] = static_cast<std::int64_t>(x);
            py[kSlot[k]] = static_cast<std::int64_t>(y);
            psx[kSlot[k]] = static_cast<std::int64_t>(8 * dx + 28 * ddx);
            psy[kSlot[k]] = static_cast<std::int64_t>(8 * dy + 28 * ddy);
            x += dx;
            dx += ddx;
            y += dy;
            dy += ddy;
        }
        xa = load(px);
        xb = load(px + 4);
        ya = load(py);
        yb = load(py + 4);
        // Slots b are 2 pixels ahead of slots a: their steps are 16 dd larger.
        sxa = load(psx);
        sya = load(psy);
        ddx16 = _mm256_set1_epi64x(static_cast<long long>(16 * ddx));
        ddy16 = _mm256_set1_epi64x(static_cast<long long>(16 * ddy));
        ddx64 = _mm256_set1_epi64x(static_cast<long long>(64 * ddx));
        ddy64 = _mm256_set1_epi64x(static_cast<long long>(64 * ddy));
    }
    VIG_TARGET_AVX2 void step() {
        xa = _mm256_add_epi64(xa, sxa);
        xb = _mm256_add_epi64(xb, _mm256_add_epi64(sxa, ddx16));
        ya = _mm256_add_epi64(ya, sya);
        yb = _mm256_add_epi64(yb, _mm256_add_epi64(sya, ddy16));
        sxa = _mm256_add_epi64(sxa, ddx64);
        sya = _mm256_add_epi64(sya, ddy64);
    }
};

// Source points given per pixel (16.16, minus half a pixel), one array pair per field line,
// widened to the sampler's 32.32.
struct ArrayLanes {
    const std::int32_t* xs;  // line L's points at xs + L * stride
    const std::int32_t* ys;
    std::size_t stride;
    const std::int32_t* x = nullptr;
    const std::int32_t* y = nullptr;
    __m256i xa, xb, ya, yb;

    VIG_TARGET_AVX2 void start(int line) {
        x = xs + static_cast<std::size_t>(line) * stride;
        y = ys + static_cast<std::size_t>(line) * stride;
    }
    // Loads the next 8 points: called only when 8 more pixels follow (the caller's loop bound).
    VIG_TARGET_AVX2 void read() {
        // Natural order (0 1 2 3 | 4 5 6 7) to the slots: a = 0 1 4 5, b = 2 3 6 7.
        constexpr int kShift = kFracBits - kPointFracBits;
        const __m256i xi = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(x));
        const __m256i yi = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(y));
        const __m256i x0 =
            _mm256_slli_epi64(_mm256_cvtepi32_epi64(_mm256_castsi256_si128(xi)), kShift);
        const __m256i x1 =
            _mm256_slli_epi64(_mm256_cvtepi32_epi64(_mm256_extracti128_si256(xi, 1)), kShift);
        const __m256i y0 =
            _mm256_slli_epi64(_mm256_cvtepi32_epi64(_mm256_castsi256_si128(yi)), kShift);
        const __m256i y1 =
            _mm256_slli_epi64(_mm256_cvtepi32_epi64(_mm256_extracti128_si256(yi, 1)), kShift);
        xa = _mm256_permute2x128_si256(x0, x1, 0x20);
        xb = _mm256_permute2x128_si256(x0, x1, 0x31);
        ya = _mm256_permute2x128_si256(y0, y1, 0x20);
        yb = _mm256_permute2x128_si256(y0, y1, 0x31);
    }
    VIG_TARGET_AVX2 void step() {
        x += 8;
        y += 8;
    }
};

// Flattened: what it calls from the shared kernel header for the pixels the vector code leaves
// to the scalar code (writePixels, Sampler::sample: edges, a line's last width % 8) is inlined
// here, so that no weak symbol is left for the linker to share with the baseline objects
// (scripts/isa-symbols.sh, prp.isa_objects_share_no_code). Measured (callgrind, bench-warp,
// valgrind's AVX2): 1 % fewer instructions a field than with the sampler out of line.
template <PixelFormat kFormat, bool kGain, bool kAgc, class Lanes>
[[gnu::flatten]] VIG_TARGET_AVX2 ApplyResult warpAvx2(const SourceView& source, Lanes& lanes,
                                                      const FieldView& field, int gainQ8) {
    Sampler s(source);
    std::uint64_t luma = 0;
    const int width = field.width;
    const std::uint8_t* row0 = s.base;
    const std::uint8_t* row1 = s.base + s.rowBytes;
    const __m256i rowBytes = _mm256_set1_epi32(static_cast<int>(s.rowBytes));
    const __m256i limX = _mm256_set1_epi32(source.width - 3);
    const __m256i limY = _mm256_set1_epi32(source.height - 2);
    const __m256i gain = _mm256_set1_epi32(gainQ8);
    // Per 128-bit lane two 8-byte loads (pixels q0, q1: R0 G0 B0 R1 G1 B1 . .) become the tap
    // pairs of each channel as 16-bit words: (R0 R1)q0 (R0 R1)q1 (G0 G1)q0 (G0 G1)q1, and
    // (B0 B1)q0 (B0 B1)q1.
    const __m256i pickRG =
        _mm256_setr_epi8(0, -1, 3, -1, 8, -1, 11, -1, 1, -1, 4, -1, 9, -1, 12, -1, 0, -1, 3, -1, 8,
                         -1, 11, -1, 1, -1, 4, -1, 9, -1, 12, -1);
    const __m256i pickB =
        _mm256_setr_epi8(2, -1, 5, -1, 10, -1, 13, -1, -1, -1, -1, -1, -1, -1, -1, -1, 2, -1, 5, -1,
                         10, -1, 13, -1, -1, -1, -1, -1, -1, -1, -1, -1);
    const __m256i pack3 = _mm256_setr_epi8(0, 1, 2, 4, 5, 6, 8, 9, 10, 12, 13, 14, -1, -1, -1, -1,
                                           0, 1, 2, 4, 5, 6, 8, 9, 10, 12, 13, 14, -1, -1, -1, -1);
    // UYVY: lane k carries Cb (even k) or Cr (odd k) of pair k / 2.
    const __m256i chromaRG = _mm256_setr_epi32(
        words(kCbR, kCbG), words(kCrR, kCrG), words(kCbR, kCbG), words(kCrR, kCrG),
        words(kCbR, kCbG), words(kCrR, kCrG), words(kCbR, kCbG), words(kCrR, kCrG));
    const __m256i chromaB =
        _mm256_setr_epi32(words(kCbB, 0), words(kCrB, 0), words(kCbB, 0), words(kCrB, 0),
                          words(kCbB, 0), words(kCrB, 0), words(kCbB, 0), words(kCrB, 0));

    alignas(32) std::int64_t px[8], py[8];
    for (int line = 0; line < field.lines; ++line) {
        std::uint8_t* out = field.pixels + static_cast<std::size_t>(line) * field.stride;
        if constexpr (std::is_same_v<Lanes, QuadraticLanes>) {
            lanes.start(field.firstLine + 2 * line);
        } else {
            lanes.start(line);
        }
        __m256i lumaSum = _mm256_setzero_si256();

        int i = 0;
        for (; i + 8 <= width; i += 8) {
            if constexpr (!std::is_same_v<Lanes, QuadraticLanes>) lanes.read();
            const __m256i xa = lanes.xa, xb = lanes.xb, ya = lanes.ya, yb = lanes.yb;
            const __m256i xi = highDwords(xa, xb), yi = highDwords(ya, yb);
            // Outside the interior: x0 > w - 3, y0 > h - 2 or either negative (sign bit).
            const __m256i outside = _mm256_or_si256(
                _mm256_or_si256(_mm256_cmpgt_epi32(xi, limX), _mm256_cmpgt_epi32(yi, limY)),
                _mm256_or_si256(xi, yi));
            if (_mm256_movemask_ps(_mm256_castsi256_ps(outside)) == 0) {
                const __m256i fx = fractions(xa, xb), fy = fractions(ya, yb);
                // Weights (256 - fx, fx) as a word pair; 256 - fy.
                const __m256i wx =
                    _mm256_add_epi32(_mm256_sub_epi32(_mm256_slli_epi32(fx, 16), fx), splat<256>());
                const __m256i fy1 = _mm256_sub_epi32(splat<256>(), fy);
                const __m256i offset =
                    _mm256_add_epi32(_mm256_mullo_epi32(yi, rowBytes),
                                     _mm256_add_epi32(xi, _mm256_add_epi32(xi, xi)));
                const __m128i offLo = _mm256_castsi256_si128(offset);
                const __m128i offHi = _mm256_extracti128_si256(offset, 1);
                const Offsets2 o01(_mm_cvtsi128_si64(offLo)), o23(_mm_extract_epi64(offLo, 1));
                const Offsets2 o45(_mm_cvtsi128_si64(offHi)), o67(_mm_extract_epi64(offHi, 1));
                // Pixels 0, 1 | 4, 5 and 2, 3 | 6, 7 (low | high 128-bit lane), so that the
                // unpacks below give pixel order.
                const __m256i a0 = load2x2(row0, o01, o45);
                const __m256i b0 = load2x2(row0, o23, o67);
                const __m256i a1 = load2x2(row1, o01, o45);
                const __m256i b1 = load2x2(row1, o23, o67);

                const __m256i rgA0 = _mm256_shuffle_epi8(a0, pickRG);
                const __m256i rgB0 = _mm256_shuffle_epi8(b0, pickRG);
                const __m256i rgA1 = _mm256_shuffle_epi8(a1, pickRG);
                const __m256i rgB1 = _mm256_shuffle_epi8(b1, pickRG);
                const __m256i topR = _mm256_madd_epi16(_mm256_unpacklo_epi64(rgA0, rgB0), wx);
                const __m256i topG = _mm256_madd_epi16(_mm256_unpackhi_epi64(rgA0, rgB0), wx);
                const __m256i botR = _mm256_madd_epi16(_mm256_unpacklo_epi64(rgA1, rgB1), wx);
                const __m256i botG = _mm256_madd_epi16(_mm256_unpackhi_epi64(rgA1, rgB1), wx);
                const __m256i topB =
                    _mm256_madd_epi16(_mm256_unpacklo_epi64(_mm256_shuffle_epi8(a0, pickB),
                                                            _mm256_shuffle_epi8(b0, pickB)),
                                      wx);
                const __m256i botB =
                    _mm256_madd_epi16(_mm256_unpacklo_epi64(_mm256_shuffle_epi8(a1, pickB),
                                                            _mm256_shuffle_epi8(b1, pickB)),
                                      wx);
                const __m256i accR = lerpRows(topR, botR, fy, fy1);
                const __m256i accG = lerpRows(topG, botG, fy, fy1);
                const __m256i accB = lerpRows(topB, botB, fy, fy1);
                __m256i r = _mm256_srli_epi32(accR, 16), b = _mm256_srli_epi32(accB, 16);
                __m256i gHigh;  // G << 16
                if constexpr (kGain) {
                    r = gainOf(r, gain);
                    b = gainOf(b, gain);
                    gHigh = _mm256_slli_epi32(gainOf(_mm256_srli_epi32(accG, 16), gain), 16);
                } else {
                    gHigh = _mm256_and_si256(accG, splat<0xff0000>());
                }
                const __m256i rg = _mm256_or_si256(r, gHigh);

                if constexpr (kFormat == PixelFormat::Uyvy) {
                    // Y' = (kYr R + kYg G + kYb B + ...) >> 16; kYg > 32767 is madd'ed as
                    // kYg - 65536 and G << 16 added back.
                    __m256i yv =
                        _mm256_add_epi32(_mm256_madd_epi16(rg, splat<words(kYr, kYg)>()), gHigh);
                    yv = _mm256_add_epi32(yv, _mm256_madd_epi16(b, splat<kYb>()));
                    yv = _mm256_add_epi32(yv, splat<(16 << 16) + (1 << 15)>());
                    // Pair sums in both lanes of the pair, then Cb or Cr per lane.
                    const __m256i rgSum =
                        _mm256_add_epi32(rg, _mm256_shuffle_epi32(rg, _MM_SHUFFLE(2, 3, 0, 1)));
                    const __m256i bSum =
                        _mm256_add_epi32(b, _mm256_shuffle_epi32(b, _MM_SHUFFLE(2, 3, 0, 1)));
                    __m256i c = _mm256_add_epi32(_mm256_madd_epi16(rgSum, chromaRG),
                                                 _mm256_madd_epi16(bSum, chromaB));
                    c = _mm256_srai_epi32(_mm256_add_epi32(c, splat<(128 << 17) + (1 << 16)>()),
                                          17);
                    // Words C0 Y0 C1 Y1 ... = Cb Y0 Cr Y1 ..., then bytes.
                    const __m256i words16 = _mm256_or_si256(
                        c, _mm256_and_si256(yv, splat<static_cast<int>(0xffff0000u)>()));
                    const __m256i bytes = _mm256_permute4x64_epi64(
                        _mm256_packus_epi16(words16, words16), _MM_SHUFFLE(2, 0, 2, 0));
                    _mm_storeu_si128(reinterpret_cast<__m128i*>(out),
                                     _mm256_castsi256_si128(bytes));
                    out += 16;
                    if constexpr (kAgc) lumaSum = _mm256_add_epi32(lumaSum, greyOf8(rg, b));
                } else if constexpr (kFormat == PixelFormat::Rgb8) {
                    const __m256i rgb = _mm256_shuffle_epi8(
                        _mm256_or_si256(_mm256_or_si256(r, _mm256_srli_epi32(gHigh, 8)),
                                        _mm256_slli_epi32(b, 16)),
                        pack3);
                    // 12 bytes per 128-bit lane: the first store's last 4 bytes are rewritten
                    // by the second.
                    const __m128i hiRgb = _mm256_extracti128_si256(rgb, 1);
                    _mm_storeu_si128(reinterpret_cast<__m128i*>(out), _mm256_castsi256_si128(rgb));
                    _mm_storel_epi64(reinterpret_cast<__m128i*>(out + 12), hiRgb);
                    const int last = _mm_extract_epi32(hiRgb, 2);
                    std::memcpy(out + 20, &last, 4);
                    out += 24;
                    if constexpr (kAgc) lumaSum = _mm256_add_epi32(lumaSum, greyOf8(rg, b));
                } else {
                    const __m256i gv = greyOf8(rg, b);
                    const __m256i packed =
                        _mm256_packus_epi16(_mm256_packus_epi32(gv, gv), _mm256_setzero_si256());
                    const __m256i both = _mm256_permutevar8x32_epi32(
                        packed, _mm256_setr_epi32(0, 4, 0, 0, 0, 0, 0, 0));
                    _mm_storel_epi64(reinterpret_cast<__m128i*>(out), _mm256_castsi256_si128(both));
                    out += 8;
                    if constexpr (kAgc) lumaSum = _mm256_add_epi32(lumaSum, gv);
                }
            } else {
                store(px, xa);
                store(px + 4, xb);
                store(py, ya);
                store(py + 4, yb);
                ArrayPositions pos{px, py, kSlot};
                out = writePixels<kFormat, kGain, kAgc>(s, pos, 8, gainQ8, out, luma);
            }
            lanes.step();
        }
        if (i < width) {
            if constexpr (std::is_same_v<Lanes, QuadraticLanes>) {
                store(px, lanes.xa);
                store(px + 4, lanes.xb);
                store(py, lanes.ya);
                store(py + 4, lanes.yb);
                ArrayPositions pos{px, py, kSlot};
                writePixels<kFormat, kGain, kAgc>(s, pos, width - i, gainQ8, out, luma);
            } else {
                // The line's last width % 8 points, in natural order.
                LinePositions pos{lanes.x, lanes.y};
                writePixels<kFormat, kGain, kAgc>(s, pos, width - i, gainQ8, out, luma);
            }
        }
        if constexpr (kAgc) luma += sumLanes(lumaSum);
    }
    return {s.edge, luma};
}

}  // namespace

ApplyResult applyQuadraticAvx2(const SourceView& source, const Quadratic& sourceFromOutput,
                               const FieldView& field, int gainQ8, bool agc) {
    return dispatchKernel(field.format, gainQ8, agc, [&]<PixelFormat F, bool G, bool A>() {
        QuadraticLanes lanes{
            QuadraticRows{sourceFromOutput}, {}, {}, {}, {}, {}, {}, {}, {}, {}, {}};
        return warpAvx2<F, G, A>(source, lanes, field, gainQ8);
    });
}

ApplyResult applyPointsAvx2(const SourceView& source, const std::int32_t* xs,
                            const std::int32_t* ys, std::size_t stride, const FieldView& field,
                            int gainQ8, bool agc) {
    return dispatchKernel(field.format, gainQ8, agc, [&]<PixelFormat F, bool G, bool A>() {
        ArrayLanes lanes{xs, ys, stride, nullptr, nullptr, {}, {}, {}, {}};
        return warpAvx2<F, G, A>(source, lanes, field, gainQ8);
    });
}

}  // namespace prp::detail

#endif  // VIG_PRP_HAVE_AVX2
