// One 720x243 NTSC field: the PRP's fused warp + UYVY against OpenCV's cv::remap.
#include "ig/caster.hpp"
#include "prp/processor.hpp"
#include "prp/warp_apply.hpp"
#include "prp/warp_fit.hpp"

#include <glm/geometric.hpp>

#include <benchmark/benchmark.h>

#if VIG_HAVE_OPENCV
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>
#endif

#include <cmath>
#include <vector>

namespace {

constexpr int kW = 720, kH = 486, kMargin = 48;
constexpr int kSrcW = kW + 2 * kMargin, kSrcH = kH + 2 * kMargin;

std::vector<ig::Rgb8> sourceImage() {
    std::vector<ig::Rgb8> px(static_cast<std::size_t>(kSrcW) * kSrcH);
    for (int y = 0; y < kSrcH; ++y) {
        for (int x = 0; x < kSrcW; ++x) {
            px[static_cast<std::size_t>(y) * kSrcW + x] = {
                static_cast<std::uint8_t>(128 + 100 * std::sin(x * 0.05 + y * 0.02)),
                static_cast<std::uint8_t>(128 + 100 * std::cos(x * 0.03 - y * 0.04)),
                static_cast<std::uint8_t>((x ^ y) & 255)};
        }
    }
    return px;
}

// A typical warp: small roll, zoom and perspective curvature.
prp::Quadratic typicalWarp() {
    prp::Quadratic q;
    const double c = std::cos(0.05), s = std::sin(0.05);
    q.a = {kMargin + 12.3, 1.01 * c, -s, 2e-6, 1e-5, -4e-6};
    q.b = {kMargin - 7.9, s, 1.01 * c, -3e-6, 5e-6, 2e-5};
    return q;
}

// The share of a field's samples beyond the frame, and the time per field pixel.
void countEdges(benchmark::State& state, const prp::ApplyResult& r) {
    benchmark::DoNotOptimize(r);
    state.counters["edge_pct"] = 100.0 * r.edgeSamples / (static_cast<double>(kW) * (kH / 2));
}
void countPixels(benchmark::State& state) {
    state.counters["ns_per_px"] = benchmark::Counter(
        static_cast<double>(kW) * (kH / 2),
        benchmark::Counter::kIsIterationInvariantRate | benchmark::Counter::kInvert);
}

// The PRP's warp of one field in `format` with `kernel` (Auto: the one the processor runs; a
// named kernel the processor lacks is reported as an error, not timed).
// `shiftX` moves the field that many source pixels right (past the margin: edge samples).
void prpField(benchmark::State& state, prp::PixelFormat format, prp::WarpKernel kernel,
              double shiftX = 0.0) {
    if (!prp::warpKernelSupported(kernel)) {
        state.SkipWithError("kernel not supported by this processor");
        return;
    }
    const auto src = sourceImage();
    prp::Quadratic q = typicalWarp();
    q.a[0] += shiftX;
    const std::size_t stride = static_cast<std::size_t>(kW) * prp::bytesPerPixel(format);
    std::vector<std::uint8_t> out(stride * (kH / 2));
    const prp::FieldView view{out.data(), stride, kW, 1, kH / 2, format};
    for (auto _ : state) {
        const prp::ApplyResult r = prp::applyQuadratic({src.data(), kSrcW, kSrcH}, q, view,
                                                       prp::kUnityGain, false, kernel);
        benchmark::DoNotOptimize(out.data());
        countEdges(state, r);
    }
    countPixels(state);
}
void BM_PrpWarpUyvyField(benchmark::State& state) {
    prpField(state, prp::PixelFormat::Uyvy, prp::WarpKernel::Auto);
}
void BM_PrpWarpUyvyFieldScalar(benchmark::State& state) {
    prpField(state, prp::PixelFormat::Uyvy, prp::WarpKernel::Scalar);
}
void BM_PrpWarpUyvyFieldAvx2(benchmark::State& state) {
    prpField(state, prp::PixelFormat::Uyvy, prp::WarpKernel::Avx2);
}
void BM_PrpWarpUyvyFieldAvx512(benchmark::State& state) {
    prpField(state, prp::PixelFormat::Uyvy, prp::WarpKernel::Avx512);
}
// A quarter of the field beyond the right edge of the frame: clamped, counted samples.
void BM_PrpWarpUyvyFieldEdges(benchmark::State& state) {
    prpField(state, prp::PixelFormat::Uyvy, prp::WarpKernel::Auto, kMargin + 0.25 * kW);
}
void BM_PrpWarpUyvyFieldEdgesScalar(benchmark::State& state) {
    prpField(state, prp::PixelFormat::Uyvy, prp::WarpKernel::Scalar, kMargin + 0.25 * kW);
}
// The same field with the sky drawn beyond the frame (prp::fillOutside, as the processor does
// with an edge fill other than repeat): `shiftX` as above; a camera 3 degrees up, so the
// horizon crosses the field. `haze`: below the horizon too (--edge-fill sky-haze; else the
// repeated edge stays there, the default); `agc`: the luma sum corrected; `perPixel`: the
// fill's slow twin. Times the warp and the fill together.
void prpFilledField(benchmark::State& state, double shiftX, bool haze, bool agc,
                    bool perPixel = false) {
    const auto src = sourceImage();
    prp::Quadratic q = typicalWarp();
    q.a[0] += shiftX;
    const prp::PixelFormat format = prp::PixelFormat::Uyvy;
    const std::size_t stride = static_cast<std::size_t>(kW) * prp::bytesPerPixel(format);
    std::vector<std::uint8_t> out(stride * (kH / 2));
    const prp::FieldView view{out.data(), stride, kW, 1, kH / 2, format};
    ig::SkyModel sky;
    ig::Intrinsics in;
    in.width = kSrcW;
    in.height = kSrcH;
    in.focal = 0.8 * kW;
    prp::OutputGeometry g;
    g.width = g.windowWidth = kW;
    g.height = g.windowHeight = kH;
    ig::Pose pose;
    pose.pitch = 0.05;
    prp::OutsideFill fill = prp::OutsideFill::of(sky, in, g, pose);
    fill.hazeBelow = haze;
    const prp::SourceView source{src.data(), kSrcW, kSrcH};
    for (auto _ : state) {
        prp::ApplyResult r = prp::applyQuadratic(source, q, view, prp::kUnityGain, agc);
        if (perPixel) {
            prp::fillOutsidePerPixel(source, q, view, prp::kUnityGain, agc, fill, r);
        } else {
            prp::fillOutside(source, q, view, prp::kUnityGain, agc, fill, r);
        }
        benchmark::DoNotOptimize(out.data());
        countEdges(state, r);
    }
    countPixels(state);
}
// A quarter of the field beyond the frame, filled (sky only, no AGC: the defaults).
void BM_PrpWarpUyvyFieldEdgesFilled(benchmark::State& state) {
    prpFilledField(state, kMargin + 0.25 * kW, false, false);
}
// The whole field beyond the frame (a frame far older than the turn it must cover), filled.
void BM_PrpWarpUyvyFieldOutsideFilled(benchmark::State& state) {
    prpFilledField(state, 2.0 * kSrcW, false, false);
}
void BM_PrpWarpUyvyFieldOutsideFilledPerPixel(benchmark::State& state) {
    prpFilledField(state, 2.0 * kSrcW, false, false, true);
}
// The same with haze below the horizon and AGC: every pixel written again, its luma replaced.
void BM_PrpWarpUyvyFieldOutsideHazeAgc(benchmark::State& state) {
    prpFilledField(state, 2.0 * kSrcW, true, true);
}
void BM_PrpWarpUyvyFieldOutsideHazeAgcPerPixel(benchmark::State& state) {
    prpFilledField(state, 2.0 * kSrcW, true, true, true);
}
void BM_PrpWarpRgbField(benchmark::State& state) {
    prpField(state, prp::PixelFormat::Rgb8, prp::WarpKernel::Auto);
}
void BM_PrpWarpRgbFieldScalar(benchmark::State& state) {
    prpField(state, prp::PixelFormat::Rgb8, prp::WarpKernel::Scalar);
}
// The whole processor on one field of a frame with depth: a ground plane seen from 60 m at
// 20 degrees down, warped to a pose 8 fields on at 200 m/s (rolled, turning). `model` Depth
// (the gather or the splat, `method`, with `kernel`), Poly or Auto; the time includes the fit.
void prpProcess(benchmark::State& state, prp::WarpModel model, prp::DepthKernel kernel,
                prp::DepthMethod method = prp::DepthMethod::Splat, bool newFrames = false) {
    if (!prp::depthKernelSupported(kernel)) {
        state.SkipWithError("kernel not supported by this processor");
        return;
    }
    ig::RenderedFrame frame;
    frame.intrinsics = ig::Intrinsics::fromFov(kW, kH, 1.0471975511965976, kMargin);
    frame.pose.position = {1000.0, 2000.0, 60.0};
    frame.pose.pitch = -0.35;
    frame.color = sourceImage();
    frame.depth.resize(frame.color.size());
    const ig::Camera cam(frame.pose, frame.intrinsics);
    for (int y = 0; y < kSrcH; ++y) {
        for (int x = 0; x < kSrcW; ++x) {
            const glm::dvec3 d = glm::normalize(cam.rayDirection(x + 0.5, y + 0.5));
            frame.depth[static_cast<std::size_t>(y) * kSrcW + x] =
                d.z < -1e-9 ? static_cast<float>(-frame.pose.position.z / d.z) : ig::kSkyDepth;
        }
    }
    const auto pixels = ig::controlPointPixels(frame.intrinsics);
    for (int k = 0; k < ig::kControlPointCount; ++k) {
        const glm::dvec3 d = glm::normalize(cam.rayDirection(pixels[k].x, pixels[k].y));
        frame.controlPoints[k].pixel = pixels[k];
        frame.controlPoints[k].world =
            d.z < -1e-9 ? glm::dvec4(frame.pose.position - frame.pose.position.z / d.z * d, 1.0)
                        : glm::dvec4(d, 0.0);
    }
    ig::Pose at = frame.pose;
    const double dt = 8 * prp::kFieldPeriod;
    at.position.y += 200.0 * dt;
    at.yaw += 0.1 * dt;
    at.roll = 0.05;
    prp::PrpOptions o;
    o.outWidth = kW;
    o.outHeight = kH;
    o.format = prp::PixelFormat::Uyvy;
    o.model = model;
    o.depthKernel = kernel;
    o.depthMethod = method;
    prp::PostRenderingProcessor prp(o);
    prp::Field field;
    std::uint64_t index = 1;
    for (auto _ : state) {
        // A new frame every field: what is made once per frame is made every time.
        if (newFrames) ++frame.sequence;
        prp.process(frame, at, 0.0, index, field);
        index += 2;  // the same parity every time
        benchmark::DoNotOptimize(field.pixels.data());
    }
    const double outPixels = static_cast<double>(field.width) * field.lines;
    state.counters["holes_pct"] = 100.0 * field.holeSamples / outPixels;
    if (model == prp::WarpModel::Depth) {
        // The gather's share of pixels that did not settle, and of pixels the splat made.
        prp::DepthWarp warp;
        prp::Field scratch = field;
        const prp::FieldView view{scratch.pixels.data(), scratch.stride,
                                  scratch.width,         prp::fieldFirstLine(scratch.parity),
                                  scratch.lines,         scratch.format};
        const prp::DepthWarpResult r = warp.apply(
            frame, frame.color.data(), at, prp::OutputGeometry::of(frame.intrinsics, kW, kH),
            prp::quadraticOf(field.warp), view, prp::kUnityGain, false, kernel, method);
        state.counters["unsettled_pct"] = 100.0 * r.unsettled / outPixels;
        state.counters["splat_pct"] = 100.0 * r.splatPixels / outPixels;
    }
    state.counters["ns_per_px"] = benchmark::Counter(
        static_cast<double>(kW) * (kH / 2),
        benchmark::Counter::kIsIterationInvariantRate | benchmark::Counter::kInvert);
}
void BM_PrpDepthUyvyField(benchmark::State& state) {
    prpProcess(state, prp::WarpModel::Depth, prp::DepthKernel::Auto);
}
// Every field from a new frame (a renderer as fast as the fields): the per-frame work (the
// scaled depths, the anti-twitter filter) in every field instead of once for a frame's fields.
void BM_PrpDepthUyvyFieldNewFrames(benchmark::State& state) {
    prpProcess(state, prp::WarpModel::Depth, prp::DepthKernel::Auto, prp::DepthMethod::Splat, true);
}
void BM_PrpDepthUyvyFieldScalar(benchmark::State& state) {
    prpProcess(state, prp::WarpModel::Depth, prp::DepthKernel::Scalar);
}
// The gather (Newton steps from the quadratic's point; the splat in tiles where they do not
// settle), AVX2 and its scalar twin.
void BM_PrpDepthUyvyFieldGather(benchmark::State& state) {
    prpProcess(state, prp::WarpModel::Depth, prp::DepthKernel::Auto, prp::DepthMethod::Gather);
}
void BM_PrpDepthUyvyFieldGatherScalar(benchmark::State& state) {
    prpProcess(state, prp::WarpModel::Depth, prp::DepthKernel::Scalar, prp::DepthMethod::Gather);
}
void BM_PrpPolyUyvyFieldWithFit(benchmark::State& state) {
    prpProcess(state, prp::WarpModel::Poly, prp::DepthKernel::Auto);
}
BENCHMARK(BM_PrpDepthUyvyField)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_PrpDepthUyvyFieldNewFrames)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_PrpDepthUyvyFieldScalar)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_PrpDepthUyvyFieldGather)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_PrpDepthUyvyFieldGatherScalar)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_PrpPolyUyvyFieldWithFit)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_PrpWarpUyvyField)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_PrpWarpUyvyFieldScalar)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_PrpWarpUyvyFieldAvx2)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_PrpWarpUyvyFieldAvx512)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_PrpWarpUyvyFieldEdges)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_PrpWarpUyvyFieldEdgesScalar)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_PrpWarpUyvyFieldEdgesFilled)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_PrpWarpUyvyFieldOutsideFilled)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_PrpWarpUyvyFieldOutsideFilledPerPixel)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_PrpWarpUyvyFieldOutsideHazeAgc)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_PrpWarpUyvyFieldOutsideHazeAgcPerPixel)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_PrpWarpRgbField)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_PrpWarpRgbFieldScalar)->Unit(benchmark::kMicrosecond);

