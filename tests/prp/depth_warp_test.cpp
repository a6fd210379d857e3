#include "prp/depth_warp.hpp"

#include "ig/error.hpp"
#include "prp/processor.hpp"
#include "prp/synthetic_frame.hpp"
#include "prp/warp_apply_kernel.hpp"

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

PrpOptions options(WarpModel m, PixelFormat f = PixelFormat::Rgb8) {
    PrpOptions o;
    o.outWidth = kIn.windowWidth();
    o.outHeight = kIn.windowHeight();
    o.format = f;
    o.model = m;
    return o;
}

// PSNR (dB) of an RGB field against the truth's lines.
double fieldPsnr(const Field& field, const ig::RenderedFrame& truth) {
    double sum = 0;
    for (int line = 0; line < field.lines; ++line) {
        const ig::Rgb8* t =
            truth.color.data() + static_cast<std::size_t>(field.frameLine(line)) * truth.width();
        const std::uint8_t* p = field.line(line);
        for (int x = 0; x < field.width; ++x) {
            const double dr = p[3 * x] - t[x].r, dg = p[3 * x + 1] - t[x].g,
                         db = p[3 * x + 2] - t[x].b;
            sum += dr * dr + dg * dg + db * db;
        }
    }
    const double mse = sum / (3.0 * field.width * field.lines);
    return mse == 0.0 ? 100.0 : 10.0 * std::log10(255.0 * 255.0 / mse);
}

ig::Pose moved(const ig::Pose& p, int k) {
    ig::Pose at = p;
    at.position += glm::dvec3{2.5, 6.0, -1.5} * static_cast<double>(k);
    at.yaw += 0.004 * k;
    at.pitch -= 0.003 * k;
    at.roll = 0.02 * k;
    return at;
}

// The AVX2 projection gives the scalar one's bits: every scaled depth, every index, and inverse
// depth and source point of every pixel that lands, over random poses, depths (sky, NaN,
// negative, zero, huge, behind the eye) and row widths that leave partial groups of eight.
TEST(DepthWarp, VectorProjectionEqualsScalarBitForBit) {
    if (!depthKernelSupported(DepthKernel::Avx2)) GTEST_SKIP() << "no AVX2 on this processor";
    std::mt19937 rng(7);
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    const float specials[] = {std::numeric_limits<float>::infinity(),
                              -std::numeric_limits<float>::infinity(),
                              std::numeric_limits<float>::quiet_NaN(),
                              0.0f,
                              -5.0f,
                              1e30f,
                              1e-20f};
    std::uint64_t landed = 0;
    for (const int width : {1, 5, 8, 13, 203, 784}) {
        for (int trial = 0; trial < 40; ++trial) {
            const ig::Intrinsics in = ig::Intrinsics::fromFov(width + 2, 40, 1.0 + 0.5 * u(rng), 1);
            ig::RenderedFrame frame;
            frame.intrinsics = in;
            frame.pose = test::lookingDown(-30.0 + 20.0 * u(rng), 200.0 + 150.0 * u(rng));
            ig::Pose field = frame.pose;
            field.position += glm::dvec3{30.0 * u(rng), 30.0 * u(rng), 20.0 * u(rng)};
            field.yaw += 0.2 * u(rng);
            field.pitch += 0.2 * u(rng);
            field.roll = 0.5 * u(rng);
            const OutputGeometry g = OutputGeometry::of(in, 2 * (width / 2 + 1), 38);
            DepthProjection p = DepthProjection::of(frame, field, g);
            if (trial % 2 == 1) {
                // A Jacobian with rotation and shear, as withJacobian() gives.
                for (float& j : p.j)
                    j = static_cast<float>(1.5 * u(rng));
            }
            std::vector<float> depth(static_cast<std::size_t>(in.width));
            for (float& d : depth) {
                const double r = 0.5 * (u(rng) + 1.0);
                d = r < 0.15 ? specials[static_cast<std::size_t>(7 * (0.5 * (u(rng) + 1.0))) % 7]
                             : static_cast<float>(50.0 + 3000.0 * r);
            }
            const int n = in.width;
            std::vector<std::int32_t> i0(n), i1(n);
            std::vector<float> z0(n), z1(n), x0(n), x1(n), y0(n), y1(n), s0(n), s1(n);
            for (int y : {0, 7, 39}) {
                // The per-frame scaled depths, from either kernel, then the projection.
                detail::scaleDepthRowScalar(p, depth.data(), 0, n, y, s0.data());
                detail::scaleDepthRowAvx2(p, depth.data(), 0, n, y, s1.data());
                ASSERT_EQ(std::memcmp(s0.data(), s1.data(), s0.size() * sizeof(float)), 0)
                    << "width " << width << " row " << y;
                for (int parity : {0, 1}) {
                    detail::projectRowScalar(p, depth.data(), s0.data(), 0, n, y, parity,
                                             {i0.data(), z0.data(), x0.data(), y0.data()});
                    detail::projectRowAvx2(p, depth.data(), s0.data(), 0, n, y, parity,
                                           {i1.data(), z1.data(), x1.data(), y1.data()});
                    for (int x = 0; x < n; ++x) {
                        ASSERT_EQ(i0[x], i1[x]) << "width " << width << " x " << x;
                        if (i0[x] < 0) continue;
                        ++landed;
                        EXPECT_EQ(std::memcmp(&z0[x], &z1[x], 4), 0);
                        EXPECT_EQ(std::memcmp(&x0[x], &x1[x], 4), 0);
                        EXPECT_EQ(std::memcmp(&y0[x], &y1[x], 4), 0);
                    }
                }
            }
        }
    }
    EXPECT_GT(landed, 10000u);  // the comparison saw many landing pixels
}

