#include "prp/warp_apply.hpp"

#include <algorithm>
#include <cmath>

namespace prp {

namespace {

// BT.601 studio range, 16 fractional bits: Y' = 16 + (65.481 R + 128.553 G + 24.966 B) / 255,
// Cb = 128 + (-37.797 R - 74.203 G + 112 B) / 255, Cr = 128 + (112 R - 93.786 G - 18.214 B) / 255.
constexpr int kYr = 16829, kYg = 33039, kYb = 6416;
constexpr int kCbR = -9714, kCbG = -19070, kCbB = 28784;
constexpr int kCrR = 28784, kCrG = -24103, kCrB = -4681;
// Full-range grey, 8 fractional bits.
constexpr int kGr = 77, kGg = 150, kGb = 29;

constexpr int kFracBits = 32;
constexpr std::int64_t kOne = std::int64_t{1} << kFracBits;
constexpr std::int64_t kHalf = kOne / 2;

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

std::int64_t toFixed(double v) {
    return static_cast<std::int64_t>(std::llround(v * kOne));
}

// Bilinear sampler over an RGB8 image with edge repetition and a count of outside samples.
struct Sampler {
    const std::uint8_t* base;
    std::size_t rowBytes;
    std::int64_t maxX, maxY;     // clamp limits (just below the last pixel centre)
    std::uint64_t spanX, spanY;  // in-frame test: (px + kHalf) <= span
    std::uint64_t edge = 0;

