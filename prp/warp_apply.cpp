#include "prp/warp_apply.hpp"

#include "prp/warp_apply_kernel.hpp"

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

}  // namespace

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