// Whole fields are the same bytes with either kernel, in every pixel format.
TEST(DepthWarp, FieldsAreTheSameWithEitherKernel) {
    if (!depthKernelSupported(DepthKernel::Avx2)) GTEST_SKIP() << "no AVX2 on this processor";
    const ig::Pose pose = test::lookingDown(-25.0, 120.0);
    const ig::RenderedFrame frame = test::renderPlane(pose, kIn);
    for (const PixelFormat f : {PixelFormat::Rgb8, PixelFormat::Uyvy, PixelFormat::Y8}) {
        for (int k = 1; k <= 8; k += 7) {
            Field a, b;
            PrpOptions o = options(WarpModel::Depth, f);
            o.depthKernel = DepthKernel::Scalar;
            PostRenderingProcessor(o).process(frame, moved(pose, k), 0.0, k, a);
            o.depthKernel = DepthKernel::Avx2;
            PostRenderingProcessor(o).process(frame, moved(pose, k), 0.0, k, b);
            EXPECT_EQ(a.pixels, b.pixels) << "k " << k;
            EXPECT_EQ(a.holeSamples, b.holeSamples);
            EXPECT_EQ(a.edgeSamples, b.edgeSamples);
        }
    }
}

// The depth warp keeps each frame's scaled depths for the frame's later fields: a processor that
// warped another frame first gives a new frame's field the same bytes as a fresh processor (a
// new sequence, or another buffer under the same sequence, is a new frame).
TEST(DepthWarp, EachFramesScaledDepthsAreMadeForIt) {
    const ig::Pose pose = test::lookingDown(-25.0, 120.0);
    const ig::RenderedFrame a = test::renderPlane(pose, kIn, 0.0, 1);
    ig::Pose higher = pose;
    higher.position.z += 60.0;
    const ig::RenderedFrame b2 = test::renderPlane(higher, kIn, 0.0, 2);
    ig::RenderedFrame copy = b2;
    copy.sequence = 1;  // another frame under the first one's sequence
    const ig::RenderedFrame& b1 = copy;
    for (const ig::RenderedFrame* b : {&b2, &b1}) {
        PostRenderingProcessor used(options(WarpModel::Depth));
        Field first, second, fresh;
        used.process(a, moved(pose, 2), 0.0, 1, first);
        used.process(*b, moved(higher, 2), 0.0, 1, second);
        PostRenderingProcessor(options(WarpModel::Depth))
            .process(*b, moved(higher, 2), 0.0, 1, fresh);
        EXPECT_EQ(second.pixels, fresh.pixels) << "sequence " << b->sequence;
        EXPECT_NE(second.pixels, first.pixels);
    }
}

