#include "prp/warp_apply.hpp"

#include "prp/warp_apply_kernel.hpp"

#include "ig/shading.hpp"

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include <algorithm>
#include <cmath>

namespace prp {

using namespace detail;

namespace {

// The portable kernel (and the oracle of the SIMD ones): one output row at a time.
template <PixelFormat kFormat, bool kGain, bool kAgc, class Rows>
ApplyResult warpField(const SourceView& source, Rows rows, const FieldView& field, int gainQ8) {
    Sampler s(source);
    std::uint64_t luma = 0;
    for (int line = 0; line < field.lines; ++line) {
        std::uint8_t* out = field.pixels + static_cast<std::size_t>(line) * field.stride;
        rows.start(field.firstLine + 2 * line + 0.5);
        writePixels<kFormat, kGain, kAgc>(s, rows, field.width, gainQ8, out, luma);
    }
    return {s.edge, luma};
}

// Picks the specialised kernel once per field.
template <class Rows>
ApplyResult dispatch(const SourceView& source, Rows rows, const FieldView& field, int gainQ8,
                     bool agc) {
    return dispatchKernel(field.format, gainQ8, agc, [&]<PixelFormat F, bool G, bool A>() {
        return warpField<F, G, A>(source, rows, field, gainQ8);
    });
}

// The fill passes' walk: the next n source points of the row (as the kernels walk them) and
// which lie outside the frame; false when none does.
template <class Rows>
bool nextPoints(Rows& rows, const Sampler& s, int n, std::int64_t* xs, std::int64_t* ys,
                bool* outside) {
    bool any = false;
    for (int k = 0; k < n; ++k) {
        xs[k] = rows.px();
        ys[k] = rows.py();
        rows.next();
        outside[k] = (static_cast<std::uint64_t>(xs[k] + kHalf) > s.spanX) |
                     (static_cast<std::uint64_t>(ys[k] + kHalf) > s.spanY);
        any |= outside[k];
    }
    return any;
}

// The fill pass's slow twin: walks each line's source points as the kernels do, and writes the
// pixels (pairs for UYVY) with any point outside again, one at a time, through convertRow.
template <class Rows>
void fillFieldPerPixel(const SourceView& source, Rows rows, const FieldView& field, int gainQ8,
                       bool agc, const OutsideFill& fill, ApplyResult& result) {
    if (result.edgeSamples == 0) return;
    Sampler s(source);
    constexpr int kChunk = 64;  // even: UYVY pairs never straddle chunks
    const int group = field.format == PixelFormat::Uyvy ? 2 : 1;
    const std::size_t bpp = bytesPerPixel(field.format);
    std::int64_t xs[kChunk], ys[kChunk];
    bool outside[kChunk];
    std::uint8_t oldRgb[6], newRgb[6], scratch[6];
    std::uint64_t oldLuma = 0, newLuma = 0;
    for (int line = 0; line < field.lines; ++line) {
        const double y = field.firstLine + 2 * line + 0.5;
        rows.start(y);
        std::uint8_t* out = field.pixels + static_cast<std::size_t>(line) * field.stride;
        for (int x0 = 0; x0 < field.width; x0 += kChunk) {
            const int n = std::min(kChunk, field.width - x0);
            if (!nextPoints(rows, s, n, xs, ys, outside)) continue;
            for (int g = 0; g + group <= n; g += group) {
                if (!outside[g] && !(group == 2 && outside[g + 1])) continue;
                for (int k = 0; k < group; ++k) {
                    int r, gr, b;
                    s.sample(xs[g + k], ys[g + k], r, gr, b);
                    std::uint8_t* o = oldRgb + 3 * k;
                    o[0] = static_cast<std::uint8_t>(r);
                    o[1] = static_cast<std::uint8_t>(gr);
                    o[2] = static_cast<std::uint8_t>(b);
                    ig::Rgb8 c{o[0], o[1], o[2]};
                    if (outside[g + k]) fill.colorAt(x0 + g + k + 0.5, y, c);
                    std::uint8_t* nw = newRgb + 3 * k;
                    nw[0] = c.r;
                    nw[1] = c.g;
                    nw[2] = c.b;
                }
                if (agc) convertRow(oldRgb, group, field.format, gainQ8, true, scratch, oldLuma);
                convertRow(newRgb, group, field.format, gainQ8, agc,
                           out + static_cast<std::size_t>(x0 + g) * bpp, newLuma);
            }
        }
    }
    if (agc) result.lumaSum = result.lumaSum - oldLuma + newLuma;
}

// The fill pass over one field: walks each line's source points as the kernels do, 64 pixels at
// a time. A pixel is written again only where its point lies outside and the fill has a colour
// for it (elsewhere the kernel's sample stands); for UYVY the pair holding it. Each run of such
// pixels (pairs) is converted by one convertRow call, the colours of a chunk worked out in one
// loop, and the source sampled only for what the fill needs: the kernel's sample of a pixel
// the fill leaves (a pair's other pixel), and, with AGC, of every pixel written again (its luma
// leaves the sum). The same bytes and sums as fillFieldPerPixel.
template <class Rows>
void fillField(const SourceView& source, Rows rows, const FieldView& field, int gainQ8, bool agc,
               const OutsideFill& fill, ApplyResult& result) {
    if (result.edgeSamples == 0) return;
    Sampler s(source);
    constexpr int kChunk = 64;  // even: UYVY pairs never straddle chunks
    const bool uyvy = field.format == PixelFormat::Uyvy;
    const std::size_t bpp = bytesPerPixel(field.format);
    std::int64_t xs[kChunk], ys[kChunk];
    bool outside[kChunk], filled[kChunk];
    std::uint8_t oldRgb[3 * kChunk], newRgb[3 * kChunk], scratch[3 * kChunk];
    std::uint64_t oldLuma = 0, newLuma = 0;
    for (int line = 0; line < field.lines; ++line) {
        const double y = field.firstLine + 2 * line + 0.5;
        rows.start(y);
        std::uint8_t* out = field.pixels + static_cast<std::size_t>(line) * field.stride;
        for (int x0 = 0; x0 < field.width; x0 += kChunk) {
            const int n = std::min(kChunk, field.width - x0);
            if (!nextPoints(rows, s, n, xs, ys, outside)) continue;
            fill.colorsAlong(x0, n, y, filled, newRgb);
            bool anyFilled = false;
            for (int k = 0; k < n; ++k) {
                filled[k] = filled[k] && outside[k];
                anyFilled |= filled[k];
            }
            if (!anyFilled) continue;
            // Runs of pixels (UYVY: pairs) written again: [a, b).
            for (int a = 0; a < n;) {
                const auto rewritten = [&](int k) {
                    return filled[k] || (uyvy && (k ^ 1) < n && filled[k ^ 1]);
                };
                if (!rewritten(a)) {
                    ++a;
                    continue;
                }
                int b = a;
                while (b < n && rewritten(b))
                    ++b;
                for (int k = a; k < b; ++k) {
                    if (filled[k] && !agc) continue;
                    int r, gr, bl;
                    s.sample(xs[k], ys[k], r, gr, bl);
                    const std::uint8_t c[3] = {static_cast<std::uint8_t>(r),
                                               static_cast<std::uint8_t>(gr),
                                               static_cast<std::uint8_t>(bl)};
                    std::copy_n(c, 3, oldRgb + 3 * k);
                    if (!filled[k]) std::copy_n(c, 3, newRgb + 3 * k);
                }
                if (agc) {
                    convertRow(oldRgb + 3 * a, b - a, field.format, gainQ8, true, scratch, oldLuma);
                }
                convertRow(newRgb + 3 * a, b - a, field.format, gainQ8, agc,
                           out + static_cast<std::size_t>(x0 + a) * bpp, newLuma);
                a = b;
            }
        }
    }
    if (agc) result.lumaSum = result.lumaSum - oldLuma + newLuma;
}

}  // namespace

std::string_view edgeFillName(EdgeFill fill) {
    switch (fill) {
        case EdgeFill::Repeat:
            return "repeat";
        case EdgeFill::Sky:
            return "sky";
        case EdgeFill::SkyHaze:
            return "sky-haze";
    }
    return "?";
}

std::optional<EdgeFill> parseEdgeFill(std::string_view name) {
    for (const EdgeFill f : {EdgeFill::Repeat, EdgeFill::Sky, EdgeFill::SkyHaze}) {
        if (name == edgeFillName(f)) return f;
    }
    return std::nullopt;
}

OutsideFill OutsideFill::of(const ig::SkyModel& sky, const ig::Intrinsics& rendered,
                            const OutputGeometry& geometry, const ig::Pose& pose) {
    OutsideFill f;
    f.sky = sky;
    f.focal = geometry.focal > 0.0 ? geometry.focal : rendered.focal;  // the field's camera
    f.sx = static_cast<double>(geometry.windowWidth) / geometry.width;
    f.sy = static_cast<double>(geometry.windowHeight) / geometry.height;
    f.cx = 0.5 * geometry.windowWidth;
    f.cy = 0.5 * geometry.windowHeight;
    const ig::CameraBasis basis = ig::CameraBasis::fromPose(pose);
    f.forwardZ = basis.forward.z;
    f.rightZ = basis.right.z;
    f.upZ = basis.up.z;
    return f;
}

bool OutsideFill::colorAt(double x, double y, ig::Rgb8& color) const {
    const double u = sx * x - cx, v = sy * y - cy;
    const double dz = focal * forwardZ + u * rightZ - v * upZ;
    if (!(dz > 0.0) && !hazeBelow) return false;
    color = ig::skyColor(sky, dz / std::sqrt(focal * focal + u * u + v * v));
    return true;
}

namespace detail {

void skyRowSse2(const SkyRow& row, int n, double* t, std::uint8_t* above) {
    // OutsideFill::colorAt's operations in its order (this file is built without contraction).
#if defined(__SSE2__)
    // Two pixels a step (every x86-64), each lane rounded as the scalar operation.
    const __m128d sx = _mm_set1_pd(row.sx), cx = _mm_set1_pd(row.cx);
    const __m128d fz = _mm_set1_pd(row.fz), rz = _mm_set1_pd(row.rz);
    const __m128d vz = _mm_set1_pd(row.vz), ff = _mm_set1_pd(row.ff);
    const __m128d vv = _mm_set1_pd(row.vv), zero = _mm_setzero_pd(), one = _mm_set1_pd(1.0);
    for (int k = 0; k < n; k += 2) {
        const __m128d x = _mm_set_pd(row.x0 + k + 1.5, row.x0 + k + 0.5);
        const __m128d u = _mm_sub_pd(_mm_mul_pd(sx, x), cx);
        const __m128d dz = _mm_sub_pd(_mm_add_pd(fz, _mm_mul_pd(u, rz)), vz);
        const __m128d len = _mm_sqrt_pd(_mm_add_pd(_mm_add_pd(ff, _mm_mul_pd(u, u)), vv));
        // std::clamp to [0, 1]: the same for every number (a NaN never reaches here).
        const __m128d c = _mm_min_pd(_mm_max_pd(_mm_div_pd(dz, len), zero), one);
        _mm_storeu_pd(t + k, _mm_sqrt_pd(c));
        const int up = _mm_movemask_pd(_mm_cmpgt_pd(dz, zero));
        above[k] = static_cast<std::uint8_t>(up & 1);
        above[k + 1] = static_cast<std::uint8_t>((up >> 1) & 1);
    }
#else
    for (int k = 0; k < n; ++k) {
        const double u = row.sx * (row.x0 + k + 0.5) - row.cx;
        const double dz = row.fz + u * row.rz - row.vz;
        t[k] = std::sqrt(std::clamp(dz / std::sqrt(row.ff + u * u + row.vv), 0.0, 1.0));
        above[k] = dz > 0.0;
    }
#endif
}

}  // namespace detail

void OutsideFill::colorsAlong(int x0, int n, double y, bool* has, std::uint8_t* rgb) const {
    // colorAt's expressions, in its order (this file is built without contraction).
    const double v = sy * y - cy;
    const SkyRow row{sx, cx, focal * forwardZ, rightZ, v * upZ, focal * focal, v * v, x0};
    alignas(64) double t[64];
    alignas(64) std::uint8_t above[64];
#if VIG_PRP_HAVE_AVX2
    if (cpuHasAvx512()) {
        skyRowAvx512(row, n, t, above);
    } else
#endif
    {
        skyRowSse2(row, n, t, above);
    }
    // ig::skyColor's blend, the channels' ends taken out of the loop (calling it per pixel
    // made the whole fill 14 % slower).
    const int a[3] = {sky.horizon.r, sky.horizon.g, sky.horizon.b};
    const int d[3] = {sky.zenith.r - a[0], sky.zenith.g - a[1], sky.zenith.b - a[2]};
    for (int k = 0; k < n; ++k) {
        has[k] = above[k] != 0 || hazeBelow;
        for (int i = 0; i < 3; ++i)
            rgb[3 * k + i] = static_cast<std::uint8_t>(a[i] + d[i] * t[k] + 0.5);
    }
}

void fillOutside(const SourceView& source, const Quadratic& sourceFromOutput,
                 const FieldView& field, int gainQ8, bool agc, const OutsideFill& fill,
                 ApplyResult& result) {
    fillField(source, QuadraticRows{sourceFromOutput}, field, gainQ8, agc, fill, result);
}

void fillOutsidePerPixel(const SourceView& source, const Quadratic& sourceFromOutput,
                         const FieldView& field, int gainQ8, bool agc, const OutsideFill& fill,
                         ApplyResult& result) {
    fillFieldPerPixel(source, QuadraticRows{sourceFromOutput}, field, gainQ8, agc, fill, result);
}

void fillOutside(const SourceView& source, const Homography& sourceFromOutput,
                 const FieldView& field, int gainQ8, bool agc, const OutsideFill& fill,
                 ApplyResult& result) {
    fillField(source, ProjectiveRows{sourceFromOutput}, field, gainQ8, agc, fill, result);
}

void fillOutside(const SourceView& source, const std::int32_t* xs, const std::int32_t* ys,
                 std::size_t stride, const FieldView& field, int gainQ8, bool agc,
                 const OutsideFill& fill, ApplyResult& result) {
    // The points as the rows the fill pass walks: 16.16 widened to the kernels' 32.32.
    struct PointRows {
        const std::int32_t *xs, *ys, *x = nullptr, *y = nullptr;
        std::size_t stride;
        int firstLine;
        void start(double rowY) {
            const auto line = static_cast<std::size_t>((rowY - 0.5 - firstLine) / 2.0);
            x = xs + line * stride;
            y = ys + line * stride;
        }
        void next() {
            ++x;
            ++y;
        }
        std::int64_t px() const { return std::int64_t{*x} * kPointScale; }
        std::int64_t py() const { return std::int64_t{*y} * kPointScale; }
    };
    fillField(source, PointRows{xs, ys, nullptr, nullptr, stride, field.firstLine}, field, gainQ8,
              agc, fill, result);
}

bool warpKernelSupported(WarpKernel kernel) {
    switch (kernel) {
        case WarpKernel::Auto:
        case WarpKernel::Scalar:
            return true;
        case WarpKernel::Avx2:
#if VIG_PRP_HAVE_AVX2
            return cpuHasAvx2();
#else
            return false;
#endif
        case WarpKernel::Avx512:
#if VIG_PRP_HAVE_AVX2
            return cpuHasAvx512();
#else
            return false;
#endif
    }
    return false;
}

ApplyResult applyQuadratic(const SourceView& source, const Quadratic& sourceFromOutput,
                           const FieldView& field, int gainQ8, bool agc, WarpKernel kernel) {
#if VIG_PRP_HAVE_AVX2
    if (kernel != WarpKernel::Scalar && avx2Takes(source, gainQ8)) {
        const bool avx512 =
            (kernel == WarpKernel::Auto || kernel == WarpKernel::Avx512) && cpuHasAvx512();
        if (avx512) return applyQuadraticAvx512(source, sourceFromOutput, field, gainQ8, agc);
        const bool avx2 =
            (kernel == WarpKernel::Auto || kernel == WarpKernel::Avx2) && cpuHasAvx2();
        if (avx2) return applyQuadraticAvx2(source, sourceFromOutput, field, gainQ8, agc);
    }
#else
    (void)kernel;
#endif
    return dispatch(source, QuadraticRows{sourceFromOutput}, field, gainQ8, agc);
}

ApplyResult applyPoints(const SourceView& source, const std::int32_t* xs, const std::int32_t* ys,
                        std::size_t stride, const FieldView& field, int gainQ8, bool agc,
                        WarpKernel kernel) {
#if VIG_PRP_HAVE_AVX2
    if (kernel != WarpKernel::Scalar && avx2Takes(source, gainQ8) && cpuHasAvx2()) {
        return applyPointsAvx2(source, xs, ys, stride, field, gainQ8, agc);
    }
#else
    (void)kernel;
#endif
    return dispatchKernel(field.format, gainQ8, agc, [&]<PixelFormat F, bool G, bool A>() {
        Sampler s(source);
        std::uint64_t luma = 0;
        for (int line = 0; line < field.lines; ++line) {
            LinePositions pos{xs + static_cast<std::size_t>(line) * stride,
                              ys + static_cast<std::size_t>(line) * stride};
            writePixels<F, G, A>(s, pos, field.width, gainQ8,
                                 field.pixels + static_cast<std::size_t>(line) * field.stride,
                                 luma);
        }
        return ApplyResult{s.edge, luma};
    });
}

ApplyResult applyHomography(const SourceView& source, const Homography& sourceFromOutput,
                            const FieldView& field, int gainQ8, bool agc) {
    return dispatch(source, ProjectiveRows{sourceFromOutput}, field, gainQ8, agc);
}

void convertRow(const std::uint8_t* rgb, int width, PixelFormat format, int gainQ8, bool agc,
                std::uint8_t* out, std::uint64_t& lumaSum) {
    // Summed here, added once: `out` is bytes, which may alias the caller's sum.
    std::uint64_t luma = 0;
    auto px = [&](int i, int& r, int& g, int& b) {
        r = rgb[3 * i];
        g = rgb[3 * i + 1];
        b = rgb[3 * i + 2];
        applyGain<true>(r, g, b, gainQ8);
        if (agc) luma += grey(r, g, b);
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
        lumaSum += luma;
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
    lumaSum += luma;
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
