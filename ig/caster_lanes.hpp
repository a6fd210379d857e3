// The fast caster's vector lanes: four doubles with AVX2 (V4) and the primitives on them that
// the four-column packets (caster_packets.cpp) and the row batches (caster_rows.hpp) share, and
// the operations written once for every lane width (vmax, vmin, vclamp01, cellColors). Every
// operation is the one-ray path's, in the same order and precision.
//
// Everything here has internal linkage (an anonymous namespace): each object that includes it
// has its own copies, compiled for its instruction set, and no linker can hand one object's
// copy to another (docs/design/multires.md, "One object per instruction set"). The functions
// carry the AVX2 target attribute, for the packets' object compiled for the baseline; the
// AVX-512 row batches declare their own eight-lane primitives (gather32, texelChannel,
// texelsFromEarlier) before including this header, so that cellColors finds them.
//
// The portable row batches (caster_rows_portable.cpp, the vector kernels' scalar twins) define
// VIG_CASTER_LANES_PORTABLE before including this header: they get the operations written once
// for every lane width, without any target attribute, and declare their own lane-by-lane
// primitives; the x86 primitives are left out.
#pragma once

#include "ig/caster.hpp"
#include "ig/fast_column.hpp"
#include "ig/level0_march.hpp"

#include <cstdint>
#include <cstring>

#if VIG_CASTER_PACKETS
#include <immintrin.h>

#define VIG_CASTER_AVX2 __attribute__((target("avx2")))
#endif

#if VIG_CASTER_LANES_PORTABLE
#define VIG_CASTER_LANES_TARGET
#else
#define VIG_CASTER_LANES_TARGET VIG_CASTER_AVX2
#endif

#if VIG_CASTER_PACKETS || VIG_CASTER_LANES_PORTABLE

