// Internals shared by the scalar and SIMD warp kernels: fixed point, integer BT.601, sampler.
#pragma once

#include "base/cpu_features.hpp"
#include "prp/warp_apply.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>

// The AVX2 kernel is built (with per-function target attributes) on x86-64 GCC and Clang.
#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#define VIG_PRP_HAVE_AVX2 1
#else
#define VIG_PRP_HAVE_AVX2 0
#endif

namespace prp::detail {

// BT.601 studio range, 16 fractional bits: Y' = 16 + (65.481 R + 128.553 G + 24.966 B) / 255,
// Cb = 128 + (-37.797 R - 74.203 G + 112 B) / 255, Cr = 128 + (112 R - 93.786 G - 18.214 B) / 255.
inline constexpr int kYr = 16829, kYg = 33039, kYb = 6416;
inline constexpr int kCbR = -9714, kCbG = -19070, kCbB = 28784;
inline constexpr int kCrR = 28784, kCrG = -24103, kCrB = -4681;
// Full-range grey, 8 fractional bits.
inline constexpr int kGr = 77, kGg = 150, kGb = 29;

inline constexpr int kFracBits = 32;
inline constexpr std::int64_t kOne = std::int64_t{1} << kFracBits;
inline constexpr std::int64_t kHalf = kOne / 2;
// Given points (applyPoints) have 16 fractional bits: enough for the sampler's 8-bit weights,
// half the bytes of 32.32.
inline constexpr int kPointFracBits = 16;
inline constexpr std::int64_t kPointScale = std::int64_t{1} << (kFracBits - kPointFracBits);
inline constexpr std::int32_t kPointHalf = std::int32_t{1} << (kPointFracBits - 1);

inline int luma601(int r, int g, int b) {
    return (kYr * r + kYg * g + kYb * b + (16 << 16) + (1 << 15)) >> 16;
}
inline int chroma601(int rs, int gs, int bs, int kr, int kg, int kb) {
    // Component sums of two pixels: one more fractional bit.
    return (kr * rs + kg * gs + kb * bs + (128 << 17) + (1 << 16)) >> 17;
}
inline int grey(int r, int g, int b) {
    return (kGr * r + kGg * g + kGb * b + 128) >> 8;
}

inline std::int64_t toFixed(double v) {
    return static_cast<std::int64_t>(std::llround(v * kOne));
}

// Bilinear sampler over an RGB8 image with edge repetition and a count of outside samples.
// The result is (sum of the four taps x weights (256 - f, f) products + 2^15) >> 16 for 8-bit
// fractions fx, fy: exact integer arithmetic, so any evaluation order gives the same value.
struct Sampler {
    const std::uint8_t* base;
    std::size_t rowBytes;
    std::int64_t maxX, maxY;     // clamp limits (just below the last pixel centre)
    std::uint64_t spanX, spanY;  // in-frame test: (px + kHalf) <= span
    std::uint64_t edge = 0;

    explicit Sampler(const SourceView& s)
        : base(reinterpret_cast<const std::uint8_t*>(s.pixels)),
          rowBytes(static_cast<std::size_t>(s.width) * 3),
          maxX((static_cast<std::int64_t>(s.width - 1) << kFracBits) - 1),
          maxY((static_cast<std::int64_t>(s.height - 1) << kFracBits) - 1),
          spanX(static_cast<std::uint64_t>(s.width) << kFracBits),
          spanY(static_cast<std::uint64_t>(s.height) << kFracBits) {}

    // (px, py): source point minus half a pixel, 32.32 fixed point.
    inline void sample(std::int64_t px, std::int64_t py, int& r, int& g, int& b) {
        edge += (static_cast<std::uint64_t>(px + kHalf) > spanX) |
                (static_cast<std::uint64_t>(py + kHalf) > spanY);
        px = std::clamp<std::int64_t>(px, 0, maxX);
        py = std::clamp<std::int64_t>(py, 0, maxY);
        const int fx = static_cast<int>((px >> (kFracBits - 8)) & 255);
        const int fy = static_cast<int>((py >> (kFracBits - 8)) & 255);
        const std::uint8_t* __restrict p0 = base +
                                            static_cast<std::size_t>(py >> kFracBits) * rowBytes +
                                            static_cast<std::size_t>(px >> kFracBits) * 3;
        const std::uint8_t* __restrict p1 = p0 + rowBytes;
        r = lerp(p0, p1, 0, fx, fy);
        g = lerp(p0, p1, 1, fx, fy);
        b = lerp(p0, p1, 2, fx, fy);
    }