#if VIG_HAVE_OPENCV
// cv::remap with precomputed fixed-point maps (CV_16SC2 + CV_16UC1), bilinear, one thread,
// to an RGB field of the same lines; optionally followed by OpenCV's YUV 4:2:2 conversion.
void remapField(benchmark::State& state, bool toUyvy) {
    cv::setNumThreads(1);
    const auto src = sourceImage();
    cv::Mat image(kSrcH, kSrcW, CV_8UC3, const_cast<ig::Rgb8*>(src.data()));
    const prp::Quadratic q = typicalWarp();
    cv::Mat mapX(kH / 2, kW, CV_32FC1), mapY(kH / 2, kW, CV_32FC1);
    for (int line = 0; line < kH / 2; ++line) {
        for (int x = 0; x < kW; ++x) {
            const glm::dvec2 p = q({x + 0.5, 2 * line + 1 + 0.5});
            mapX.at<float>(line, x) = static_cast<float>(p.x - 0.5);
            mapY.at<float>(line, x) = static_cast<float>(p.y - 0.5);
        }
    }
    cv::Mat fixedXY, fixedA;
    cv::convertMaps(mapX, mapY, fixedXY, fixedA, CV_16SC2);
    cv::Mat field(kH / 2, kW, CV_8UC3), yuv;
    for (auto _ : state) {
        cv::remap(image, field, fixedXY, fixedA, cv::INTER_LINEAR, cv::BORDER_REPLICATE);
        if (toUyvy) {
            // OpenCV has no RGB -> UYVY; the closest single call is RGB -> YUV 4:4:4.
            cv::cvtColor(field, yuv, cv::COLOR_RGB2YUV);
        }
        benchmark::DoNotOptimize(field.data);
    }
    state.counters["ns_per_px"] = benchmark::Counter(
        static_cast<double>(kW) * (kH / 2),
        benchmark::Counter::kIsIterationInvariantRate | benchmark::Counter::kInvert);
}
void BM_OpenCvRemapField(benchmark::State& state) {
    remapField(state, false);
}
void BM_OpenCvRemapThenYuvField(benchmark::State& state) {
    remapField(state, true);
}
BENCHMARK(BM_OpenCvRemapField)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_OpenCvRemapThenYuvField)->Unit(benchmark::kMicrosecond);
#endif

}  // namespace

BENCHMARK_MAIN();