// Warming a processor up on a frame (before a field clock starts) changes none of its fields,
// and a frame its fields would refuse is refused there too.
TEST(DepthWarp, AWarmedUpProcessorGivesTheSameFields) {
    const ig::Pose pose = test::lookingDown(-25.0, 120.0);
    const ig::RenderedFrame frame = test::renderPlane(pose, kIn, 0.0, 3);
    for (const WarpModel m : {WarpModel::Depth, WarpModel::Auto, WarpModel::Poly}) {
        PrpOptions o = options(m);
        o.antiTwitter = true;
        PostRenderingProcessor warmed(o), cold(o);
        warmed.warmUp(frame);
        for (int k = 1; k <= 3; ++k) {
            Field a, b;
            warmed.process(frame, moved(pose, k), 0.0, k, a);
            cold.process(frame, moved(pose, k), 0.0, k, b);
            EXPECT_EQ(a.pixels, b.pixels) << warpModelName(m) << " k " << k;
        }
    }
    ig::RenderedFrame broken = frame;
    broken.depth.pop_back();
    EXPECT_THROW(PostRenderingProcessor(options(WarpModel::Depth)).warmUp(broken), ig::InputError);
}

// Nothing lands where there is no depth: every pixel is a hole and samples the quadratic, so
// the field is the polynomial model's, byte for byte.
TEST(DepthWarp, HolesTakeThePolynomialWarp) {
    const ig::Pose pose = test::lookingDown(-35.0, 300.0);
    ig::RenderedFrame frame = test::renderPlane(pose, kIn);
    std::fill(frame.depth.begin(), frame.depth.end(), std::numeric_limits<float>::quiet_NaN());
    for (const PixelFormat f : {PixelFormat::Rgb8, PixelFormat::Uyvy}) {
        Field depth, poly;
        PostRenderingProcessor(options(WarpModel::Depth, f))
            .process(frame, moved(pose, 3), 0.0, 3, depth);
        PostRenderingProcessor(options(WarpModel::Poly, f))
            .process(frame, moved(pose, 3), 0.0, 3, poly);
        EXPECT_EQ(depth.pixels, poly.pixels);
        EXPECT_EQ(depth.holeSamples, static_cast<std::uint64_t>(depth.width) *
                                         static_cast<std::uint64_t>(depth.lines));
        EXPECT_EQ(depth.warp.model, WarpModel::Depth);
    }
}

// The float splat is about as accurate as the double-precision reference against true renders
// (within 1 dB; the camera descends 7 % of its height, so the ground is magnified and the splat
// leaves holes), and beats the quadratic low over the ground, where parallax is large.
TEST(DepthWarp, AsAccurateAsTheReference) {
    const ig::Pose pose = test::lookingDown(-20.0, 40.0);
    const ig::RenderedFrame frame = test::renderPlane(pose, kIn);
    for (int k = 1; k <= 8; ++k) {
        ig::Pose at = pose;
        at.position += glm::dvec3{1.0, 3.0, -0.35} * static_cast<double>(k);
        at.yaw += 0.004 * k;
        at.roll = 0.02 * k;
        const ig::RenderedFrame truth = test::renderPlane(at, kIn.window());
        Field fast, ref;
        PostRenderingProcessor(options(WarpModel::Depth)).process(frame, at, 0.0, k, fast);
        PrpOptions o = options(WarpModel::Depth);
        o.depthReference = true;
        PostRenderingProcessor(o).process(frame, at, 0.0, k, ref);
        Field poly;
        PostRenderingProcessor(options(WarpModel::Poly)).process(frame, at, 0.0, k, poly);
        const double f = fieldPsnr(fast, truth), r = fieldPsnr(ref, truth);
        EXPECT_GT(f, r - 1.0) << "k " << k;
        if (k >= 7) {
            EXPECT_GT(f, fieldPsnr(poly, truth) + 1.0) << "k " << k;
        }
    }
}