    static inline int lerp(const std::uint8_t* p0, const std::uint8_t* p1, int c, int fx, int fy) {
        const int top = (p0[c] << 8) + (p0[c + 3] - p0[c]) * fx;
        const int bot = (p1[c] << 8) + (p1[c + 3] - p1[c]) * fx;
        return ((top << 8) + (bot - top) * fy + (1 << 15)) >> 16;
    }
};

// Quadratic along one output row by forward differences (constant second difference).
struct QuadraticRows {
    const Quadratic& q;
    std::int64_t x = 0, dx = 0, ddx = 0, y = 0, dy = 0, ddy = 0;

    void start(double rowY) {
        // Along the row: f(X) = A + B X + C X^2 at X = i + 0.5; f(X+1) - f(X) = B + C (2X + 1).
        auto coeffs = [&](const std::array<double, 6>& c, std::int64_t& v, std::int64_t& d,
                          std::int64_t& dd) {
            const double a0 = c[0] + c[2] * rowY + c[5] * rowY * rowY;
            const double b1 = c[1] + c[3] * rowY;
            const double c2 = c[4];
            v = toFixed(a0 + b1 * 0.5 + c2 * 0.25 - 0.5);
            d = toFixed(b1 + 2.0 * c2);
            dd = toFixed(2.0 * c2);
        };
        coeffs(q.a, x, dx, ddx);
        coeffs(q.b, y, dy, ddy);
    }
    inline void next() {
        x += dx;
        dx += ddx;
        y += dy;
        dy += ddy;
    }
    inline std::int64_t px() const { return x; }
    inline std::int64_t py() const { return y; }
};

// Projective map along one row: numerators and denominator are linear, one division per pixel.
struct ProjectiveRows {
    const Homography& hm;
    double nx = 0, ny = 0, w = 0;
    std::int64_t cx = 0, cy = 0;

    void start(double rowY) {
        const auto& h = hm.h;
        nx = h[0] * 0.5 + h[1] * rowY + h[2];
        ny = h[3] * 0.5 + h[4] * rowY + h[5];
        w = h[6] * 0.5 + h[7] * rowY + h[8];
        compute();
    }
    inline void compute() {
        const double inv = 1.0 / w;
        const double lim = kMaxSourceCoordinate;
        cx = static_cast<std::int64_t>(std::clamp(nx * inv - 0.5, -lim, lim) * kOne);
        cy = static_cast<std::int64_t>(std::clamp(ny * inv - 0.5, -lim, lim) * kOne);
    }
    inline void next() {
        nx += hm.h[0];
        ny += hm.h[3];
        w += hm.h[6];
        compute();
    }
    inline std::int64_t px() const { return cx; }
    inline std::int64_t py() const { return cy; }
};

// Source points of a run of pixels held in arrays (slot[k] is pixel k's index).
struct ArrayPositions {
    const std::int64_t* x;
    const std::int64_t* y;
    const int* slot;
    int k = 0;

    inline void next() { ++k; }
    inline std::int64_t px() const { return x[slot[k]]; }
    inline std::int64_t py() const { return y[slot[k]]; }
};

// Source points of consecutive pixels held in natural order.
// Points given per pixel in 16.16 fixed point, read as the sampler's 32.32.
struct LinePositions {
    const std::int32_t* x;
    const std::int32_t* y;
    int k = 0;

