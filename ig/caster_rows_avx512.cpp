// The row batches on eight lanes (AVX-512): RowBatches<V8> (caster_rows.hpp). This object is
// compiled for AVX-512 F/DQ/VL/BW (ig/CMakeLists.txt) and its kernel is called only where the
// processor has them (base::cpuFeatures). Everything it defines has internal linkage but
// rows_avx512::kernel() (docs/design/multires.md, "One object per instruction set").
#include "ig/fast_column.hpp"

#if VIG_CASTER_WIDE && defined(__AVX512F__) && defined(__AVX512DQ__) && defined(__AVX512VL__) && \
    defined(__AVX512BW__)
#include <immintrin.h>

#include <cstdint>
#include <cstring>
#include <utility>

namespace ig::fast {
namespace {

// The primitives on eight lanes, those that the shared operations (caster_lanes.hpp:
// cellColors) call declared before it. (The masked forms with every lane set: GCC 12 warns of
// the unmasked ones' undefined source.)
using V8 = double __attribute__((vector_size(64)));
using M8 = decltype(V8{} < V8{});

[[gnu::always_inline]] inline V8 vsqrt(V8 v) {
    return reinterpret_cast<V8>(_mm512_maskz_sqrt_pd(0xFF, reinterpret_cast<__m512d>(v)));
}
[[gnu::always_inline]] inline V8 vfloor(V8 v) {
    return reinterpret_cast<V8>(_mm512_maskz_roundscale_pd(
        0xFF, reinterpret_cast<__m512d>(v), _MM_FROUND_TO_NEG_INF | _MM_FROUND_NO_EXC));
}
[[gnu::always_inline]] inline int vmask(M8 m) {
    return static_cast<int>(_mm512_movepi64_mask(reinterpret_cast<__m512i>(m)));
}
[[gnu::always_inline]] inline V8 toV8(__m256i v) {
    return reinterpret_cast<V8>(_mm512_maskz_cvtepi32_pd(0xFF, v));
}
// Whether the eight 32-bit lanes of v are equal.
[[gnu::always_inline]] inline bool sameInAllLanes(__m256i v) {
    const __m256i first = _mm256_broadcastd_epi32(_mm256_castsi256_si128(v));
    return _mm256_movemask_epi8(_mm256_cmpeq_epi32(v, first)) == -1;
}
// The 32 bits at byte offset scale * idx from base, eight lanes (as gather32: 64-bit offsets).
template <int kScale>
[[gnu::always_inline]] inline __m256i gather32(const void* base, V8 idx) {
    alignas(64) std::int64_t i[8];
    _mm512_store_si512(i, _mm512_cvttpd_epi64(reinterpret_cast<__m512d>(idx)));
    const auto* b = static_cast<const unsigned char*>(base);
    int v[8];
    for (int l = 0; l < 8; ++l)
        std::memcpy(&v[l], b + i[l] * kScale, 4);
    return _mm256_setr_epi32(v[0], v[1], v[2], v[3], v[4], v[5], v[6], v[7]);
}

// The eight 16-bit heights h[o[l] + add] in one register.
template <int... kLane>
[[gnu::always_inline]] inline __m128i heights16(const std::uint16_t* h, const std::ptrdiff_t* o,
                                                std::ptrdiff_t add,
                                                std::integer_sequence<int, kLane...>) {
    __m128i v = _mm_setzero_si128();
    ((v = _mm_insert_epi16(v, h[o[kLane] + add], kLane)), ...);
    return v;
}

[[gnu::always_inline]] inline V8 texelChannel(__m256i texels, int k) {
    return toV8(_mm256_and_si256(_mm256_srl_epi32(texels, _mm_cvtsi32_si128(8 * k)),
                                 _mm256_set1_epi32(0xFF)));
}
[[gnu::always_inline]] inline __m256i texelsFromEarlier(__m256i texels) {
    return _mm256_srli_epi32(texels, 8);
}

}  // namespace
}  // namespace ig::fast

#include "ig/caster_lanes.hpp"