// The point each output pixel samples is the rendered point that landed nearest its centre,
// moved to the centre by the quadratic's Jacobian: under a field that differs from the frame by
// a rotation (roll, yaw and pitch; no translation, so no parallax) every point, holes included,
// is the exact source of its output pixel's centre within 0.02 rendered pixels over the whole
// field, where moving it by the output scaling alone (no rotation) misses by up to
// sin(roll) times the distance moved (0.32 pixels here, holes included).
TEST(DepthWarp, PointsAreMovedToTheirPixelCentresByTheWarpsJacobian) {
    const ig::Pose pose = test::lookingDown(-25.0, 150.0);
    const ig::RenderedFrame frame = test::renderPlane(pose, kIn);
    ig::Pose at = pose;
    at.roll = 0.3;
    at.yaw += 0.01;
    at.pitch -= 0.008;
    Field poly;
    PostRenderingProcessor(options(WarpModel::Poly)).process(frame, at, 0.0, 1, poly);
    const FieldView view{poly.pixels.data(),          poly.stride, poly.width,
                         fieldFirstLine(poly.parity), poly.lines,  poly.format};
    const OutputGeometry geometry = OutputGeometry::of(kIn, poly.width, poly.frameHeight);
    DepthWarp warp;
    const DepthWarpResult r = warp.apply(frame, frame.color.data(), at, geometry,
                                         quadraticOf(poly.warp), view, kUnityGain, false);
    EXPECT_GT(r.holes, 0u);  // the rotation leaves holes between landing points
    EXPECT_FALSE(r.abandoned);
    // The write from the points, past the last look at the clock, is timed for the caller.
    EXPECT_GT(r.tailSeconds, 0.0);
    EXPECT_LT(r.tailSeconds, 10.0);
    const ig::Camera fieldCam(at, kIn.window()), frameCam(pose, kIn);
    double worst = 0.0;
    std::size_t compared = 0;
    for (int line = 0; line < poly.lines; ++line) {
        const double row = poly.frameLine(line) + 0.5;
        for (int x = 0; x < poly.width; ++x) {
            const auto exact = frameCam.project(fieldCam.rayDirection(x + 0.5, row), 0.0);
            ASSERT_TRUE(exact.has_value());
            // Points within the frame, two pixels from its edges.
            if (exact->x < 2.0 || exact->y < 2.0 || exact->x > kIn.width - 2.0 ||
                exact->y > kIn.height - 2.0)
                continue;
            const std::size_t i = static_cast<std::size_t>(line) * poly.width + x;
            const double sx = (warp.pointsX()[i] + detail::kPointHalf) * 0x1p-16;
            const double sy = (warp.pointsY()[i] + detail::kPointHalf) * 0x1p-16;
            worst = std::max({worst, std::abs(sx - exact->x), std::abs(sy - exact->y)});
            ++compared;
        }
    }
    EXPECT_GT(compared, static_cast<std::size_t>(poly.width) * poly.lines * 3 / 4);
    EXPECT_LT(worst, 0.02);
}