    Sampler(const SourceView& s)
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
        auto lerp = [&](int c) {
            const int top = (p0[c] << 8) + (p0[c + 3] - p0[c]) * fx;
            const int bot = (p1[c] << 8) + (p1[c + 3] - p1[c]) * fx;
            return ((top << 8) + (bot - top) * fy + (1 << 15)) >> 16;
        };
        r = lerp(0);
        g = lerp(1);
        b = lerp(2);
    }
};

// Quadratic along one output row by forward differences (constant second difference).
struct QuadraticRows {
    const Quadratic& q;
    std::int64_t x, dx, ddx, y, dy, ddy;

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
    double nx, ny, w;
    std::int64_t cx, cy;

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

template <bool kGain>
inline void applyGain(int& r, int& g, int& b, int gainQ8) {
    if constexpr (kGain) {
        r = std::min(255, (r * gainQ8 + 128) >> 8);
        g = std::min(255, (g * gainQ8 + 128) >> 8);
        b = std::min(255, (b * gainQ8 + 128) >> 8);
    }
}

template <PixelFormat kFormat, bool kGain, bool kAgc, class Rows>
ApplyResult warpField(const SourceView& source, Rows rows, const FieldView& field, int gainQ8) {
    Sampler s(source);
    std::uint64_t luma = 0;
    const int width = field.width;
    for (int line = 0; line < field.lines; ++line) {
        std::uint8_t* __restrict out = field.pixels + static_cast<std::size_t>(line) * field.stride;
        rows.start(field.firstLine + 2 * line + 0.5);
        if constexpr (kFormat == PixelFormat::Uyvy) {
            for (int i = 0; i + 1 < width; i += 2) {
                int r0, g0, b0, r1, g1, b1;
                s.sample(rows.px(), rows.py(), r0, g0, b0);
                rows.next();
                s.sample(rows.px(), rows.py(), r1, g1, b1);
                rows.next();
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
            for (int i = 0; i < width; ++i) {
                int r, g, b;
                s.sample(rows.px(), rows.py(), r, g, b);
                rows.next();
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
    }
    return {s.edge, luma};
}

// Picks the specialised kernel once per field.
template <class Rows>
ApplyResult dispatch(const SourceView& source, Rows rows, const FieldView& field, int gainQ8,
                     bool agc) {
    const bool gain = gainQ8 != kUnityGain;
    auto pick = [&]<PixelFormat F>() {
        if (agc) {
            return gain ? warpField<F, true, true>(source, rows, field, gainQ8)
                        : warpField<F, false, true>(source, rows, field, gainQ8);
        }
        return gain ? warpField<F, true, false>(source, rows, field, gainQ8)
                    : warpField<F, false, false>(source, rows, field, gainQ8);
    };
    switch (field.format) {
        case PixelFormat::Rgb8:
            return pick.template operator()<PixelFormat::Rgb8>();
        case PixelFormat::Y8:
            return pick.template operator()<PixelFormat::Y8>();
        case PixelFormat::Uyvy:
            break;
    }
    return pick.template operator()<PixelFormat::Uyvy>();
}

}  // namespace

ApplyResult applyQuadratic(const SourceView& source, const Quadratic& sourceFromOutput,
                           const FieldView& field, int gainQ8, bool agc) {
    return dispatch(source, QuadraticRows{sourceFromOutput, 0, 0, 0, 0, 0, 0}, field, gainQ8, agc);
}

ApplyResult applyHomography(const SourceView& source, const Homography& sourceFromOutput,
                            const FieldView& field, int gainQ8, bool agc) {
    return dispatch(source, ProjectiveRows{sourceFromOutput, 0, 0, 0, 0, 0}, field, gainQ8, agc);
}

void convertRow(const std::uint8_t* rgb, int width, PixelFormat format, int gainQ8, bool agc,
                std::uint8_t* out, std::uint64_t& lumaSum) {
    auto px = [&](int i, int& r, int& g, int& b) {
        r = rgb[3 * i];
        g = rgb[3 * i + 1];
        b = rgb[3 * i + 2];
        applyGain<true>(r, g, b, gainQ8);
        if (agc) lumaSum += grey(r, g, b);
    };
    if (format == PixelFormat::Uyvy) {
        for (int i = 0; i + 1 < width; i += 2) {
            int r0, g0, b0, r1, g1, b1;
            px(i, r0, g0, b0);
            px(i + 1, r1, g1, b1);
            const int rs = r0 + r1, gs = g0 + g1, bs = b0 + b1;
            out[0] = static_cast<std::uint8_t>(chroma601(rs, gs, bs, kCbR, kCbG, kCbB));
            out[1] = static_cast<std::uint8_t>(luma601(r0, g0, b0));
            out[2] = static_cast<std::uint8_t>(chroma601(rs, gs, bs, kCrR, kCrG, kCrB));
            out[3] = static_cast<std::uint8_t>(luma601(r1, g1, b1));
            out += 4;
        }
        return;
    }
    for (int i = 0; i < width; ++i) {
        int r, g, b;
        px(i, r, g, b);
        if (format == PixelFormat::Rgb8) {
            out[3 * i] = static_cast<std::uint8_t>(r);
            out[3 * i + 1] = static_cast<std::uint8_t>(g);
            out[3 * i + 2] = static_cast<std::uint8_t>(b);
        } else {
            out[i] = static_cast<std::uint8_t>(grey(r, g, b));
        }
    }
}

YCbCr bt601(int r, int g, int b) {
    YCbCr c;
    c.y = bt601Luma(r, g, b);
    bt601ChromaOfSum(2 * r, 2 * g, 2 * b, c.cb, c.cr);
    return c;
}

std::uint8_t bt601Luma(int r, int g, int b) {
    return static_cast<std::uint8_t>(luma601(r, g, b));
}

void bt601ChromaOfSum(int rSum, int gSum, int bSum, std::uint8_t& cb, std::uint8_t& cr) {
    cb = static_cast<std::uint8_t>(chroma601(rSum, gSum, bSum, kCbR, kCbG, kCbB));
    cr = static_cast<std::uint8_t>(chroma601(rSum, gSum, bSum, kCrR, kCrG, kCrB));
}

std::uint8_t greyOf(int r, int g, int b) {
    return static_cast<std::uint8_t>(grey(r, g, b));
}

}  // namespace prp