namespace ig::fast {
namespace {

// sampleLine on eight lanes.
template <bool kMajorX>
[[gnu::always_inline]] inline LineN<V8> sampleLine(const MapView& mv, long line, V8 n,
                                                   double lastN) {
    const V8 i = vmin(vfloor(n), V8{} + (lastN - 1.0));
    const V8 f = n - i;
    const __m256i ii = _mm512_maskz_cvttpd_epi32(0xFF, reinterpret_cast<__m512d>(i));
    const std::uint16_t* h = mv.heights;
    const int w = mv.width;
    __m256i a, b;
    if (kMajorX) {
        // Minor along y: the two samples are a row apart (64-bit offsets, as sampleLine).
        const std::ptrdiff_t wr = w;
        const std::uint16_t* col = h + line;
        if (sameInAllLanes(ii)) {
            const std::uint16_t* p0 = col + _mm256_cvtsi256_si32(ii) * wr;
            const V8 h0 = V8{} + static_cast<double>(p0[0]);
            const V8 h1 = V8{} + static_cast<double>(p0[wr]);
            return {h0 + f * (h1 - h0), h0, h1, i};
        }
        alignas(32) int r[8];
        _mm256_store_si256(reinterpret_cast<__m256i*>(r), ii);
        std::ptrdiff_t o[8];
        for (int l = 0; l < 8; ++l)
            o[l] = line + r[l] * wr;
        const auto lanes = std::make_integer_sequence<int, 8>{};
        a = _mm256_cvtepu16_epi32(heights16(h, o, 0, lanes));
        b = _mm256_cvtepu16_epi32(heights16(h, o, wr, lanes));
    } else {
        // Minor along x: the two samples are adjacent, one 32-bit load.
        const auto* row = reinterpret_cast<const unsigned char*>(h + line * w);
        if (sameInAllLanes(ii)) {
            std::uint32_t v0;
            std::memcpy(&v0, row + 2 * static_cast<std::ptrdiff_t>(_mm256_cvtsi256_si32(ii)), 4);
            const V8 h0 = V8{} + static_cast<double>(v0 & 0xFFFFu);
            const V8 h1 = V8{} + static_cast<double>(v0 >> 16);
            return {h0 + f * (h1 - h0), h0, h1, i};
        }
        const __m256i g = gather32<2>(row, i);
        a = _mm256_and_si256(g, _mm256_set1_epi32(0xFFFF));
        b = _mm256_srli_epi32(g, 16);
    }
    const V8 h0 = toV8(a), h1 = toV8(b);
    return {h0 + f * (h1 - h0), h0, h1, i};
}

// quantizeLanes on eight lanes.
[[gnu::always_inline]] inline void quantizeLanes(const V8 rgb[3], Rgb8* c) {
    __m256i q[3];
    for (int ch = 0; ch < 3; ++ch) {
        __m256 v = _mm512_maskz_cvtpd_ps(0xFF, reinterpret_cast<__m512d>(rgb[ch]));
        v = _mm256_add_ps(v, _mm256_set1_ps(0.5f));
        v = _mm256_min_ps(_mm256_max_ps(v, _mm256_setzero_ps()), _mm256_set1_ps(255.0f));
        q[ch] = _mm256_cvttps_epi32(v);
    }
    storeRgb(_mm256_castsi256_si128(q[0]), _mm256_castsi256_si128(q[1]),
             _mm256_castsi256_si128(q[2]), c);
    storeRgb(_mm256_extracti128_si256(q[0], 1), _mm256_extracti128_si256(q[1], 1),
             _mm256_extracti128_si256(q[2], 1), c + 4);
}

}  // namespace
}  // namespace ig::fast

#include "ig/caster_rows.hpp"

namespace ig::rows_avx512 {

fast::RowKernel kernel() {
    return {8, &fast::RowBatches<fast::V8>::run, &fast::RowBatches<fast::V8>::cast};
}

}  // namespace ig::rows_avx512

#else

namespace ig::rows_avx512 {

fast::RowKernel kernel() {
    return {};
}

}  // namespace ig::rows_avx512

#endif