// Occlusion: a slab hovering at half the camera's height over the ground hides the ground
// behind it from the frame and from each field, which sees other parts of the ground past its
// edges. For field eyes ahead of the frame's camera, behind it, beside it, above and below it,
// the depth warp shows the slab where it is nearer: within 1 dB of the double-precision
// reference against the true render, and at least 1 dB better than the quadratic, which
// cannot follow the slab's parallax.
TEST(DepthWarp, ANearerSurfaceHidesTheGroundBehindIt) {
    const ig::Pose pose = test::lookingDown(-30.0, 80.0);
    const ig::Camera cam(pose, kIn);
    const ig::CameraBasis b = ig::CameraBasis::fromPose(pose);
    // The slab around the ground point seen a little below the frame's centre.
    const glm::dvec3 dir = glm::normalize(cam.rayDirection(kIn.cx(), kIn.cy() + 15.0));
    const glm::dvec3 ground = pose.position + (-pose.position.z / dir.z) * dir;
    const test::Slab slab{ground.x - 40.0, ground.y - 40.0, ground.x + 40.0, ground.y + 40.0, 40.0};
    const ig::RenderedFrame frame = test::renderPlane(pose, kIn, 0.0, 0, &slab);
    const ig::RenderedFrame bare = test::renderPlane(pose, kIn);
    std::size_t onSlab = 0;
    for (std::size_t i = 0; i < frame.color.size(); ++i)
        onSlab += frame.depth[i] < 0.6f * bare.depth[i] ? 1 : 0;
    ASSERT_GT(onSlab, frame.color.size() / 10);  // the slab fills a good part of the frame
    const glm::dvec3 moves[] = {6.0 * b.forward,
                                -6.0 * b.forward,
                                8.0 * b.right,
                                -8.0 * b.right,
                                6.0 * b.up,
                                -6.0 * b.up,
                                5.0 * b.forward + 4.0 * b.right - 3.0 * b.up};
    for (const glm::dvec3& m : moves) {
        ig::Pose at = pose;
        at.position += m;
        at.yaw += 0.01;
        at.roll = 0.05;
        const ig::RenderedFrame truth = test::renderPlane(at, kIn.window(), 0.0, 0, &slab);
        PrpOptions o = options(WarpModel::Depth);
        Field fast, ref, poly;
        PostRenderingProcessor(o).process(frame, at, 0.0, 1, fast);
        o.depthReference = true;
        PostRenderingProcessor(o).process(frame, at, 0.0, 1, ref);
        PostRenderingProcessor(options(WarpModel::Poly)).process(frame, at, 0.0, 1, poly);
        const double pf = fieldPsnr(fast, truth), pr = fieldPsnr(ref, truth),
                     pq = fieldPsnr(poly, truth);
        EXPECT_GT(pf, pr - 1.0) << "move " << m.x << " " << m.y << " " << m.z;
        EXPECT_GT(pf, pq + 1.0) << "move " << m.x << " " << m.y << " " << m.z;
    }
}

// Auto keeps the quadratic where it is exact (no motion) and takes the depth model when the
// quadratic misses the check points by more than the threshold; the choice is recorded.
TEST(AutoWarp, PicksByTheCheckPointError) {
    const ig::Pose pose = test::lookingDown(-20.0, 40.0);
    const ig::RenderedFrame frame = test::renderPlane(pose, kIn);
    PostRenderingProcessor still(options(WarpModel::Auto));
    Field field;
    still.process(frame, pose, 0.0, 0, field);
    EXPECT_EQ(field.warp.model, WarpModel::Poly);
    EXPECT_GE(field.warp.checkErrorPx, 0.0);
    EXPECT_LT(field.warp.checkErrorPx, 1e-3);

    const ig::Pose at = moved(pose, 8);
    PostRenderingProcessor moving(options(WarpModel::Auto));
    moving.process(frame, at, 0.0, 8, field);
    const double e = field.warp.checkErrorPx;
    ASSERT_GT(e, 0.0);
    EXPECT_EQ(field.warp.model, e > 0.25 ? WarpModel::Depth : WarpModel::Poly);
    // A threshold either side of the measured error flips the choice.
    for (const double t : {0.5 * e, 2.0 * e}) {
        PrpOptions o = options(WarpModel::Auto);
        o.autoThresholdPx = t;
        PostRenderingProcessor prp(o);
        prp.process(frame, at, 0.0, 8, field);
        EXPECT_EQ(field.warp.checkErrorPx, e);
        EXPECT_EQ(field.warp.model, t < e ? WarpModel::Depth : WarpModel::Poly);
    }
}

