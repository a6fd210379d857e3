// x86 SIMD helpers shared by the AVX2 and AVX-512 warp kernels (target attributes per function).
#pragma once

#include "prp/warp_apply_kernel.hpp"

#if VIG_PRP_HAVE_AVX2

#include <immintrin.h>

#include <cstddef>
#include <cstdint>

#define VIG_TARGET_AVX2 __attribute__((target("avx2")))
#define VIG_TARGET_AVX512 \
    __attribute__((target("avx2,avx512f,avx512bw,avx512dq,avx512vl,avx512vbmi")))

// In an anonymous namespace: each kernel object has its own copies, and no weak symbol with
// AVX2 code is left for the linker to share (scripts/isa-symbols.sh).
namespace prp::detail::simd {
namespace {

// Two 16-bit words in one dword (lo | hi << 16), as _mm256_madd_epi16 reads them.
constexpr int words(int lo, int hi) {
    return static_cast<int>(static_cast<std::uint32_t>(static_cast<std::uint16_t>(lo)) |
                            (static_cast<std::uint32_t>(static_cast<std::uint16_t>(hi)) << 16));
}

// Two 32-bit offsets taken from one 64-bit lane.
struct Offsets2 {
    std::ptrdiff_t first, second;
    explicit Offsets2(long long v)
        : first(static_cast<std::int32_t>(v)), second(static_cast<std::int32_t>(v >> 32)) {}
};

// Four 8-byte loads: lo's pair in the low 128-bit lane, hi's in the high one. Broadcast loads
// and blends rather than inserts: they keep the shuffle units free.
VIG_TARGET_AVX2 inline __m256i load2x2(const std::uint8_t* base, Offsets2 lo, Offsets2 hi) {
    const __m256i q0 =
        _mm256_castsi128_si256(_mm_loadl_epi64(reinterpret_cast<const __m128i*>(base + lo.first)));
    const __m256i q1 = _mm256_broadcastq_epi64(
        _mm_loadl_epi64(reinterpret_cast<const __m128i*>(base + lo.second)));
    const __m256i q2 =
        _mm256_broadcastq_epi64(_mm_loadl_epi64(reinterpret_cast<const __m128i*>(base + hi.first)));
    const __m256i q3 = _mm256_broadcastq_epi64(
        _mm_loadl_epi64(reinterpret_cast<const __m128i*>(base + hi.second)));
    return _mm256_blend_epi32(_mm256_blend_epi32(q0, q1, 0x0c), _mm256_blend_epi32(q2, q3, 0xc0),
                              0xf0);
}

}  // namespace
}  // namespace prp::detail::simd

#endif  // VIG_PRP_HAVE_AVX2
