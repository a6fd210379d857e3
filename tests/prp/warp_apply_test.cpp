#include "prp/warp_apply.hpp"
#include "prp/warp_apply_kernel.hpp"

#include <gtest/gtest.h>
#include <glm/geometric.hpp>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <random>
#include <string>
#include <vector>

namespace prp {
namespace {

std::vector<ig::Rgb8> pattern(int w, int h, int seed) {
    std::mt19937 rng(seed);
    std::uniform_int_distribution<int> d(0, 255);
    std::vector<ig::Rgb8> px(static_cast<std::size_t>(w) * h);
    for (auto& p : px) {
        p = {static_cast<std::uint8_t>(d(rng)), static_cast<std::uint8_t>(d(rng)),
             static_cast<std::uint8_t>(d(rng))};
    }
    return px;
}

// Double-precision bilinear sample with edge clamping (the obviously-correct twin).
void referenceSample(const std::vector<ig::Rgb8>& img, int w, int h, glm::dvec2 p, double out[3]) {
    const double x = std::clamp(p.x - 0.5, 0.0, w - 1.0), y = std::clamp(p.y - 0.5, 0.0, h - 1.0);
    const int x0 = std::min(static_cast<int>(x), w - 2), y0 = std::min(static_cast<int>(y), h - 2);
    const double fx = x - x0, fy = y - y0;
    auto at = [&](int xx, int yy, int c) {
        const ig::Rgb8 v = img[static_cast<std::size_t>(yy) * w + xx];
        return static_cast<double>(c == 0 ? v.r : c == 1 ? v.g : v.b);
    };
    for (int c = 0; c < 3; ++c) {
        out[c] = (1 - fy) * ((1 - fx) * at(x0, y0, c) + fx * at(x0 + 1, y0, c)) +
                 fy * ((1 - fx) * at(x0, y0 + 1, c) + fx * at(x0 + 1, y0 + 1, c));
    }
}

struct Output {
    std::vector<std::uint8_t> px;
    FieldView view;
    Output(int w, int frameH, int first, PixelFormat f) {
        const int lines = (frameH - first + 1) / 2;
        view = {nullptr, static_cast<std::size_t>(w) * bytesPerPixel(f), w, first, lines, f};
        px.resize(view.stride * lines);
        view.pixels = px.data();
    }
};

// A fill that varies across the image: a camera pitched up 10 degrees and rolled, so the
// horizon crosses the output and sky and haze colours both occur.
OutsideFill testFill(int outW, int outH) {
    ig::Pose pose;
    pose.pitch = 0.17;
    pose.roll = 0.3;
    OutputGeometry g;
    g.width = g.windowWidth = outW;
    g.height = g.windowHeight = outH;
    ig::Intrinsics in;
    in.width = outW;
    in.height = outH;
    in.focal = 0.8 * outW;
    ig::SkyModel sky;
    sky.zenith = {10, 40, 200};
    sky.horizon = {230, 220, 210};
    OutsideFill fill = OutsideFill::of(sky, in, g, pose);
    fill.hazeBelow = true;
    return fill;
}

TEST(WarpApply, IdentityCopiesTheWindowExactly) {
    const int w = 48, h = 40, margin = 5;
    const auto img = pattern(w, h, 1);
    const SourceView src{img.data(), w, h};
    for (const int first : {0, 1}) {
        Output out(w - 2 * margin, h - 2 * margin, first, PixelFormat::Rgb8);
        const Quadratic q = Quadratic::fromAffine({1, 0, 0, 1, margin, margin});
        const ApplyResult r = applyQuadratic(src, q, out.view, kUnityGain, false);
        EXPECT_EQ(r.edgeSamples, 0u);
        for (int line = 0; line < out.view.lines; ++line) {
            for (int x = 0; x < out.view.width; ++x) {
                const ig::Rgb8 want =
                    img[static_cast<std::size_t>(first + 2 * line + margin) * w + x + margin];
                const std::uint8_t* got = &out.px[line * out.view.stride + 3 * x];
                ASSERT_EQ(got[0], want.r);
                ASSERT_EQ(got[1], want.g);
                ASSERT_EQ(got[2], want.b);
            }
        }
    }
}

TEST(WarpApply, ForwardDifferencesMatchDirectBilinearEvaluation) {
    // Random quadratics over a 720-wide row: the fixed-point recurrence must stay within a
    // level of a double-precision bilinear sample everywhere.
    const int w = 760, h = 520;
    const auto img = pattern(w, h, 2);
    // Smooth the noise so a 1/256-pixel position error stays below one level.
    std::vector<ig::Rgb8> smooth(img.size());
    for (int y = 0; y < h; ++y) {
        for (int x = 0; x < w; ++x) {
            smooth[static_cast<std::size_t>(y) * w + x] = {
                static_cast<std::uint8_t>(128 + 100 * std::sin(x * 0.05 + y * 0.02)),
                static_cast<std::uint8_t>(128 + 100 * std::cos(x * 0.03 - y * 0.04)),
                static_cast<std::uint8_t>((x + 2 * y) & 255)};
        }
    }
    const SourceView src{smooth.data(), w, h};
    std::mt19937 rng(3);
    std::uniform_real_distribution<double> d(-1.0, 1.0);
    for (int trial = 0; trial < 6; ++trial) {
        Quadratic q;
        q.a = {20 + 5 * d(rng), 1 + 0.05 * d(rng), 0.05 * d(rng),
               2e-5 * d(rng),   2e-5 * d(rng),     2e-5 * d(rng)};
        q.b = {20 + 5 * d(rng), 0.05 * d(rng), 1 + 0.05 * d(rng),
               2e-5 * d(rng),   2e-5 * d(rng), 2e-5 * d(rng)};
        Output out(720, 486, trial % 2, PixelFormat::Rgb8);
        applyQuadratic(src, q, out.view, kUnityGain, false);
        int worst = 0;
        for (int line = 0; line < out.view.lines; line += 7) {
            for (int x = 0; x < 720; ++x) {
                double want[3];
                referenceSample(smooth, w, h, q({x + 0.5, out.view.firstLine + 2 * line + 0.5}),
                                want);
                for (int c = 0; c < 3; ++c) {
                    const int got = out.px[line * out.view.stride + 3 * x + c];
                    worst = std::max(worst, static_cast<int>(std::abs(got - want[c]) + 0.5));
                }
            }
        }
        EXPECT_LE(worst, 2) << trial;
    }
}

TEST(WarpApply, HalfPixelShiftAverages) {
    const int w = 8, h = 6;
    std::vector<ig::Rgb8> img(w * h);
    for (int y = 0; y < h; ++y) {
        for (int x = 0; x < w; ++x)
            img[y * w + x] = {static_cast<std::uint8_t>(x * 20), 0, 0};
    }
    Output out(6, 6, 0, PixelFormat::Rgb8);
    applyQuadratic({img.data(), w, h}, Quadratic::fromAffine({1, 0, 0, 1, 0.5, 0}), out.view,
                   kUnityGain, false);
    for (int x = 0; x < 6; ++x)
        EXPECT_EQ(out.px[3 * x], x * 20 + 10);
}

TEST(WarpApply, OutsideSamplesRepeatTheEdgeAndAreCounted) {
    const int w = 16, h = 12;
    const auto img = pattern(w, h, 4);
    for (const double shift : {-30.0, -3.0, 2.0, 25.0}) {
        Output out(w, h, 1, PixelFormat::Rgb8);
        const ApplyResult r =
            applyQuadratic({img.data(), w, h}, Quadratic::fromAffine({1, 0, 0, 1, shift, 0}),
                           out.view, kUnityGain, false);
        const int outside = std::min(w, static_cast<int>(std::ceil(std::abs(shift))));
        EXPECT_EQ(r.edgeSamples, static_cast<std::uint64_t>(outside * out.view.lines)) << shift;
        // Left of the frame every sample shows column 0, right of it column w - 1.
        for (int line = 0; line < out.view.lines; ++line) {
            const int fy = 2 * line + 1;
            const int x = shift < 0 ? 0 : w - 1;
            const ig::Rgb8 edge = img[fy * w + (shift < 0 ? 0 : w - 1)];
            EXPECT_NEAR(out.px[line * out.view.stride + 3 * x], edge.r, 1);
        }
    }
}

TEST(WarpApply, OutsideFillShowsSkyAboveTheHorizonAndHazeOrTheEdgeBelow) {
    // Camera pitched up, the frame shifted so the left third of the output samples outside it:
    // those pixels show skyColor of their ray (a per-pixel double evaluation) above the horizon
    // and, below it, the horizon colour or the repeated edge; the others the warp.
    const int w = 60, h = 40;
    const auto img = pattern(w, h, 5);
    ig::SkyModel sky;
    sky.zenith = {0, 0, 255};
    sky.horizon = {255, 255, 255};
    OutputGeometry g;
    g.width = g.windowWidth = w;
    g.height = g.windowHeight = h;
    ig::Intrinsics in;
    in.width = w;
    in.height = h;
    in.focal = 30.0;
    ig::Pose pose;
    pose.pitch = 0.2;
    OutsideFill fill = OutsideFill::of(sky, in, g, pose);
    const Quadratic q = Quadratic::fromAffine({1, 0, 0, 1, -20.0, 0});
    for (const bool agc : {false, true}) {
        fill.hazeBelow = !agc;  // with AGC: the edge repeated below the horizon
        Output filled(w, h, 0, PixelFormat::Rgb8), plain(w, h, 0, PixelFormat::Rgb8);
        const ApplyResult r0 = applyQuadratic({img.data(), w, h}, q, plain.view, kUnityGain, agc);
        ApplyResult r = applyQuadratic({img.data(), w, h}, q, filled.view, kUnityGain, agc);
        fillOutside({img.data(), w, h}, q, filled.view, kUnityGain, agc, fill, r);
        EXPECT_EQ(r.edgeSamples, r0.edgeSamples);
        EXPECT_EQ(r.edgeSamples, static_cast<std::uint64_t>(20 * filled.view.lines));
        const ig::CameraBasis basis = ig::CameraBasis::fromPose(pose);
        std::uint64_t luma = 0;
        int above = 0, below = 0;
        for (int line = 0; line < filled.view.lines; ++line) {
            const double y = 2 * line + 0.5;
            for (int x = 0; x < w; ++x) {
                const std::uint8_t* p = &filled.px[line * filled.view.stride + 3 * x];
                luma += greyOf(p[0], p[1], p[2]);
                if (x >= 20) {
                    // Inside: the warp as it was.
                    ASSERT_EQ(p[0], plain.px[line * plain.view.stride + 3 * x]);
                    continue;
                }
                const glm::dvec3 d = glm::normalize(
                    30.0 * basis.forward + (x + 0.5 - 30.0) * basis.right - (y - 20.0) * basis.up);
                const double t = std::sqrt(std::max(d.z, 0.0));
                (d.z > 0.0 ? above : below)++;
                if (d.z <= 0.0 && !fill.hazeBelow) {
                    // Below the horizon: the repeated edge, as without the fill.
                    ASSERT_EQ(p[0], plain.px[line * plain.view.stride + 3 * x]);
                    ASSERT_EQ(p[1], plain.px[line * plain.view.stride + 3 * x + 1]);
                    continue;
                }
                ASSERT_NEAR(p[0], 255.0 * (1.0 - t), 1.0) << x << ", " << y;
                ASSERT_EQ(p[2], 255);
            }
        }
        EXPECT_GT(above, 50);
        EXPECT_GT(below, 50);
        if (agc) {
            EXPECT_EQ(r.lumaSum, luma);
        }
    }
}

TEST(WarpApply, OutsideFillOfAProjectiveWarpMatchesTheQuadraticOne) {
    const int w = 40, h = 30;
    const auto img = pattern(w, h, 6);
    const Affine2 m{1.0, 0.0, 0.0, 1.0, 17.0, -9.0};
    const Homography hm{{m.m00, m.m01, m.tx, m.m10, m.m11, m.ty, 0.0, 0.0, 1.0}};
    const OutsideFill fill = testFill(w, h);
    Output a(w, h, 1, PixelFormat::Uyvy), b(w, h, 1, PixelFormat::Uyvy);
    ApplyResult ra =
        applyQuadratic({img.data(), w, h}, Quadratic::fromAffine(m), a.view, kUnityGain, true);
    ApplyResult rb = applyHomography({img.data(), w, h}, hm, b.view, kUnityGain, true);
    fillOutside({img.data(), w, h}, Quadratic::fromAffine(m), a.view, kUnityGain, true, fill, ra);
    fillOutside({img.data(), w, h}, hm, b.view, kUnityGain, true, fill, rb);
    EXPECT_EQ(ra.edgeSamples, rb.edgeSamples);
    EXPECT_GT(ra.edgeSamples, 0u);
    EXPECT_EQ(a.px, b.px);
    EXPECT_EQ(ra.lumaSum, rb.lumaSum);
}

TEST(Bt601, PrimariesMatchTheStandard) {
    // Rec. ITU-R BT.601 studio-range values of the 100% colour bars.
    struct Case {
        int r, g, b, y, cb, cr;
    };
    const Case cases[] = {{255, 255, 255, 235, 128, 128}, {0, 0, 0, 16, 128, 128},
                          {255, 0, 0, 81, 90, 240},       {0, 255, 0, 145, 54, 34},
                          {0, 0, 255, 41, 240, 110},      {255, 255, 0, 210, 16, 146},
                          {0, 255, 255, 170, 166, 16},    {255, 0, 255, 106, 202, 222}};
    for (const Case& c : cases) {
        const YCbCr v = bt601(c.r, c.g, c.b);
        EXPECT_EQ(v.y, c.y) << c.r << "," << c.g << "," << c.b;
        EXPECT_EQ(v.cb, c.cb) << c.r << "," << c.g << "," << c.b;
        EXPECT_EQ(v.cr, c.cr) << c.r << "," << c.g << "," << c.b;
    }
}

TEST(Bt601, SweepAgreesWithTheFormula) {
    for (int r = 0; r < 256; r += 15) {
        for (int g = 0; g < 256; g += 15) {
            for (int b = 0; b < 256; b += 15) {
                const double y = 16 + (65.481 * r + 128.553 * g + 24.966 * b) / 255;
                const double cb = 128 + (-37.797 * r - 74.203 * g + 112.0 * b) / 255;
                const double cr = 128 + (112.0 * r - 93.786 * g - 18.214 * b) / 255;
                const YCbCr v = bt601(r, g, b);
                ASSERT_LE(std::abs(v.y - y), 0.51);
                ASSERT_LE(std::abs(v.cb - cb), 0.51);
                ASSERT_LE(std::abs(v.cr - cr), 0.51);
            }
        }
    }
}

TEST(WarpApply, UyvyIsTheFusedBt601OfTheRgbWarp) {
    const int w = 40, h = 30;
    const auto img = pattern(w, h, 6);
    const Quadratic q = Quadratic::fromAffine({0.9, 0.1, -0.1, 0.95, 3.3, 2.7});
    Output rgb(w, h, 0, PixelFormat::Rgb8), uyvy(w, h, 0, PixelFormat::Uyvy),
        grey(w, h, 0, PixelFormat::Y8);
    applyQuadratic({img.data(), w, h}, q, rgb.view, kUnityGain, false);
    applyQuadratic({img.data(), w, h}, q, uyvy.view, kUnityGain, false);
    applyQuadratic({img.data(), w, h}, q, grey.view, kUnityGain, false);
    for (int line = 0; line < rgb.view.lines; ++line) {
        for (int x = 0; x < w; x += 2) {
            const std::uint8_t* p = &rgb.px[line * rgb.view.stride + 3 * x];
            const std::uint8_t* u = &uyvy.px[line * uyvy.view.stride + 2 * x];
            EXPECT_EQ(u[1], bt601Luma(p[0], p[1], p[2]));
            EXPECT_EQ(u[3], bt601Luma(p[3], p[4], p[5]));
            std::uint8_t cb, cr;
            bt601ChromaOfSum(p[0] + p[3], p[1] + p[4], p[2] + p[5], cb, cr);
            EXPECT_EQ(u[0], cb);
            EXPECT_EQ(u[2], cr);
            EXPECT_EQ(grey.px[line * grey.view.stride + x], greyOf(p[0], p[1], p[2]));
        }
    }
}

TEST(WarpApply, HomographyAgreesWithAnEqualAffineQuadratic) {
    const int w = 50, h = 40;
    const auto img = pattern(w, h, 8);
    const Affine2 m{0.97, 0.05, -0.04, 1.02, 4.2, 3.1};
    Homography hm;
    hm.h = {m.m00, m.m01, m.tx, m.m10, m.m11, m.ty, 0, 0, 1};
    Output a(44, 34, 1, PixelFormat::Rgb8), b(44, 34, 1, PixelFormat::Rgb8);
    const ApplyResult ra =
        applyQuadratic({img.data(), w, h}, Quadratic::fromAffine(m), a.view, kUnityGain, false);
    const ApplyResult rb = applyHomography({img.data(), w, h}, hm, b.view, kUnityGain, false);
    EXPECT_EQ(ra.edgeSamples, rb.edgeSamples);
    int worst = 0;
    for (std::size_t i = 0; i < a.px.size(); ++i)
        worst = std::max(worst, std::abs(a.px[i] - b.px[i]));
    EXPECT_LE(worst, 1);
}

void expectKernelAgrees(WarpKernel kernel, const std::vector<ig::Rgb8>& img, int w, int h,
                        const Quadratic& q, int outW, int frameH, int first, PixelFormat f,
                        int gainQ8, bool agc, const std::string& what) {
    Output scalar(outW, frameH, first, f), simd(outW, frameH, first, f);
    // Different fill values: a pixel either kernel leaves unwritten shows up as a mismatch.
    std::fill(scalar.px.begin(), scalar.px.end(), 0x11);
    std::fill(simd.px.begin(), simd.px.end(), 0x11);
    const ApplyResult rs =
        applyQuadratic({img.data(), w, h}, q, scalar.view, gainQ8, agc, WarpKernel::Scalar);
    const ApplyResult rv = applyQuadratic({img.data(), w, h}, q, simd.view, gainQ8, agc, kernel);
    EXPECT_EQ(rs.edgeSamples, rv.edgeSamples) << what;
    EXPECT_EQ(rs.lumaSum, rv.lumaSum) << what;
    std::size_t mismatches = 0, firstBad = 0;
    for (std::size_t i = 0; i < scalar.px.size(); ++i) {
        if (scalar.px[i] != simd.px[i] && mismatches++ == 0) firstBad = i;
    }
    EXPECT_EQ(mismatches, 0u) << what << ": first at byte " << firstBad << " of "
                              << scalar.px.size();
    // The out-of-frame fill over either kernel's field: the same field again.
    const OutsideFill fill = testFill(outW, frameH);
    ApplyResult fs = rs, fv = rv;
    fillOutside({img.data(), w, h}, q, scalar.view, gainQ8, agc, fill, fs);
    fillOutside({img.data(), w, h}, q, simd.view, gainQ8, agc, fill, fv);
    EXPECT_EQ(fs.lumaSum, fv.lumaSum) << what << " (filled)";
    EXPECT_EQ(fs.edgeSamples, rs.edgeSamples) << what << " (filled)";
    EXPECT_TRUE(scalar.px == simd.px) << what << " (filled)";
}

// The SIMD kernels this processor runs.
std::vector<WarpKernel> simdKernels() {
    std::vector<WarpKernel> kernels;
    for (const WarpKernel k : {WarpKernel::Avx2, WarpKernel::Avx512}) {
        if (warpKernelSupported(k)) kernels.push_back(k);
    }
    return kernels;
}

const char* kernelName(WarpKernel k) {
    return k == WarpKernel::Avx2 ? "avx2" : k == WarpKernel::Avx512 ? "avx512" : "other";
}

// Runs `q` through the scalar and every SIMD kernel; expects identical bytes and counts.
void expectKernelsAgree(const std::vector<ig::Rgb8>& img, int w, int h, const Quadratic& q,
                        int outW, int frameH, int first, PixelFormat f, int gainQ8, bool agc,
                        const std::string& what) {
    for (const WarpKernel k : simdKernels()) {
        expectKernelAgrees(k, img, w, h, q, outW, frameH, first, f, gainQ8, agc,
                           what + " (" + kernelName(k) + ")");
    }
}

// A rotation, zoom and curvature with the output pushed partly or wholly out of the source.
Quadratic randomWarp(std::mt19937& rng, int w, int h, int outW, int outH) {
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    const double angle = 0.3 * u(rng), scale = 1.0 + 0.3 * u(rng);
    const double c = scale * std::cos(angle), s = scale * std::sin(angle);
    // Centre the output on the source, then push it partly (or wholly) out of the frame.
    const double tx = 0.5 * w - (c * 0.5 * outW - s * 0.5 * outH) + 0.6 * w * u(rng);
    const double ty = 0.5 * h - (s * 0.5 * outW + c * 0.5 * outH) + 0.6 * h * u(rng);
    Quadratic q = Quadratic::fromAffine({c, -s, s, c, tx, ty});
    const double k = 0.5 / (outW * outW + outH * outH);
    for (int i = 3; i < 6; ++i) {
        q.a[i] = k * u(rng);
        q.b[i] = k * u(rng);
    }
    return q;
}

TEST(WarpApplySimd, MatchesScalarBitForBitOnRandomWarps) {
    if (simdKernels().empty()) GTEST_SKIP() << "no SIMD kernel on this processor";
    std::mt19937 rng(11);
    std::uniform_int_distribution<int> size(2, 70);
    const PixelFormat formats[] = {PixelFormat::Rgb8, PixelFormat::Y8, PixelFormat::Uyvy};
    for (int trial = 0; trial < 300; ++trial) {
        const int w = size(rng), h = size(rng);
        const int outW = std::uniform_int_distribution<int>(1, 75)(rng);
        const int outH = std::uniform_int_distribution<int>(1, 40)(rng);
        const auto img = pattern(w, h, 100 + trial);
        const Quadratic q = randomWarp(rng, w, h, outW, outH);
        const PixelFormat f = formats[trial % 3];
        const int gainQ8 = trial % 4 == 0 ? kUnityGain : 64 + 16 * (trial % 40);
        const bool agc = trial % 2 == 1;
        expectKernelsAgree(img, w, h, q, outW, outH, trial % 2, f, gainQ8, agc,
                           "trial " + std::to_string(trial) + " source " + std::to_string(w) + "x" +
                               std::to_string(h) + " out " + std::to_string(outW) + "x" +
                               std::to_string(outH));
    }
}

TEST(WarpApplySimd, MatchesScalarOnFullFieldsAcrossTheFrameEdges) {
    // A 720-wide field slid across the source: all in, partly out on each side, wholly out.
    if (simdKernels().empty()) GTEST_SKIP() << "no SIMD kernel on this processor";
    const int w = 800, h = 300, outW = 720, outH = 256;
    const auto img = pattern(w, h, 21);
    const double c = std::cos(0.05), s = std::sin(0.05);
    for (const double shift : {0.0, -60.0, 70.25, 500.0, -900.0}) {
        Quadratic q;
        q.a = {40 + shift, 1.01 * c, -s, 2e-6, 1e-5, -4e-6};
        q.b = {20 - 0.3 * shift, s, 1.01 * c, -3e-6, 5e-6, 2e-5};
        for (const PixelFormat f : {PixelFormat::Uyvy, PixelFormat::Rgb8, PixelFormat::Y8}) {
            expectKernelsAgree(img, w, h, q, outW, outH, 1, f, kUnityGain, false,
                               "shift " + std::to_string(shift));
        }
        expectKernelsAgree(img, w, h, q, outW, outH, 0, PixelFormat::Uyvy, 700, true,
                           "gain, shift " + std::to_string(shift));
    }
}

TEST(WarpApplySimd, SaturatingGainMatchesScalar) {
    if (simdKernels().empty()) GTEST_SKIP() << "no SIMD kernel on this processor";
    const int w = 40, h = 30;
    const auto img = pattern(w, h, 31);
    const Quadratic q = Quadratic::fromAffine({0.9, 0.1, -0.1, 0.95, 3.3, 2.7});
    for (const int gainQ8 : {0, 1, 255, 257, 4096, 1 << 16}) {
        for (const PixelFormat f : {PixelFormat::Uyvy, PixelFormat::Rgb8, PixelFormat::Y8}) {
            expectKernelsAgree(img, w, h, q, 36, 26, 0, f, gainQ8, true,
                               "gain " + std::to_string(gainQ8));
        }
    }
}

// A fill of a random camera: any pitch (the horizon anywhere, or off the field), any roll, a
// field scaled onto a smaller or larger rendered window, haze below the horizon or not.
OutsideFill randomFill(std::mt19937& rng, int outW, int outH) {
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    ig::Pose pose;
    pose.yaw = 3.0 * u(rng);
    pose.pitch = 1.5 * u(rng);
    pose.roll = 0.8 * u(rng);
    OutputGeometry g;
    g.width = outW;
    g.height = outH;
    g.windowWidth = std::max(1, static_cast<int>(outW * (1.0 + 0.3 * u(rng))));
    g.windowHeight = std::max(1, static_cast<int>(outH * (1.0 + 0.3 * u(rng))));
    ig::Intrinsics in;
    in.width = g.windowWidth;
    in.height = g.windowHeight;
    in.focal = (0.5 + 0.5 * (u(rng) + 1.0)) * outW;
    ig::SkyModel sky;
    std::uniform_int_distribution<int> byte(0, 255);
    sky.zenith = {static_cast<std::uint8_t>(byte(rng)), static_cast<std::uint8_t>(byte(rng)),
                  static_cast<std::uint8_t>(byte(rng))};
    sky.horizon = {static_cast<std::uint8_t>(byte(rng)), static_cast<std::uint8_t>(byte(rng)),
                   static_cast<std::uint8_t>(byte(rng))};
    OutsideFill fill = OutsideFill::of(sky, in, g, pose);
    fill.hazeBelow = u(rng) > 0.0;
    return fill;
}

TEST(WarpApply, OutsideFillIsItsPerPixelTwinBitForBit) {
    // The fill a run at a time against the one a pixel at a time, over every kernel's field:
    // same bytes, same luma sum, same edge count, in every format, with and without gain and
    // AGC, over warps partly or wholly out of the frame.
    std::mt19937 rng(17);
    std::uniform_int_distribution<int> size(2, 70);
    const PixelFormat formats[] = {PixelFormat::Rgb8, PixelFormat::Y8, PixelFormat::Uyvy};
    std::vector<WarpKernel> kernels = simdKernels();
    kernels.push_back(WarpKernel::Scalar);
    int rewritten = 0;
    for (int trial = 0; trial < 300; ++trial) {
        const int w = size(rng), h = size(rng);
        const int outW = 2 * std::uniform_int_distribution<int>(1, 90)(rng);
        const int outH = std::uniform_int_distribution<int>(1, 40)(rng);
        const auto img = pattern(w, h, 300 + trial);
        const Quadratic q = randomWarp(rng, w, h, outW, outH);
        const OutsideFill fill = randomFill(rng, outW, outH);
        const PixelFormat f = formats[trial % 3];
        const int gainQ8 = trial % 4 == 0 ? kUnityGain : 64 + 16 * (trial % 40);
        const bool agc = trial % 2 == 1;
        const WarpKernel kernel = kernels[static_cast<std::size_t>(trial) % kernels.size()];
        const std::string what = "trial " + std::to_string(trial);
        Output fast(outW, outH, trial % 2, f), slow(outW, outH, trial % 2, f);
        ApplyResult rf = applyQuadratic({img.data(), w, h}, q, fast.view, gainQ8, agc, kernel);
        ApplyResult rs = applyQuadratic({img.data(), w, h}, q, slow.view, gainQ8, agc, kernel);
        const std::vector<std::uint8_t> warped = fast.px;
        fillOutside({img.data(), w, h}, q, fast.view, gainQ8, agc, fill, rf);
        fillOutsidePerPixel({img.data(), w, h}, q, slow.view, gainQ8, agc, fill, rs);
        ASSERT_EQ(fast.px, slow.px) << what;
        EXPECT_EQ(rf.lumaSum, rs.lumaSum) << what;
        EXPECT_EQ(rf.edgeSamples, rs.edgeSamples) << what;
        rewritten += fast.px != warped;
    }
    // The cases reach the fill: most fields have pixels it writes again.
    EXPECT_GT(rewritten, 150);
}

TEST(WarpApply, SkyRowsAreColorAtInEveryInstructionSet) {
    // colorsAlong (a row at a time, the processor's widest path) against colorAt pixel by
    // pixel, and the SSE2 and AVX-512 rows against each other to the bit.
    std::mt19937 rng(23);
    std::uniform_int_distribution<int> count(1, 64), start(-20, 700), row(0, 500);
    int above = 0, below = 0;
    for (int trial = 0; trial < 400; ++trial) {
        const OutsideFill fill = randomFill(rng, 720, 486);
        const int x0 = start(rng), n = count(rng);
        const double y = row(rng) + 0.5;
        bool has[64];
        std::uint8_t rgb[3 * 64];
        fill.colorsAlong(x0, n, y, has, rgb);
        for (int k = 0; k < n; ++k) {
            ig::Rgb8 c{1, 2, 3};
            const bool expected = fill.colorAt(x0 + k + 0.5, y, c);
            ASSERT_EQ(has[k], expected) << "trial " << trial << " pixel " << k;
            (expected ? above : below)++;
            if (!expected) continue;
            ASSERT_EQ(rgb[3 * k], c.r) << "trial " << trial << " pixel " << k;
            ASSERT_EQ(rgb[3 * k + 1], c.g) << "trial " << trial << " pixel " << k;
            ASSERT_EQ(rgb[3 * k + 2], c.b) << "trial " << trial << " pixel " << k;
        }
#if VIG_PRP_HAVE_AVX2
        if (!detail::cpuHasAvx512()) continue;
        const double v = fill.sy * y - fill.cy;
        const detail::SkyRow sky{fill.sx,
                                 fill.cx,
                                 fill.focal * fill.forwardZ,
                                 fill.rightZ,
                                 v * fill.upZ,
                                 fill.focal * fill.focal,
                                 v * v,
                                 x0};
        double t1[64], t2[64];
        std::uint8_t a1[64], a2[64];
        detail::skyRowSse2(sky, n, t1, a1);
        detail::skyRowAvx512(sky, n, t2, a2);
        for (int k = 0; k < n; ++k) {
            ASSERT_EQ(std::memcmp(&t1[k], &t2[k], sizeof(double)), 0) << "trial " << trial;
            ASSERT_EQ(a1[k], a2[k]) << "trial " << trial;
        }
#endif
    }
    EXPECT_GT(above, 1000);
    EXPECT_GT(below, 1000);
}

TEST(WarpApply, EveryKernelNameRunsAndAgrees) {
    // Auto and a kernel the processor may lack both fall back cleanly (Scalar is always there).
    EXPECT_TRUE(warpKernelSupported(WarpKernel::Scalar));
    EXPECT_TRUE(warpKernelSupported(WarpKernel::Auto));
    const int w = 30, h = 20;
    const auto img = pattern(w, h, 41);
    const Quadratic q = Quadratic::fromAffine({1.02, 0.03, -0.02, 0.99, -2.5, 1.5});
    Output ref(28, 18, 1, PixelFormat::Uyvy);
    const ApplyResult rr =
        applyQuadratic({img.data(), w, h}, q, ref.view, kUnityGain, true, WarpKernel::Scalar);
    for (const WarpKernel k : {WarpKernel::Auto, WarpKernel::Avx2, WarpKernel::Avx512}) {
        Output out(28, 18, 1, PixelFormat::Uyvy);
        const ApplyResult r = applyQuadratic({img.data(), w, h}, q, out.view, kUnityGain, true, k);
        EXPECT_EQ(r.edgeSamples, rr.edgeSamples);
        EXPECT_EQ(r.lumaSum, rr.lumaSum);
        EXPECT_EQ(out.px, ref.px);
    }
}

}  // namespace
}  // namespace prp