// Check points of the frame at its own pose map through the identity-like warp exactly, at any
// roll (the warp composes roll, the check points are projected with it).
TEST(AutoWarp, CheckPointsAreExactAtTheFramePoseAnyRoll) {
    const ig::Pose pose = test::lookingDown(-10.0, 300.0);  // horizon in view: sky points too
    const ig::RenderedFrame frame = test::renderPlane(pose, kIn);
    const OutputGeometry g = OutputGeometry::of(kIn, kIn.windowWidth(), kIn.windowHeight());
    for (const double roll : {0.0, 0.3, -0.7}) {
        ig::Pose at = pose;
        at.roll = roll;
        std::array<Correspondence, kCheckPointCount> pts;
        const std::size_t n = checkCorrespondences(frame, at, g, pts);
        EXPECT_EQ(n, static_cast<std::size_t>(kCheckPointCount));
        FitOptions fo;
        const WarpInfo w = fitWarp(frame, at, g, fo, nullptr);
        EXPECT_LT(warpCheckError(w, {pts.data(), n}), 1e-6) << "roll " << roll;
    }
}

// Beyond the rendered frame the depth warp (splat or gather) and auto's depth fields honour
// --edge-fill as the quadratic does: with the haze below the horizon, every pixel the fill
// rewrote (it differs from the repeated edge) where the quadratic's was rewritten too is the
// quadratic's pixel, which depends only on the output pixel and the pose.
TEST(DepthWarp, EdgeFillBeyondTheFrameAsTheQuadratic) {
    const ig::Pose pose = test::lookingDown(-10.0, 300.0);  // horizon in view
    const ig::RenderedFrame frame = test::renderPlane(pose, kIn);
    ig::Pose at = pose;
    at.yaw += 0.35;  // a third of the field beyond the frame's right edge
    at.position += glm::dvec3{5.0, 10.0, -3.0};
    const auto run = [&](WarpModel m, EdgeFill fill, DepthMethod method) {
        PrpOptions o = options(m);
        o.edgeFill = fill;
        o.depthMethod = method;
        o.autoThresholdPx = 1e-9;  // auto takes the depth warp
        Field f;
        PostRenderingProcessor(o).process(frame, at, 0.0, 1, f);
        return f;
    };
    const Field poly = run(WarpModel::Poly, EdgeFill::SkyHaze, DepthMethod::Splat);
    const Field polyRepeat = run(WarpModel::Poly, EdgeFill::Repeat, DepthMethod::Splat);
    for (const WarpModel m : {WarpModel::Depth, WarpModel::Auto}) {
        for (const DepthMethod method : {DepthMethod::Splat, DepthMethod::Gather}) {
            const Field repeat = run(m, EdgeFill::Repeat, method);
            const Field haze = run(m, EdgeFill::SkyHaze, method);
            ASSERT_EQ(haze.warp.model, WarpModel::Depth);
            ASSERT_GT(haze.edgeSamples, 0u);
            std::size_t filled = 0, both = 0;
            for (std::size_t i = 0; i < haze.pixels.size(); i += 3) {
                if (std::memcmp(&haze.pixels[i], &repeat.pixels[i], 3) == 0) continue;
                ++filled;
                // Near the frame's edge the models may disagree on which side a point lies.
                if (std::memcmp(&poly.pixels[i], &polyRepeat.pixels[i], 3) == 0) continue;
                ++both;
                ASSERT_EQ(std::memcmp(&haze.pixels[i], &poly.pixels[i], 3), 0) << "pixel " << i / 3;
            }
            EXPECT_GT(filled, haze.edgeSamples / 2);
            EXPECT_GT(both, 9 * filled / 10);
        }
    }
}