    inline void next() { ++k; }
    inline std::int64_t px() const { return static_cast<std::int64_t>(x[k]) * kPointScale; }
    inline std::int64_t py() const { return static_cast<std::int64_t>(y[k]) * kPointScale; }
};

template <bool kGain>
inline void applyGain(int& r, int& g, int& b, int gainQ8) {
    if constexpr (kGain) {
        r = std::min(255, (r * gainQ8 + 128) >> 8);
        g = std::min(255, (g * gainQ8 + 128) >> 8);
        b = std::min(255, (b * gainQ8 + 128) >> 8);
    }
}

// The scalar kernel for `count` consecutive pixels of one row: samples the points `pos` walks
// through and writes them in kFormat from `out` on; returns the end of what it wrote. UYVY
// writes whole pairs only.
template <PixelFormat kFormat, bool kGain, bool kAgc, class Positions>
inline std::uint8_t* writePixels(Sampler& s, Positions& pos, int count, int gainQ8,
                                 std::uint8_t* __restrict out, std::uint64_t& luma) {
    if constexpr (kFormat == PixelFormat::Uyvy) {
        for (int i = 0; i + 1 < count; i += 2) {
            int r0, g0, b0, r1, g1, b1;
            s.sample(pos.px(), pos.py(), r0, g0, b0);
            pos.next();
            s.sample(pos.px(), pos.py(), r1, g1, b1);
            pos.next();
            applyGain<kGain>(r0, g0, b0, gainQ8);
            applyGain<kGain>(r1, g1, b1, gainQ8);
            const int rs = r0 + r1, gs = g0 + g1, bs = b0 + b1;
            out[0] = static_cast<std::uint8_t>(chroma601(rs, gs, bs, kCbR, kCbG, kCbB));
            out[1] = static_cast<std::uint8_t>(luma601(r0, g0, b0));
            out[2] = static_cast<std::uint8_t>(chroma601(rs, gs, bs, kCrR, kCrG, kCrB));
            out[3] = static_cast<std::uint8_t>(luma601(r1, g1, b1));
            if constexpr (kAgc) luma += grey(r0, g0, b0) + grey(r1, g1, b1);
            out += 4;
        }
    } else {
        for (int i = 0; i < count; ++i) {
            int r, g, b;
            s.sample(pos.px(), pos.py(), r, g, b);
            pos.next();
            applyGain<kGain>(r, g, b, gainQ8);
            if constexpr (kFormat == PixelFormat::Rgb8) {
                out[0] = static_cast<std::uint8_t>(r);
                out[1] = static_cast<std::uint8_t>(g);
                out[2] = static_cast<std::uint8_t>(b);
                out += 3;
                if constexpr (kAgc) luma += grey(r, g, b);
            } else {
                const int y = grey(r, g, b);
                *out++ = static_cast<std::uint8_t>(y);
                if constexpr (kAgc) luma += y;
            }
        }
    }
    return out;
}

// Whether the SIMD quadratic kernels can take this source and gain (it addresses the source with
// 32-bit offsets, needs at least 3 x 2 pixels for its clamp-free interior, and 16-bit products).
inline bool avx2Takes(const SourceView& s, int gainQ8) {
    return s.width >= 3 && s.height >= 2 && gainQ8 >= 0 && gainQ8 <= (1 << 16) &&
           static_cast<std::uint64_t>(s.width) * static_cast<std::uint64_t>(s.height) * 3 <
               (std::uint64_t{1} << 31);
}

#if VIG_PRP_HAVE_AVX2
// True when the running processor has AVX2, respectively AVX-512 F+BW+DQ+VL+VBMI
// (base::cpuFeatures, detected once).
inline bool cpuHasAvx2() {
    return base::cpuFeatures().avx2;
}
inline bool cpuHasAvx512() {
    return base::cpuFeatures().avx512vbmi;
}
// applyQuadratic's AVX2 kernel; bit-identical to the scalar one. Needs cpuHasAvx2() and
// avx2Takes(source, gainQ8).
ApplyResult applyQuadraticAvx2(const SourceView& source, const Quadratic& sourceFromOutput,
                               const FieldView& field, int gainQ8, bool agc);
// applyPoints' AVX2 kernel; bit-identical to the scalar one. Needs cpuHasAvx2() and
// avx2Takes(source, gainQ8).
ApplyResult applyPointsAvx2(const SourceView& source, const std::int32_t* xs,
                            const std::int32_t* ys, std::size_t stride, const FieldView& field,
                            int gainQ8, bool agc);
// The same with AVX-512, 16 pixels per step. Needs cpuHasAvx512() and avx2Takes(...).
ApplyResult applyQuadraticAvx512(const SourceView& source, const Quadratic& sourceFromOutput,
                                 const FieldView& field, int gainQ8, bool agc);
#endif

// One output row of the out-of-frame fill's sky (OutsideFill::colorsAlong): pixel k's centre
// x = x0 + k + 0.5 looks up by dz = fz + u rz - vz, u = sx x - cx, over the length
// sqrt(ff + u u + vv); its sky blend is t = sqrt(clamp(dz / length, 0, 1)).
struct SkyRow {
    double sx, cx, fz, rz, vz, ff, vv;
    int x0;
};
// t[k] and above[k] (dz > 0) for k < n <= 64 (t and above hold 64), two pixels a step with
// SSE2 (one without), each lane rounded as the scalar operation.
void skyRowSse2(const SkyRow& row, int n, double* t, std::uint8_t* above);
#if VIG_PRP_HAVE_AVX2
// The same eight pixels a step with AVX-512. Needs cpuHasAvx512().
void skyRowAvx512(const SkyRow& row, int n, double* t, std::uint8_t* above);
#endif

// Picks the kernel specialised for the field's format, gain and AGC once per field:
// run.template operator()<format, gain, agc>().
template <class Run>
ApplyResult dispatchKernel(PixelFormat format, int gainQ8, bool agc, Run&& run) {
    const bool gain = gainQ8 != kUnityGain;
    auto pick = [&]<PixelFormat F>() {
        if (agc) {
            return gain ? run.template operator()<F, true, true>()
                        : run.template operator()<F, false, true>();
        }
        return gain ? run.template operator()<F, true, false>()
                    : run.template operator()<F, false, false>();
    };
    switch (format) {
        case PixelFormat::Rgb8:
            return pick.template operator()<PixelFormat::Rgb8>();
        case PixelFormat::Y8:
            return pick.template operator()<PixelFormat::Y8>();
        case PixelFormat::Uyvy:
            break;
    }
    return pick.template operator()<PixelFormat::Uyvy>();
}

}  // namespace prp::detail