namespace ig::fast {
namespace {

// std::max, std::min and std::clamp to [0, 1] on N lanes, with their exact semantics.
template <class V>
[[gnu::always_inline]] VIG_CASTER_LANES_TARGET inline V vmax(V a, V b) {
    return a < b ? b : a;
}
template <class V>
[[gnu::always_inline]] VIG_CASTER_LANES_TARGET inline V vmin(V a, V b) {
    return b < a ? b : a;
}
template <class V>
[[gnu::always_inline]] VIG_CASTER_LANES_TARGET inline V vclamp01(V v) {
    const V zero = V{} + 0.0, one = V{} + 1.0;
    return v < zero ? zero : (one < v ? one : v);
}

// The surface where each lane crosses a level-0 major line, linear along the line:
// lineSample's h, h0, h1 and i (an integer-valued double), lane by lane.
template <class V>
struct LineN {
    V h, h0, h1, i;
};

// One step of a row batch's lanes from major line A to line B (stepHits): A's cell iA
// (an integer-valued double) and the ray's height over A's sample on the side the track
// moves to, dEdgeA; the minor coordinate nA at A; B's ray height zB; the ray's height over
// the surface at A (above) and at B (below); A and B's major distances uA, uB; the step's
// index k.
template <class V>
struct LaneStep {
    V iA, dEdgeA, nA, zB, above, below;
    double uA, uB;
    long k;
};

#if !VIG_CASTER_LANES_PORTABLE
using V4 = double __attribute__((vector_size(32)));
using M4 = decltype(V4{} < V4{});

[[gnu::always_inline]] VIG_CASTER_AVX2 inline V4 vsqrt(V4 v) {
    return reinterpret_cast<V4>(_mm256_sqrt_pd(reinterpret_cast<__m256d>(v)));
}
[[gnu::always_inline]] VIG_CASTER_AVX2 inline V4 vfloor(V4 v) {
    return reinterpret_cast<V4>(_mm256_floor_pd(reinterpret_cast<__m256d>(v)));
}
[[gnu::always_inline]] VIG_CASTER_AVX2 inline int vmask(M4 m) {
    return _mm256_movemask_pd(reinterpret_cast<__m256d>(m));
}
// The 32 bits at byte offset scale * idx from base, four lanes (idx integer-valued, below
// 2^53: 64-bit offsets, a paged map may hold more than 2^31 samples; inactive lanes must carry
// a valid index).
// (Four scalar loads: hardware gathers are slow where microcode guards them.)
template <int kScale>
[[gnu::always_inline]] VIG_CASTER_AVX2 inline __m128i gather32(const void* base, V4 idx) {
    const auto* b = static_cast<const unsigned char*>(base);
    int v[4];
    for (int l = 0; l < 4; ++l)
        std::memcpy(&v[l], b + static_cast<std::ptrdiff_t>(idx[l]) * kScale, 4);
    return _mm_setr_epi32(v[0], v[1], v[2], v[3]);
}
[[gnu::always_inline]] VIG_CASTER_AVX2 inline V4 toV4(__m128i v) {
    return reinterpret_cast<V4>(_mm256_cvtepi32_pd(v));
}

// Channel k (0..2: r, g, b) of four texels gathered as 32-bit lanes (gather32), and the
// texels read from one byte earlier (the last one of the map) moved down to their own r.
[[gnu::always_inline]] VIG_CASTER_AVX2 inline V4 texelChannel(__m128i texels, int k) {
    return toV4(
        _mm_and_si128(_mm_srl_epi32(texels, _mm_cvtsi32_si128(8 * k)), _mm_set1_epi32(0xFF)));
}
[[gnu::always_inline]] VIG_CASTER_AVX2 inline __m128i texelsFromEarlier(__m128i texels) {
    return _mm_srli_epi32(texels, 8);
}

// Whether the four 32-bit lanes of v are equal.
[[gnu::always_inline]] VIG_CASTER_AVX2 inline bool sameInAllLanes(__m128i v) {
    return _mm_movemask_epi8(_mm_cmpeq_epi32(v, _mm_shuffle_epi32(v, 0))) == 0xFFFF;
}

// The surface where each lane crosses level-0 major line `line` at minor coordinate n
// (in [0, lastN] in every lane): lineSample on four lanes.
template <bool kMajorX>
[[gnu::always_inline]] VIG_CASTER_AVX2 inline LineN<V4> sampleLine(const MapView& mv, long line,
                                                                   V4 n, double lastN) {
    const V4 i = vmin(vfloor(n), V4{} + (lastN - 1.0));
    const V4 f = n - i;
    const __m128i ii = _mm256_cvttpd_epi32(reinterpret_cast<__m256d>(i));
    const std::uint16_t* h = mv.heights;
    __m128i a, b;
    if (kMajorX) {
        // Minor along y: the two samples are a row apart (64-bit offsets: a paged map may
        // hold more than 2^31 samples).
        const std::ptrdiff_t w = mv.width;
        const std::uint16_t* col = h + line;
        const std::uint16_t* p0 = col + _mm_cvtsi128_si32(ii) * w;
        if (sameInAllLanes(ii)) {
            // All four tracks cross the line in one cell (common where cells span many
            // pixels): two loads.
            const V4 h0 = V4{} + static_cast<double>(p0[0]);
            const V4 h1 = V4{} + static_cast<double>(p0[w]);
            return {h0 + f * (h1 - h0), h0, h1, i};
        }
        const std::uint16_t* p1 = col + _mm_extract_epi32(ii, 1) * w;
        const std::uint16_t* p2 = col + _mm_extract_epi32(ii, 2) * w;
        const std::uint16_t* p3 = col + _mm_extract_epi32(ii, 3) * w;
        __m128i v = _mm_cvtsi32_si128(p0[0]);
        v = _mm_insert_epi16(v, p1[0], 1);
        v = _mm_insert_epi16(v, p2[0], 2);
        v = _mm_insert_epi16(v, p3[0], 3);
        v = _mm_insert_epi16(v, p0[w], 4);
        v = _mm_insert_epi16(v, p1[w], 5);
        v = _mm_insert_epi16(v, p2[w], 6);
        v = _mm_insert_epi16(v, p3[w], 7);
        a = _mm_cvtepu16_epi32(v);
        b = _mm_cvtepu16_epi32(_mm_srli_si128(v, 8));
    } else {
        // Minor along x: the two samples are adjacent, one 32-bit load.
        const auto* row = reinterpret_cast<const unsigned char*>(h + line * mv.width);
        const int i0 = _mm_cvtsi128_si32(ii), i3 = _mm_extract_epi32(ii, 3);
        if (sameInAllLanes(ii)) {
            // All four tracks cross the line in one cell: one load.
            int v0;
            std::memcpy(&v0, row + 2 * static_cast<std::ptrdiff_t>(i0), 4);
            const __m128i g = _mm_set1_epi32(v0);
            const V4 h0 = toV4(_mm_and_si128(g, _mm_set1_epi32(0xFFFF)));
            const V4 h1 = toV4(_mm_srli_epi32(g, 16));
            return {h0 + f * (h1 - h0), h0, h1, i};
        }
        const int i1 = _mm_extract_epi32(ii, 1), i2 = _mm_extract_epi32(ii, 2);
        int v[4];
        std::memcpy(&v[0], row + 2 * static_cast<std::ptrdiff_t>(i0), 4);
        std::memcpy(&v[1], row + 2 * static_cast<std::ptrdiff_t>(i1), 4);
        std::memcpy(&v[2], row + 2 * static_cast<std::ptrdiff_t>(i2), 4);
        std::memcpy(&v[3], row + 2 * static_cast<std::ptrdiff_t>(i3), 4);
        __m128i g = _mm_cvtsi32_si128(v[0]);
        g = _mm_insert_epi32(g, v[1], 1);
        g = _mm_insert_epi32(g, v[2], 2);
        g = _mm_insert_epi32(g, v[3], 3);
        a = _mm_and_si128(g, _mm_set1_epi32(0xFFFF));
        b = _mm_srli_epi32(g, 16);
    }
    const V4 h0 = toV4(a), h1 = toV4(b);
    return {h0 + f * (h1 - h0), h0, h1, i};
}

// Four pixels' channels (each 0..255, one per 32-bit lane) as twelve bytes r g b r g b ...
// at c.
[[gnu::always_inline]] VIG_CASTER_AVX2 inline void storeRgb(__m128i r, __m128i g, __m128i b,
                                                            Rgb8* c) {
    static_assert(sizeof(Rgb8) == 3);
    const __m128i bytes =
        _mm_packus_epi16(_mm_packus_epi32(r, g), _mm_packus_epi32(b, _mm_setzero_si128()));
    const __m128i rgb = _mm_shuffle_epi8(
        bytes, _mm_setr_epi8(0, 4, 8, 1, 5, 9, 2, 6, 10, 3, 7, 11, -1, -1, -1, -1));
    _mm_storel_epi64(reinterpret_cast<__m128i*>(c), rgb);
    const int last = _mm_extract_epi32(rgb, 2);
    std::memcpy(reinterpret_cast<unsigned char*>(c) + 8, &last, 4);
}
// quantizeColor() on four lanes (no haze).
[[gnu::always_inline]] VIG_CASTER_AVX2 inline void quantizeLanes(const V4 rgb[3], Rgb8* c) {
    __m128i q[3];
    for (int ch = 0; ch < 3; ++ch) {
        __m128 v = _mm256_cvtpd_ps(reinterpret_cast<__m256d>(rgb[ch]));
        v = _mm_add_ps(v, _mm_set1_ps(0.5f));
        v = _mm_min_ps(_mm_max_ps(v, _mm_setzero_ps()), _mm_set1_ps(255.0f));
        q[ch] = _mm_cvttps_epi32(v);
    }
    storeRgb(q[0], q[1], q[2], c);
}

#endif  // !VIG_CASTER_LANES_PORTABLE

// cellColor on N lanes (the unused lanes must carry a valid cell).
template <class V>
[[gnu::always_inline]] VIG_CASTER_LANES_TARGET inline void cellColors(const MapView& mv, V cx, V cy,
                                                                      V fx, V fy, V rgb[3]) {
    fx = vclamp01(fx);
    fy = vclamp01(fy);
    const V i00 = cy * static_cast<double>(mv.width) + cx;
    const V i01 = i00 + static_cast<double>(mv.width);
    // Four bytes from each texel's first: r, g, b and the next texel's r, all inside the array
    // but at the last texel of the upper row, read from one byte earlier.
    const auto c00 = gather32<1>(mv.colors, i00 * 3.0);
    const auto c10 = gather32<1>(mv.colors, i00 * 3.0 + 3.0);
    const auto c01 = gather32<1>(mv.colors, i01 * 3.0);
    const auto c11 = texelsFromEarlier(gather32<1>(mv.colors, i01 * 3.0 + 2.0));
    const V w00 = (1 - fx) * (1 - fy), w10 = fx * (1 - fy), w01 = (1 - fx) * fy, w11 = fx * fy;
    for (int k = 0; k < 3; ++k) {
        rgb[k] = w00 * texelChannel(c00, k) + w10 * texelChannel(c10, k) +
                 w01 * texelChannel(c01, k) + w11 * texelChannel(c11, k);
    }
}

}  // namespace
}  // namespace ig::fast

#endif  // VIG_CASTER_PACKETS || VIG_CASTER_LANES_PORTABLE