// Auto on a deadline: once the depth model's fields take longer than the budget, the fields that
// want it get the quadratic (marked), with the same image as the quadratic's; one field in
// kDepthRetryFields measures the depth model again (each retry over budget doubling the wait, up
// to kDepthRetryFieldsMax), and a depth field still unfinished at the
// budget is abandoned for the quadratic (marked), so under a budget no machine meets every field
// is the quadratic's. Without a budget (offline), auto always takes the depth model; under one
// it never needs to abandon, the image is the unlimited one's.
TEST(DepthWarp, AutoOverItsTimeBudgetTakesTheQuadratic) {
    const ig::Pose pose = test::lookingDown(-10.0, 300.0);
    const ig::RenderedFrame frame = test::renderPlane(pose, kIn);
    ig::Pose at = pose;
    at.yaw += 0.05;
    at.position += glm::dvec3{5.0, 10.0, -3.0};
    PrpOptions o = options(WarpModel::Auto);
    o.autoThresholdPx = 1e-9;  // every field wants the depth model
    o.autoDepthBudget = 1e-9;  // which no machine warps a field in
    PostRenderingProcessor budgeted(o);
    o.autoDepthBudget = 3600.0;  // which every machine does
    PostRenderingProcessor generous(o);
    o.autoDepthBudget = 0.0;
    PostRenderingProcessor unlimited(o);
    PostRenderingProcessor poly(options(WarpModel::Poly));
    Field f, g, q, r;
    std::uint64_t abandoned = 0, over = 0;
    // The first field tries it; the retries come kDepthRetryFields after it, then twice, four
    // times... that many fields after the last, up to kDepthRetryFieldsMax.
    std::vector<std::uint64_t> tries = {1};
    for (std::uint64_t wait = kDepthRetryFields; tries.size() < 6;
         wait = std::min(2 * wait, kDepthRetryFieldsMax)) {
        tries.push_back(tries.back() + wait);
    }
    ASSERT_EQ(tries.back() - tries[tries.size() - 2], kDepthRetryFieldsMax);
    const std::uint64_t fields = tries.back() + 1;
    std::vector<std::uint64_t> abandonedAt;
    for (std::uint64_t n = 1; n <= fields; ++n) {
        budgeted.process(frame, at, 0.0, n, f);
        poly.process(frame, at, 0.0, n, q);
        if (f.warp.depthAbandoned) abandonedAt.push_back(n);
        if (n % 97 != 1 && !f.warp.depthAbandoned) {
            EXPECT_TRUE(f.warp.depthOverBudget) << "field " << n;
            ASSERT_EQ(f.warp.model, WarpModel::Poly) << "field " << n;
            ASSERT_EQ(f.pixels, q.pixels) << "the quadratic's own field, field " << n;
            over += 1;
            continue;  // the depth twins on a sample of the fields (and every try)
        }
        unlimited.process(frame, at, 0.0, n, g);
        generous.process(frame, at, 0.0, n, r);
        EXPECT_EQ(g.warp.model, WarpModel::Depth);
        EXPECT_FALSE(g.warp.depthOverBudget || g.warp.depthAbandoned);
        EXPECT_EQ(r.warp.model, WarpModel::Depth);
        EXPECT_FALSE(r.warp.depthOverBudget || r.warp.depthAbandoned);
        EXPECT_EQ(r.pixels, g.pixels) << "a deadline not reached changes nothing";
        ASSERT_EQ(f.warp.model, WarpModel::Poly) << "field " << n;
        EXPECT_NE(f.warp.depthOverBudget, f.warp.depthAbandoned) << "field " << n;
        abandoned += f.warp.depthAbandoned;
        over += f.warp.depthOverBudget;
        EXPECT_EQ(f.pixels, q.pixels) << "the quadratic's own field, field " << n;
    }
    EXPECT_EQ(abandonedAt, tries);
    EXPECT_EQ(abandoned, tries.size());
    EXPECT_EQ(over, fields - tries.size());
    o.autoDepthBudget = -1.0;
    EXPECT_THROW(PostRenderingProcessor{o}, ig::InputError);
}

