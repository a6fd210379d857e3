#include "prp/processor.hpp"

#include "ig/error.hpp"
#include "prp/synthetic_frame.hpp"
#include "prp/warp_apply.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <vector>

namespace prp {
namespace {

const ig::Intrinsics kIn = ig::Intrinsics::fromFov(96, 72, 1.0, 12);

TEST(WarpModelNames, RoundTrip) {
    for (const WarpModel m : {WarpModel::Poly, WarpModel::Affine, WarpModel::Homography,
                              WarpModel::Depth, WarpModel::Hold, WarpModel::Auto}) {
        EXPECT_EQ(parseWarpModel(warpModelName(m)), m);
    }
    EXPECT_FALSE(parseWarpModel("Poly"));
    EXPECT_FALSE(parseWarpModel(""));
}

// A frame whose red is its row and green its column (mod 256), control points on a plane.
ig::RenderedFrame coordinateFrame(const ig::Pose& pose) {
    ig::RenderedFrame f = test::renderPlane(pose, kIn);
    for (int y = 0; y < kIn.height; ++y) {
        for (int x = 0; x < kIn.width; ++x) {
            f.color[static_cast<std::size_t>(y) * kIn.width + x] = {
                static_cast<std::uint8_t>(y), static_cast<std::uint8_t>(x), 77};
        }
    }
    return f;
}

PrpOptions options(PixelFormat f = PixelFormat::Rgb8, WarpModel m = WarpModel::Poly) {
    PrpOptions o;
    o.outWidth = kIn.windowWidth();
    o.outHeight = kIn.windowHeight();
    o.format = f;
    o.model = m;
    return o;
}

TEST(Processor, BeyondTheFrameItShowsSkyAndHazeAndCountsAsBefore) {
    // A turn of twice the margin: the field's right part samples beyond the frame. Pitched up so
    // the horizon crosses the field: sky above, the horizon (haze) colour below.
    ig::Pose pose = test::lookingDown(-2.0);
    const ig::RenderedFrame f = coordinateFrame(pose);
    ig::Pose turned = pose;
    turned.yaw += std::atan(24.0 / kIn.focal);
    for (const PixelFormat fmt : {PixelFormat::Rgb8, PixelFormat::Uyvy}) {
        PrpOptions o = options(fmt);
        o.sky.zenith = {0, 0, 250};
        o.sky.horizon = {250, 250, 250};
        o.edgeFill = EdgeFill::Repeat;
        PostRenderingProcessor repeat(o);
        o.edgeFill = EdgeFill::SkyHaze;
        PostRenderingProcessor filled(o);
        o.edgeFill = EdgeFill::Sky;
        PostRenderingProcessor sky(o);
        Field a, b, c;
        repeat.process(f, turned, 0.0, 0, a);
        filled.process(f, turned, 0.0, 0, b);
        sky.process(f, turned, 0.0, 0, c);
        EXPECT_EQ(c.edgeSamples, a.edgeSamples);
        EXPECT_GT(a.edgeSamples, 0u);
        EXPECT_EQ(a.edgeSamples, b.edgeSamples);
        ASSERT_EQ(a.pixels.size(), b.pixels.size());
        std::size_t changed = 0;
        for (int line = 0; line < a.lines; ++line) {
            for (std::size_t i = 0; i < a.stride; ++i)
                changed += a.line(line)[i] != b.line(line)[i];
        }
        // Only the pixels (UYVY: pairs) outside change.
        EXPECT_GT(changed, 0u);
        EXPECT_LE(changed, 4 * a.edgeSamples);
        if (fmt != PixelFormat::Rgb8) continue;
        // Right of the frame: above the horizon bluer than below, below the horizon colour.
        const std::uint8_t* top = b.line(0) + 3 * (kIn.windowWidth() - 1);
        const std::uint8_t* bottom = b.line(b.lines - 1) + 3 * (kIn.windowWidth() - 1);
        EXPECT_LT(top[0], 250);
        EXPECT_EQ(top[2], 250);
        EXPECT_EQ(bottom[0], 250);
        EXPECT_EQ(bottom[1], 250);
        // Sky: the same above the horizon, the repeated edge below.
        EXPECT_EQ(c.line(0)[3 * (kIn.windowWidth() - 1)], top[0]);
        const int last = 3 * (kIn.windowWidth() - 1);
        EXPECT_EQ(c.line(c.lines - 1)[last], a.line(a.lines - 1)[last]);
        EXPECT_EQ(c.line(c.lines - 1)[last + 1], a.line(a.lines - 1)[last + 1]);
    }
}

TEST(Processor, EachFieldHoldsTheLinesOfItsParity) {
    const ig::Pose pose = test::lookingDown(-40.0);
    const ig::RenderedFrame f = coordinateFrame(pose);
    PostRenderingProcessor prp(options());
    Field field;
    for (std::uint64_t index = 0; index < 4; ++index) {
        prp.process(f, pose, fieldTime(1.0, index), index, field);
        EXPECT_EQ(field.index, index);
        EXPECT_EQ(field.parity, fieldParity(index));
        EXPECT_EQ(field.lines, 36);
        EXPECT_EQ(field.stride, 96u * 3);
        EXPECT_NEAR(field.frameAge, fieldTime(1.0, index) - f.time, 1e-12);
        EXPECT_EQ(field.edgeSamples, 0u);
        for (int line = 0; line < field.lines; ++line) {
            for (int x = 0; x < field.width; x += 7) {
                const std::uint8_t* p = field.line(line) + 3 * x;
                ASSERT_EQ(p[0], field.frameLine(line) + kIn.margin) << index << " " << line;
                ASSERT_EQ(p[1], x + kIn.margin);
            }
        }
    }
}

TEST(Processor, ReusesItsBuffersFromFieldToField) {
    const ig::Pose pose = test::lookingDown(-40.0);
    const ig::RenderedFrame f = test::renderPlane(pose, kIn);
    for (const WarpModel m : {WarpModel::Poly, WarpModel::Depth}) {
        PostRenderingProcessor prp(options(PixelFormat::Uyvy, m));
        Field field;
        prp.process(f, pose, 0.0, 0, field);
        const std::uint8_t* data = field.pixels.data();
        for (std::uint64_t i = 1; i < 6; ++i) {
            ig::Pose p = pose;
            p.yaw += 0.002 * i;
            prp.process(f, p, fieldTime(0.0, i), i, field);
            EXPECT_EQ(field.pixels.data(), data);
        }
    }
}

double fieldError(const Field& field, const ig::RenderedFrame& truth) {
    // Mean absolute error (0..255) of an RGB field against the truth's window lines.
    double sum = 0;
    const int m = truth.intrinsics.margin;
    for (int line = 0; line < field.lines; ++line) {
        const int y = field.frameLine(line) + m;
        for (int x = 0; x < field.width; ++x) {
            const ig::Rgb8 t = truth.color[static_cast<std::size_t>(y) * truth.width() + x + m];
            const std::uint8_t* p = field.line(line) + 3 * x;
            sum += std::abs(p[0] - t.r) + std::abs(p[1] - t.g) + std::abs(p[2] - t.b);
        }
    }
    return sum / (3.0 * field.width * field.lines);
}

// Past `holdAfter` of frame age a field holds the frame: the Hold model's field, to the byte.
TEST(Processor, HoldsAFrameOlderThanHoldAfter) {
    const ig::Pose pose = test::lookingDown(-40.0, 300.0);
    ig::RenderedFrame f = test::renderPlane(pose, kIn);
    f.time = 10.0;
    ig::Pose at = pose;
    at.position += glm::dvec3{6.0, 16.0, -4.0};
    at.yaw += 0.016;
    at.roll = 0.04;
    for (const WarpModel m : {WarpModel::Poly, WarpModel::Depth}) {
        PrpOptions withHold = options(PixelFormat::Rgb8, m);
        withHold.holdAfter = 0.5;
        PostRenderingProcessor limited(withHold), motion(options(PixelFormat::Rgb8, m)),
            held(options(PixelFormat::Rgb8, WarpModel::Hold));
        Field a, b, c;
        // Within the horizon: the model itself.
        limited.process(f, at, 10.4, 0, a);
        motion.process(f, at, 10.4, 0, b);
        EXPECT_EQ(a.pixels, b.pixels) << warpModelName(m);
        EXPECT_EQ(a.warp.model, m);
        // Past it: the Hold model's field.
        limited.process(f, at, 10.6, 1, a);
        held.process(f, at, 10.6, 1, c);
        EXPECT_EQ(a.pixels, c.pixels) << warpModelName(m);
        EXPECT_EQ(a.warp.model, WarpModel::Hold);
        motion.process(f, at, 10.6, 1, b);
        EXPECT_NE(a.pixels, b.pixels);
    }
    PrpOptions bad = options();
    bad.holdAfter = std::nan("");
    EXPECT_THROW(PostRenderingProcessor{bad}, ig::InputError);
}

TEST(Processor, MotionCompensationBeatsHoldOnAMovingCamera) {
    const ig::Pose pose = test::lookingDown(-40.0, 300.0);
    const ig::RenderedFrame f = test::renderPlane(pose, kIn);
    for (int k = 0; k <= 8; k += 4) {
        ig::Pose at = pose;
        at.position += glm::dvec3{1.5, 4.0, -1.0} * static_cast<double>(k);
        at.yaw += 0.004 * k;
        at.pitch -= 0.002 * k;
        at.roll = 0.01 * k;
        // The truth, rendered at the field's pose (roll included) without margins.
        const ig::RenderedFrame truth = test::renderPlane(at, kIn.window());
        double hold = 0;
        {
            PostRenderingProcessor prp(options(PixelFormat::Rgb8, WarpModel::Hold));
            Field field;
            prp.process(f, at, 0.0, static_cast<std::uint64_t>(k), field);
            hold = fieldError(field, truth);
        }
        for (const WarpModel m :
             {WarpModel::Poly, WarpModel::Affine, WarpModel::Homography, WarpModel::Depth}) {
            PostRenderingProcessor prp(options(PixelFormat::Rgb8, m));
            Field field;
            prp.process(f, at, 0.0, static_cast<std::uint64_t>(k), field);
            EXPECT_EQ(field.warp.fallback, Fallback::None);
            const double e = fieldError(field, truth);
            if (k == 0) {
                EXPECT_EQ(e, 0.0) << warpModelName(m);  // same pose: every model is exact
            } else {
                EXPECT_LT(e, 0.5 * hold) << warpModelName(m) << " k=" << k;
            }
        }
    }
}

TEST(Processor, NonFinitePoseHoldsThePreviousWarp) {
    const ig::Pose pose = test::lookingDown(-40.0);
    const ig::RenderedFrame f = test::renderPlane(pose, kIn);
    PostRenderingProcessor prp(options());
    Field field;
    ig::Pose moved = pose;
    moved.yaw += 0.02;
    prp.process(f, moved, 0.0, 0, field);
    const WarpInfo first = field.warp;
    EXPECT_EQ(first.fallback, Fallback::None);
    ig::Pose bad = moved;
    bad.pitch = std::numeric_limits<double>::quiet_NaN();
    prp.process(f, bad, kFieldPeriod, 1, field);
    EXPECT_EQ(field.warp.fallback, Fallback::Hold);
    EXPECT_EQ(field.warp.a, first.a);
    EXPECT_EQ(field.warp.b, first.b);
}

TEST(Processor, AgcMovesTheMeanTowardTheTarget) {
    const ig::Pose pose = test::lookingDown(-40.0);
    ig::RenderedFrame f = test::renderPlane(pose, kIn);
    for (auto& c : f.color)
        c = {static_cast<std::uint8_t>(c.r / 4), static_cast<std::uint8_t>(c.g / 4),
             static_cast<std::uint8_t>(c.b / 4)};
    PrpOptions o = options(PixelFormat::Y8);
    o.agc = true;
    o.agcTarget = 0.4;
    o.agcRate = 0.3;
    PostRenderingProcessor prp(o);
    Field field;
    auto mean = [&] {
        double s = 0;
        for (const std::uint8_t v : field.pixels)
            s += v;
        return s / (255.0 * field.pixels.size());
    };
    prp.process(f, pose, 0.0, 0, field);
    const double start = mean();
    EXPECT_LT(start, 0.2);
    double previousGap = std::abs(start - 0.4);
    for (std::uint64_t i = 1; i < 40; ++i) {
        prp.process(f, pose, fieldTime(0.0, i), i, field);
        const double gap = std::abs(mean() - 0.4);
        EXPECT_LE(gap, previousGap + 0.01);  // smooth: no overshoot swings
        previousGap = gap;
    }
    EXPECT_LT(previousGap, 0.03);
    EXPECT_GT(field.gain, 2.0);
}

TEST(Processor, AntiTwitterSpreadsAOneLineDetailOverThree) {
    const ig::Pose pose = test::lookingDown(-40.0);
    ig::RenderedFrame f = test::renderPlane(pose, kIn);
    for (auto& c : f.color)
        c = {0, 0, 0};
    const int bright = kIn.margin + 21;  // frame line 21: Bottom field, line 10
    for (int x = 0; x < kIn.width; ++x)
        f.color[bright * kIn.width + x] = {200, 200, 200};
    for (const bool filter : {false, true}) {
        PrpOptions o = options(PixelFormat::Y8);
        o.antiTwitter = filter;
        PostRenderingProcessor prp(o);
        Field top, bottom;
        prp.process(f, pose, 0.0, 0, bottom);
        prp.process(f, pose, 0.0, 1, top);
        // Without the filter only the bottom field shows the line; with it both fields do.
        EXPECT_EQ(bottom.line(10)[40], filter ? 100 : 200);
        EXPECT_EQ(top.line(10)[40], filter ? 50 : 0);
        EXPECT_EQ(top.line(11)[40], filter ? 50 : 0);
    }
}

TEST(Processor, ScalesToTheOutputSize) {
    const ig::Pose pose = test::lookingDown(-40.0);
    const ig::RenderedFrame f = coordinateFrame(pose);
    PrpOptions o = options();
    o.outWidth = 48;
    o.outHeight = 144;
    PostRenderingProcessor prp(o);
    Field field;
    prp.process(f, pose, 0.0, 1, field);
    EXPECT_EQ(field.lines, 72);
    EXPECT_EQ(field.edgeSamples, 0u);
    // Output (x, y) shows window point (2 x, y / 2).
    for (int line = 0; line < field.lines; line += 5) {
        const double wy = (field.frameLine(line) + 0.5) * 0.5;
        EXPECT_NEAR(field.line(line)[0 + 3 * 10], wy - 0.5 + kIn.margin, 1.0);
        EXPECT_NEAR(field.line(line)[1 + 3 * 10], 2 * 10.5 - 0.5 + kIn.margin, 1.0);
    }
}

TEST(Processor, RejectsUnusableOptionsAndFrames) {
    PrpOptions o = options(PixelFormat::Uyvy);
    o.outWidth = 95;
    EXPECT_THROW(PostRenderingProcessor{o}, ig::InputError);
    o = options();
    o.outHeight = 1;
    EXPECT_THROW(PostRenderingProcessor{o}, ig::InputError);
    o = options();
    o.agcTarget = std::numeric_limits<double>::quiet_NaN();
    EXPECT_THROW(PostRenderingProcessor{o}, ig::InputError);
    o = options();
    o.agcRate = 0.0;
    EXPECT_THROW(PostRenderingProcessor{o}, ig::InputError);

    PostRenderingProcessor prp(options(PixelFormat::Rgb8, WarpModel::Depth));
    ig::RenderedFrame f = test::renderPlane(test::lookingDown(), kIn);
    f.depth.pop_back();
    Field field;
    EXPECT_THROW(prp.process(f, f.pose, 0.0, 0, field), ig::InputError);
    f.color.clear();
    EXPECT_THROW(prp.process(f, f.pose, 0.0, 0, field), ig::InputError);
}

}  // namespace
}  // namespace prp
