#include "common/cone_map.hpp"
#include "ig/caster.hpp"
#include "prp/depth_warp.hpp"
#include "prp/processor.hpp"
#include "prp/synthetic_frame.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <random>
#include <vector>

namespace prp {
namespace {

const ig::Intrinsics kIn = ig::Intrinsics::fromFov(160, 120, 1.0, 16);

PrpOptions options(const ig::Intrinsics& in, WarpModel m, DepthMethod method) {
    PrpOptions o;
    o.outWidth = in.windowWidth();
    o.outHeight = in.windowHeight();
    o.format = PixelFormat::Rgb8;
    o.model = m;
    o.depthMethod = method;
    return o;
}

Field process(const ig::RenderedFrame& frame, const ig::Pose& at, WarpModel m,
              DepthMethod method = DepthMethod::Gather, DepthKernel kernel = DepthKernel::Auto,
              std::uint64_t index = 1) {
    PrpOptions o = options(frame.intrinsics, m, method);
    o.depthKernel = kernel;
    Field field;
    PostRenderingProcessor(o).process(frame, at, 0.0, index, field);
    return field;
}

// The depth warp applied directly (its statistics and flags), with the processor's quadratic.
struct Gathered {
    Field field;
    DepthWarpResult result;
    std::vector<std::uint8_t> unsettled;
};
Gathered gather(const ig::RenderedFrame& frame, const ig::Pose& at,
                DepthKernel kernel = DepthKernel::Auto) {
    Gathered g;
    g.field = process(frame, at, WarpModel::Poly);
    const FieldView view{g.field.pixels.data(),          g.field.stride, g.field.width,
                         fieldFirstLine(g.field.parity), g.field.lines,  g.field.format};
    DepthWarp warp;
    const OutputGeometry geometry =
        OutputGeometry::of(frame.intrinsics, g.field.width, g.field.frameHeight);
    g.result = warp.apply(frame, frame.color.data(), at, geometry, quadraticOf(g.field.warp), view,
                          kUnityGain, false, kernel, DepthMethod::Gather);
    g.unsettled.assign(warp.unsettled(),
                       warp.unsettled() + static_cast<std::size_t>(g.field.width) * g.field.lines);
    return g;
}

// PSNR (dB) of an RGB field against the truth's lines, or against another field.
double fieldPsnr(const Field& field, const std::uint8_t* other, std::size_t otherStride) {
    double sum = 0;
    for (int line = 0; line < field.lines; ++line) {
        const std::uint8_t* t = other + static_cast<std::size_t>(line) * otherStride;
        const std::uint8_t* p = field.line(line);
        for (int i = 0; i < 3 * field.width; ++i) {
            const double d = p[i] - t[i];
            sum += d * d;
        }
    }
    const double mse = sum / (3.0 * field.width * field.lines);
    return mse == 0.0 ? 100.0 : 10.0 * std::log10(255.0 * 255.0 / mse);
}
double truthPsnr(const Field& field, const ig::RenderedFrame& truth) {
    const std::size_t stride = 3 * static_cast<std::size_t>(truth.width());
    const auto* base = reinterpret_cast<const std::uint8_t*>(truth.color.data());
    return fieldPsnr(field, base + stride * static_cast<std::size_t>(field.frameLine(0)),
                     2 * stride);
}

ig::Pose moved(const ig::Pose& p, int k) {
    ig::Pose at = p;
    at.position += glm::dvec3{2.5, 6.0, -1.5} * static_cast<double>(k);
    at.yaw += 0.004 * k;
    at.pitch -= 0.003 * k;
    at.roll = 0.02 * k;
    return at;
}

// The AVX2 gather gives the scalar one's bits: every point and flag, over random poses, fits and
// depths (sky, NaN, zero, negative, huge, -inf), spans that start anywhere and leave partial
// groups of eight and of thirty-two.
TEST(DepthGather, VectorEqualsScalarBitForBit) {
    if (!depthKernelSupported(DepthKernel::Avx2)) GTEST_SKIP() << "no AVX2 on this processor";
    std::mt19937 rng(11);
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    const float specials[] = {std::numeric_limits<float>::infinity(),
                              -std::numeric_limits<float>::infinity(),
                              std::numeric_limits<float>::quiet_NaN(),
                              0.0f,
                              -5.0f,
                              1e30f,
                              1e-20f};
    std::uint64_t compared = 0, settled = 0;
    for (int trial = 0; trial < 30; ++trial) {
        const int width = 40 + 37 * (trial % 5);
        const ig::Intrinsics in = ig::Intrinsics::fromFov(width, 30, 1.0 + 0.4 * u(rng), 4);
        const ig::Pose pose = test::lookingDown(-15.0 + 10.0 * u(rng), 100.0 + 60.0 * u(rng));
        ig::RenderedFrame frame = test::renderPlane(pose, in);
        for (float& d : frame.depth) {
            if (0.5 * (u(rng) + 1.0) < 0.03) {
                d = specials[static_cast<std::size_t>(7 * (0.5 * (u(rng) + 1.0))) % 7];
            }
        }
        ig::Pose field = pose;
        field.position += glm::dvec3{10.0 * u(rng), 10.0 * u(rng), 5.0 * u(rng)};
        field.yaw += 0.05 * u(rng);
        field.pitch += 0.05 * u(rng);
        field.roll = 0.3 * u(rng);
        const OutputGeometry g = OutputGeometry::of(in, in.windowWidth(), in.windowHeight());
        const Quadratic q = quadraticOf(fitWarp(frame, field, g, FitOptions{}, nullptr));
        const DepthProjection p = DepthProjection::of(frame, field, g);
        const int n = g.width;
        std::vector<std::int32_t> x0(n), x1(n), y0(n), y1(n);
        std::vector<std::uint8_t> f0(n), f1(n);
        std::vector<float> d0(n), d1(n);
        for (const int row : {1, 13, 27}) {
            const GatherLine line = GatherLine::of(q, row + 0.5);
            for (const int begin : {0, 3}) {
                const int c0 =
                    detail::gatherLineScalar(p, line, frame.depth.data(), in.width, in.height,
                                             begin, n, x0.data(), y0.data(), f0.data(), d0.data());
                const int c1 =
                    detail::gatherLineAvx2(p, line, frame.depth.data(), in.width, in.height, begin,
                                           n, x1.data(), y1.data(), f1.data(), d1.data());
                EXPECT_EQ(c0, c1);
                for (int x = begin; x < n; ++x) {
                    ASSERT_EQ(x0[x], x1[x]) << "trial " << trial << " row " << row << " x " << x;
                    ASSERT_EQ(y0[x], y1[x]) << "trial " << trial << " row " << row << " x " << x;
                    ASSERT_EQ(f0[x], f1[x]) << "trial " << trial << " row " << row << " x " << x;
                    if (f0[x] == 0) {
                        ASSERT_EQ(std::memcmp(&d0[x], &d1[x], 4), 0);
                    }
                    ++compared;
                    settled += f0[x] == 0 ? 1 : 0;
                }
            }
        }
    }
    EXPECT_GT(compared, 10000u);
    EXPECT_GT(settled, compared / 2);  // most pixels settle: the comparison saw real points
}

// Whole fields are the same bytes with either kernel.
TEST(DepthGather, FieldsAreTheSameWithEitherKernel) {
    if (!depthKernelSupported(DepthKernel::Avx2)) GTEST_SKIP() << "no AVX2 on this processor";
    const ig::Pose pose = test::lookingDown(-25.0, 120.0);
    const ig::RenderedFrame frame = test::renderPlane(pose, kIn);
    for (int k = 1; k <= 8; k += 7) {
        const Field a = process(frame, moved(pose, k), WarpModel::Depth, DepthMethod::Gather,
                                DepthKernel::Scalar, k);
        const Field b = process(frame, moved(pose, k), WarpModel::Depth, DepthMethod::Gather,
                                DepthKernel::Avx2, k);
        EXPECT_EQ(a.pixels, b.pixels) << "k " << k;
        EXPECT_EQ(a.holeSamples, b.holeSamples);
    }
}

// The field's own pose: every pixel settles at once on the quadratic's point (which is exact
// there), and the field is the polynomial model's within one level.
TEST(DepthGather, IdentityPoseIsThePolynomialWarp) {
    const ig::Pose pose = test::lookingDown(-10.0, 300.0);  // horizon in view: sky too
    const ig::RenderedFrame frame = test::renderPlane(pose, kIn);
    const Gathered g = gather(frame, pose);
    EXPECT_EQ(g.result.unsettled, 0u);
    EXPECT_EQ(g.result.splatPixels, 0u);
    const Field poly = process(frame, pose, WarpModel::Poly);
    int worst = 0;
    for (std::size_t i = 0; i < poly.pixels.size(); ++i)
        worst = std::max(worst, std::abs(poly.pixels[i] - g.field.pixels[i]));
    EXPECT_LE(worst, 1);
}

// A textured cone on a plane, cast by the reference caster: the cone's silhouette is a depth
// edge. Against true renders the gather is within 0.1 dB of the splat (or better) at every
// horizon: the pixels beside the silhouette that settle on the ground the cone hides are caught
// by the depth jump between output neighbours (without it: 30.3 against 37.6 dB at k = 1).
TEST(DepthGather, AsAccurateAsTheSplatOnRealFrames) {
    ig::TerrainMap map = vig_test::coneMap(257, 0.8, 60.0);
    for (int iy = 0; iy < 257; ++iy) {
        for (int ix = 0; ix < 257; ++ix)
            map.setColor(ix, iy, test::groundColor(7.0 * ix, 5.0 * iy));
    }
    const auto caster = ig::makeCaster(ig::CasterKind::Reference, map);
    ig::Pose pose;
    pose.position = {128.0, 20.0, 45.0};
    pose.yaw = 0.0;  // facing +y, toward the cone
    pose.pitch = -0.25;
    const ig::Intrinsics in = ig::Intrinsics::fromFov(256, 192, 1.0, 16);
    const ig::RenderedFrame frame = ig::renderFrame(*caster, map, pose, in);
    std::uint64_t unsettled = 0;
    for (int k = 1; k <= 8; k += 1) {
        ig::Pose at = pose;
        at.position += glm::dvec3{1.5, 3.0, -0.8} * static_cast<double>(k);
        at.yaw += 0.006 * k;
        const ig::RenderedFrame truth = ig::renderFrame(*caster, map, at, in.window());
        const Field splat = process(frame, at, WarpModel::Depth, DepthMethod::Splat);
        const Field gathered = process(frame, at, WarpModel::Depth, DepthMethod::Gather);
        EXPECT_GT(truthPsnr(gathered, truth), truthPsnr(splat, truth) - 0.1) << "k " << k;
        const Gathered g = gather(frame, at);
        EXPECT_EQ(g.field.pixels, gathered.pixels);
        unsettled += g.result.unsettled;
        // One field ahead the gather makes much of the field; further on the cone's own
        // parallax (which the quadratic's Jacobian does not know) leaves too many pixels
        // unsettled and the whole field is splatted.
        if (k == 1) {
            EXPECT_LT(g.result.splatPixels, g.unsettled.size()) << "k " << k;
        }
    }
    EXPECT_GT(unsettled, 0u);  // the silhouette does not settle
}

// Hard cases: NaN depth everywhere (nothing settles: the splat, whose every pixel is a hole,
// gives the quadratic's field byte for byte); one NaN pixel (only the tiles around it are
// splatted); negative depth (behind the eye); a depth step (its edges do not settle); sky only
// (directions settle everywhere).
TEST(DepthGather, HardCases) {
    const ig::Pose pose = test::lookingDown(-35.0, 300.0);
    const ig::RenderedFrame plane = test::renderPlane(pose, kIn);
    const ig::Pose at = moved(pose, 3);
    const std::size_t pixels = static_cast<std::size_t>(kIn.windowWidth()) *
                               static_cast<std::size_t>((kIn.windowHeight() + 1) / 2);
    {
        ig::RenderedFrame frame = plane;
        std::fill(frame.depth.begin(), frame.depth.end(), std::numeric_limits<float>::quiet_NaN());
        const Gathered g = gather(frame, at);
        EXPECT_EQ(g.result.unsettled, pixels);
        EXPECT_EQ(g.result.splatPixels, pixels);
        EXPECT_EQ(process(frame, at, WarpModel::Depth).pixels,
                  process(frame, at, WarpModel::Poly).pixels);
    }
    {
        ig::RenderedFrame frame = plane;
        frame.depth[static_cast<std::size_t>(60) * kIn.width + 90] =
            std::numeric_limits<float>::quiet_NaN();
        const Gathered g = gather(frame, at);
        EXPECT_GT(g.result.unsettled, 0u);
        EXPECT_LE(g.result.unsettled, 8u);
        const std::uint64_t tile = DepthWarp::kGatherTileWidth * DepthWarp::kGatherTileLines;
        EXPECT_GE(g.result.splatPixels, 1u);
        EXPECT_LE(g.result.splatPixels, 2 * tile);
    }
    {
        ig::RenderedFrame frame = plane;
        std::fill(frame.depth.begin(), frame.depth.end(), -50.0f);
        const Gathered g = gather(frame, at);
        EXPECT_EQ(g.result.unsettled, pixels);
    }
    {
        // A slab hovering at half the distance over the middle of the frame (same colours).
        ig::RenderedFrame frame = plane;
        for (int y = 40; y < 100; ++y) {
            for (int x = 50; x < 140; ++x)
                frame.depth[static_cast<std::size_t>(y) * kIn.width + x] *= 0.5f;
        }
        const Gathered g = gather(frame, at);
        EXPECT_GT(g.result.unsettled, 20u);
        EXPECT_LT(g.result.unsettled, pixels / 5);
        EXPECT_GT(g.result.splatPixels, 0u);
        // Far from the slab's edges (the output's top lines) everything settled.
        for (int line = 0; line < 5; ++line) {
            for (int x = 0; x < kIn.windowWidth(); ++x)
                EXPECT_EQ(g.unsettled[static_cast<std::size_t>(line) * kIn.windowWidth() + x], 0);
        }
    }
    {
        ig::Pose up = pose;
        up.pitch = 0.9;  // all sky
        const ig::RenderedFrame sky = test::renderPlane(up, kIn);
        ASSERT_TRUE(std::all_of(sky.depth.begin(), sky.depth.end(),
                                [](float d) { return d == ig::kSkyDepth; }));
        ig::Pose to = up;
        to.position += glm::dvec3{40.0, 80.0, -20.0};
        to.yaw += 0.03;
        to.roll = 0.1;
        const Gathered g = gather(sky, to);
        EXPECT_EQ(g.result.unsettled, 0u);
        const Field splat = process(sky, to, WarpModel::Depth, DepthMethod::Splat);
        EXPECT_GT(fieldPsnr(g.field, splat.pixels.data(), splat.stride), 40.0);
    }
}

}  // namespace
}  // namespace prp