// The depth model's budget on synthetic times (seconds): a field that wants it takes it while
// it is within budget; an abandoned field marks it over budget whatever its own time (its time is
// its deadline's: a deadline brought early by a slow quadratic made every field try the depth
// model, and give it up, when that time counted as the model's cost); the retries' waits double
// up to kDepthRetryFieldsMax and a retry within budget brings them back; the deadline leaves
// room for the larger of the depth field's tail and the quadratic.
TEST(DepthWarp, TheDepthBudgetDecidesOnWhatTheFieldsMeasured) {
    const DepthBudget none;
    EXPECT_TRUE(none.mayTry(5));
    EXPECT_TRUE(std::isinf(none.allowance()));

    DepthBudget b(0.010);
    EXPECT_TRUE(b.mayTry(1));
    EXPECT_DOUBLE_EQ(b.allowance(), 0.010);
    b.depthField(1, 0.004, false, 0.001);
    b.quadraticField(0.002);
    EXPECT_TRUE(b.mayTry(2));
    EXPECT_DOUBLE_EQ(b.allowance(), 0.010 - 0.002);  // the quadratic is the larger
    b.quadraticField(0.002);
    b.depthField(2, 0.005, false, 0.004);  // tail mean 0.00175
    EXPECT_DOUBLE_EQ(b.allowance(), 0.010 - 0.002);

    // Abandoned early (3 ms of a 10 ms budget): over budget all the same.
    b.depthField(3, 0.003, true, 0.0);
    EXPECT_TRUE(b.overBudget());
    EXPECT_FALSE(b.mayTry(4));
    EXPECT_FALSE(b.mayTry(3 + kDepthRetryFields - 1));
    EXPECT_TRUE(b.mayTry(3 + kDepthRetryFields));
    std::uint64_t at = 3 + kDepthRetryFields;
    for (std::uint64_t wait = 2 * kDepthRetryFields; wait <= 2 * kDepthRetryFieldsMax; wait *= 2) {
        b.depthField(at, 0.003, true, 0.0);  // the retry abandoned too
        const std::uint64_t expected = std::min(wait, kDepthRetryFieldsMax);
        EXPECT_EQ(b.retryFields(), expected);
        EXPECT_FALSE(b.mayTry(at + expected - 1));
        EXPECT_TRUE(b.mayTry(at + expected));
        at += expected;
    }
    // A retry that completes within budget: the model is back, the wait too.
    b.depthField(at, 0.004, false, 0.001);
    EXPECT_FALSE(b.overBudget());
    EXPECT_TRUE(b.mayTry(at + 1));
    EXPECT_EQ(b.retryFields(), kDepthRetryFields);

    // Completed fields over budget (their running mean above it) send the next ones to the
    // quadratic as well.
    DepthBudget slow(0.010);
    for (std::uint64_t n = 1; n <= 4; ++n)
        slow.depthField(n, 0.020, false, 0.002);
    EXPECT_TRUE(slow.overBudget());
    EXPECT_FALSE(slow.mayTry(5));
    // A slow quadratic leaves the depth model no time at all rather than a negative one.
    slow.quadraticField(0.050);
    EXPECT_EQ(slow.allowance(), 0.0);
}

// The gather method abandons the same way (its lines and splatted tiles look at the clock).
TEST(DepthWarp, TheGatherIsAbandonedAtItsDeadlineToo) {
    const ig::Pose pose = test::lookingDown(-10.0, 300.0);
    const ig::RenderedFrame frame = test::renderPlane(pose, kIn);
    ig::Pose at = pose;
    at.yaw += 0.05;
    PrpOptions o = options(WarpModel::Auto);
    o.autoThresholdPx = 1e-9;
    o.autoDepthBudget = 1e-9;
    o.depthMethod = DepthMethod::Gather;
    PostRenderingProcessor budgeted(o);
    PostRenderingProcessor poly(options(WarpModel::Poly));
    Field f, q;
    budgeted.process(frame, at, 0.0, 1, f);
    poly.process(frame, at, 0.0, 1, q);
    EXPECT_TRUE(f.warp.depthAbandoned);
    EXPECT_EQ(f.warp.model, WarpModel::Poly);
    EXPECT_EQ(f.pixels, q.pixels);
}

}  // namespace
}  // namespace prp
