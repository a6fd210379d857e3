// The span caster's resample (docs/design/span_renderer.md, "Resample"): a blocked transpose of
// a strip of rows out of the column-major plane, then each output row from its plane row with
// 32.32 fixed-point positions, 8-bit weights and two colour channels per 32-bit word; a plain
// copy where the row's columns are the image's (stretch 1 on whole columns: pitch 0).
#include "ig/span_resample.hpp"

#include "ig/frame.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

namespace ig {

namespace {

template <class T>
void transposePlain(const T* colMajor, int height, int j0, int j1, int y0, int y1, T* rows,
                    int stride) {
    for (int y = y0; y < y1; ++y)
        for (int j = j0; j < j1; ++j)
            rows[static_cast<std::size_t>(y - y0) * stride + (j - j0)] =
                colMajor[static_cast<std::size_t>(j) * height + y];
}

template <class T>
void transposeBlocked(const T* colMajor, int height, int j0, int j1, int y0, int y1, T* rows,
                      int stride) {
    static_assert(sizeof(T) == 4);
    int y = y0;
#if defined(__SSE2__)
    const auto col = [&](int j, int yy) {
        return colMajor + static_cast<std::size_t>(j) * height + yy;
    };
    for (; y + 4 <= y1; y += 4) {
        T* const r0 = rows + static_cast<std::size_t>(y - y0) * stride - j0;
        int j = j0;
        for (; j + 4 <= j1; j += 4) {
            // Four columns' four rows, then the 4x4 transpose: rows' four columns.
            const __m128i a = _mm_loadu_si128(reinterpret_cast<const __m128i*>(col(j, y)));
            const __m128i b = _mm_loadu_si128(reinterpret_cast<const __m128i*>(col(j + 1, y)));
            const __m128i c = _mm_loadu_si128(reinterpret_cast<const __m128i*>(col(j + 2, y)));
            const __m128i d = _mm_loadu_si128(reinterpret_cast<const __m128i*>(col(j + 3, y)));
            const __m128i ab0 = _mm_unpacklo_epi32(a, b), ab1 = _mm_unpackhi_epi32(a, b);
            const __m128i cd0 = _mm_unpacklo_epi32(c, d), cd1 = _mm_unpackhi_epi32(c, d);
            _mm_storeu_si128(reinterpret_cast<__m128i*>(r0 + j), _mm_unpacklo_epi64(ab0, cd0));
            _mm_storeu_si128(reinterpret_cast<__m128i*>(r0 + stride + j),
                             _mm_unpackhi_epi64(ab0, cd0));
            _mm_storeu_si128(reinterpret_cast<__m128i*>(r0 + 2 * stride + j),
                             _mm_unpacklo_epi64(ab1, cd1));
            _mm_storeu_si128(reinterpret_cast<__m128i*>(r0 + 3 * stride + j),
                             _mm_unpackhi_epi64(ab1, cd1));
        }
        if (j < j1) transposePlain(colMajor, height, j, j1, y, y + 4, r0 + j, stride);
    }
#endif
    if (y < y1)
        transposePlain(colMajor, height, j0, j1, y, y1,
                       rows + static_cast<std::size_t>(y - y0) * stride, stride);
}

}  // namespace

void spanTranspose(const std::uint32_t* colMajor, int height, int j0, int j1, int y0, int y1,
                   std::uint32_t* rows, int stride) {
    transposeBlocked(colMajor, height, j0, j1, y0, y1, rows, stride);
}
void spanTranspose(const float* colMajor, int height, int j0, int j1, int y0, int y1, float* rows,
                   int stride) {
    transposeBlocked(colMajor, height, j0, j1, y0, y1, rows, stride);
}
void spanTransposeReference(const std::uint32_t* colMajor, int height, int j0, int j1, int y0,
                            int y1, std::uint32_t* rows, int stride) {
    transposePlain(colMajor, height, j0, j1, y0, y1, rows, stride);
}

SpanRowMap spanRowMap(double firstColumn, double stretch) {
    constexpr double kOne = 4294967296.0;  // 2^32
    return {static_cast<std::int64_t>(std::llround(firstColumn * kOne)),
            static_cast<std::int64_t>(std::llround(stretch * kOne))};
}

namespace {

// Column and 8-bit weight of a 32.32 position rounded to 1/256 of a column.
inline void columnWeight(std::int64_t pos, int& j, std::uint32_t& w) {
    const std::int64_t q = (pos + (std::int64_t{1} << 23)) >> 24;
    j = static_cast<int>(q >> 8);
    w = static_cast<std::uint32_t>(q & 255);
}

inline float depthMix(float da, float db, std::uint32_t w) {
    const float lo = std::min(da, db), hi = std::max(da, db);
    return lo < kSkyDepth && hi <= 1.05f * lo ? da + (db - da) * (static_cast<float>(w) * 0x1p-8f)
                                              : (w < 128 ? da : db);
}

}  // namespace

void spanResampleRowReference(const std::uint32_t* color, const float* depth, SpanRowMap map,
                              int width, Rgb8* outColor, float* outDepth) {
    for (int x = 0; x < width; ++x) {
        int j;
        std::uint32_t w;
        columnWeight(map.first + x * map.step, j, w);
        std::uint8_t c[3];
        for (int ch = 0; ch < 3; ++ch) {
            const std::uint32_t a = color[j] >> (8 * ch) & 255u;
            if (w == 0) {
                c[ch] = static_cast<std::uint8_t>(a);
                continue;
            }
            const std::uint32_t b = color[j + 1] >> (8 * ch) & 255u;
            c[ch] = static_cast<std::uint8_t>((a * (256u - w) + b * w + 128u) >> 8);
        }
        outColor[x] = Rgb8{c[0], c[1], c[2]};
        outDepth[x] = w == 0 ? depth[j] : depthMix(depth[j], depth[j + 1], w);
    }
}

void spanResampleRow(const std::uint32_t* __restrict__ color, const float* __restrict__ depth,
                     SpanRowMap map, int width, Rgb8* __restrict__ outColor,
                     float* __restrict__ outDepth) {
    if (width <= 0) return;
    auto* const out = reinterpret_cast<std::uint8_t*>(outColor);
    // A packed colour to three bytes: four-byte stores (the next pixel's store overwrites the
    // fourth) but for the row's last pixel.
    const auto put = [out](int x, std::uint32_t c) { std::memcpy(out + 3 * x, &c, 4); };
    const auto putLast = [out](int x, std::uint32_t c) { std::memcpy(out + 3 * x, &c, 3); };
    constexpr std::int64_t kOne = std::int64_t{1} << 32;
    if (map.step == kOne && (map.first & (kOne - 1)) == 0) {
        // The row's columns are the image's: a copy.
        const std::int64_t j0 = map.first >> 32;
        const std::uint32_t* __restrict__ c = color + j0;
        for (int x = 0; x + 1 < width; ++x)
            put(x, c[x]);
        putLast(width - 1, c[width - 1]);
        std::memcpy(outDepth, depth + j0, static_cast<std::size_t>(width) * sizeof(float));
        return;
    }
    std::int64_t pos = map.first;
    int x0 = 0;
#if defined(__SSE2__)
    // Four pixels at a time: their columns and weights, the gathered pairs, then the mixes on
    // 16-bit lanes (the products fit: 255 * 256 + 128 < 2^16) and the depths by masks.
    const __m128i zero = _mm_setzero_si128(), round = _mm_set1_epi16(128);
    const __m128i w256 = _mm_set1_epi16(256);
    const __m128 kStep = _mm_set1_ps(0x1p-8f), kNear = _mm_set1_ps(1.05f);
    const __m128 kSky = _mm_set1_ps(kSkyDepth);
    const __m128i half = _mm_set1_epi32(128);
    alignas(16) std::uint32_t packed[4];
    for (; x0 + 5 <= width; x0 += 4) {
        int j[4];
        std::uint32_t w[4];
        for (int i = 0; i < 4; ++i) {
            columnWeight(pos, j[i], w[i]);
            pos += map.step;
        }
        const __m128i ca =
            _mm_set_epi32(static_cast<int>(color[j[3]]), static_cast<int>(color[j[2]]),
                          static_cast<int>(color[j[1]]), static_cast<int>(color[j[0]]));
        const __m128i cb =
            _mm_set_epi32(static_cast<int>(color[j[3] + 1]), static_cast<int>(color[j[2] + 1]),
                          static_cast<int>(color[j[1] + 1]), static_cast<int>(color[j[0] + 1]));
        const __m128i wv = _mm_set_epi32(static_cast<int>(w[3]), static_cast<int>(w[2]),
                                         static_cast<int>(w[1]), static_cast<int>(w[0]));
        // Each pixel's weight on its four 16-bit channel lanes.
        const __m128i w16 = _mm_packs_epi32(wv, wv);       // w0 w1 w2 w3 w0 w1 w2 w3
        const __m128i wLo = _mm_unpacklo_epi16(w16, w16);  // w0 w0 w1 w1 w2 w2 w3 w3
        const __m128i wA = _mm_unpacklo_epi32(wLo, wLo);   // w0 x4, w1 x4
        const __m128i wB = _mm_unpackhi_epi32(wLo, wLo);   // w2 x4, w3 x4
        auto mix = [&](__m128i a, __m128i b, __m128i wt) {
            const __m128i p =
                _mm_add_epi16(_mm_mullo_epi16(a, _mm_sub_epi16(w256, wt)), _mm_mullo_epi16(b, wt));
            return _mm_srli_epi16(_mm_add_epi16(p, round), 8);
        };
        const __m128i lo = mix(_mm_unpacklo_epi8(ca, zero), _mm_unpacklo_epi8(cb, zero), wA);
        const __m128i hi = mix(_mm_unpackhi_epi8(ca, zero), _mm_unpackhi_epi8(cb, zero), wB);
        _mm_store_si128(reinterpret_cast<__m128i*>(packed), _mm_packus_epi16(lo, hi));
        for (int i = 0; i < 4; ++i)
            put(x0 + i, packed[i]);
        const __m128 da = _mm_set_ps(depth[j[3]], depth[j[2]], depth[j[1]], depth[j[0]]);
        const __m128 db =
            _mm_set_ps(depth[j[3] + 1], depth[j[2] + 1], depth[j[1] + 1], depth[j[0] + 1]);
        const __m128 dmin = _mm_min_ps(da, db), dmax = _mm_max_ps(da, db);
        const __m128 smooth =
            _mm_and_ps(_mm_cmplt_ps(dmin, kSky), _mm_cmple_ps(dmax, _mm_mul_ps(kNear, dmin)));
        const __m128 lerp =
            _mm_add_ps(da, _mm_mul_ps(_mm_sub_ps(db, da), _mm_mul_ps(_mm_cvtepi32_ps(wv), kStep)));
        const __m128 far = _mm_castsi128_ps(_mm_cmplt_epi32(wv, half));  // w < 128: j's
        const __m128 nearer = _mm_or_ps(_mm_and_ps(far, da), _mm_andnot_ps(far, db));
        _mm_storeu_ps(outDepth + x0,
                      _mm_or_ps(_mm_and_ps(smooth, lerp), _mm_andnot_ps(smooth, nearer)));
    }
#endif
    auto pixel = [&](int x) {
        int j;
        std::uint32_t w;
        columnWeight(pos, j, w);
        pos += map.step;
        const std::uint32_t ca = color[j], cb = color[j + 1];
        const std::uint32_t rb =
            ((ca & 0xff00ffu) * (256u - w) + (cb & 0xff00ffu) * w + 0x800080u) >> 8 & 0xff00ffu;
        const std::uint32_t g =
            ((ca & 0xff00u) * (256u - w) + (cb & 0xff00u) * w + 0x8000u) >> 8 & 0xff00u;
        outDepth[x] = w == 0 ? depth[j] : depthMix(depth[j], depth[j + 1], w);
        return rb | g;
    };
    for (int x = x0; x + 1 < width; ++x)
        put(x, pixel(x));
    putLast(width - 1, pixel(width - 1));
}

}  // namespace ig
