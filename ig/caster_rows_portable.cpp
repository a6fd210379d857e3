// The row batches on portable lanes (RowBatches<P4>, RowBatches<P8>; caster_rows.hpp): the
// scalar twins of the AVX2 four-row and AVX-512 eight-row kernels. The same template, over
// lanes of four and eight doubles whose arithmetic the compiler lowers lane by lane (GCC and
// Clang vector types; this object is compiled without any instruction-set flag, and like the
// vector objects without contraction into fused multiply-adds, ig/CMakeLists.txt); the
// primitives the intrinsics provide in the vector objects are written here lane by lane, each
// doing what its intrinsic does (the same truncations, roundings and clamps). So the twin and
// the vector kernel share one source of reasoning and give the same image to the bit
// (tests/ig/caster_kernel_test.cpp). Never chosen by default: forced by name (rows4-portable,
// rows8-portable). Everything here has internal linkage but rows_portable::kernel4/kernel8
// (docs/design/multires.md, "One object per instruction set").
#include "ig/fast_column.hpp"

#if VIG_CASTER_ROWS
#define VIG_CASTER_LANES_PORTABLE 1

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstring>

namespace ig::fast {
namespace {

using P4 = double __attribute__((vector_size(32)));
using P8 = double __attribute__((vector_size(64)));

template <class V>
inline constexpr int kLanesOf = static_cast<int>(sizeof(V) / sizeof(double));

// N 32-bit lanes (what gather32 returns in the vector objects).
template <int N>
struct Texels {
    std::uint32_t v[N];
};

// _mm256_sqrt_pd / _mm512_sqrt_pd: the correctly rounded square root, lane by lane.
template <class V>
[[gnu::always_inline]] inline V vsqrt(V v) {
    V r;
    for (int l = 0; l < kLanesOf<V>; ++l)
        r[l] = std::sqrt(v[l]);
    return r;
}
// _mm256_floor_pd / roundscale toward minus infinity.
template <class V>
[[gnu::always_inline]] inline V vfloor(V v) {
    V r;
    for (int l = 0; l < kLanesOf<V>; ++l)
        r[l] = std::floor(v[l]);
    return r;
}
// movemask: bit l set where lane l of the mask is set (a comparison's lanes are 0 or all ones).
template <class M>
[[gnu::always_inline]] inline int vmask(M m) {
    constexpr int kN = static_cast<int>(sizeof(M) / sizeof(m[0]));
    int bits = 0;
    for (int l = 0; l < kN; ++l)
        bits |= (m[l] != 0 ? 1 : 0) << l;
    return bits;
}
// The 32 bits at byte offset scale * idx from base (64-bit offsets).
template <int kScale, class V>
[[gnu::always_inline]] inline Texels<kLanesOf<V>> gather32(const void* base, V idx) {
    const auto* b = static_cast<const unsigned char*>(base);
    Texels<kLanesOf<V>> t;
    for (int l = 0; l < kLanesOf<V>; ++l) {
        std::memcpy(&t.v[l], b + static_cast<std::ptrdiff_t>(idx[l]) * kScale, 4);
    }
    return t;
}
// Channel k (0..2) of the texels: (t >> 8k) & 0xFF, as a double.
template <int N>
[[gnu::always_inline]] inline auto texelChannel(const Texels<N>& t, int k) {
    double __attribute__((vector_size(N * sizeof(double)))) r;
    for (int l = 0; l < N; ++l)
        r[l] = static_cast<double>((t.v[l] >> (8 * k)) & 0xFFu);
    return r;
}
template <int N>
[[gnu::always_inline]] inline Texels<N> texelsFromEarlier(Texels<N> t) {
    for (int l = 0; l < N; ++l)
        t.v[l] >>= 8;
    return t;
}

}  // namespace
}  // namespace ig::fast

#include "ig/caster_lanes.hpp"

namespace ig::fast {
namespace {

// sampleLine on N lanes: the cell's two samples on the line, read lane by lane (64-bit
// offsets: a paged map may hold more than 2^31 samples).
template <bool kMajorX, class V>
[[gnu::always_inline]] inline LineN<V> sampleLine(const MapView& mv, long line, V n, double lastN) {
    const V i = vmin(vfloor(n), V{} + (lastN - 1.0));
    const V f = n - i;
    const std::uint16_t* h = mv.heights;
    const std::ptrdiff_t w = mv.width;
    V h0, h1;
    for (int l = 0; l < kLanesOf<V>; ++l) {
        const int ii = static_cast<int>(i[l]);
        if (kMajorX) {
            // Minor along y: the two samples are a row apart.
            const std::ptrdiff_t o = line + ii * w;
            h0[l] = static_cast<double>(h[o]);
            h1[l] = static_cast<double>(h[o + w]);
        } else {
            // Minor along x: the two samples are adjacent.
            const std::uint16_t* row = h + line * w;
            h0[l] = static_cast<double>(row[ii]);
            h1[l] = static_cast<double>(row[ii + 1]);
        }
    }
    return {h0 + f * (h1 - h0), h0, h1, i};
}

// quantizeLanes: cvtpd_ps (round to nearest), + 0.5f, max with 0 and min with 255 as
// maxps/minps order them, cvttps (truncation); quantizeColor()'s result.
template <class V>
[[gnu::always_inline]] inline void quantizeLanes(const V rgb[3], Rgb8* c) {
    for (int l = 0; l < kLanesOf<V>; ++l) {
        std::uint8_t q[3];
        for (int ch = 0; ch < 3; ++ch) {
            float v = static_cast<float>(rgb[ch][l]);
            v = v + 0.5f;
            v = v > 0.0f ? v : 0.0f;
            v = v < 255.0f ? v : 255.0f;
            q[ch] = static_cast<std::uint8_t>(static_cast<int>(v));
        }
        c[l] = Rgb8{q[0], q[1], q[2]};
    }
}

}  // namespace
}  // namespace ig::fast

#include "ig/caster_rows.hpp"

namespace ig::rows_portable {

fast::RowKernel kernel4() {
    return {4, &fast::RowBatches<fast::P4>::run, &fast::RowBatches<fast::P4>::cast};
}
fast::RowKernel kernel8() {
    return {8, &fast::RowBatches<fast::P8>::run, &fast::RowBatches<fast::P8>::cast};
}

}  // namespace ig::rows_portable

#else

namespace ig::rows_portable {

fast::RowKernel kernel4() {
    return {};
}
fast::RowKernel kernel8() {
    return {};
}

}  // namespace ig::rows_portable

#endif
