// A field seen at another field of view than its frame was rendered with (a sensor's zoom).
#include "prp/processor.hpp"
#include "prp/synthetic_frame.hpp"
#include "prp/warp_fit.hpp"

#include <gtest/gtest.h>
#include <glm/geometric.hpp>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <random>
#include <string>

namespace prp {
namespace {

constexpr int kWindowW = 160, kWindowH = 120, kMargin = 16;
constexpr double kHfovA = 1.0;  // the frame's field of view, radians

ig::Intrinsics intrinsicsAt(double hfov) {
    return ig::Intrinsics::fromFov(kWindowW, kWindowH, hfov, kMargin);
}

PrpOptions options(WarpModel m) {
    PrpOptions o;
    o.outWidth = kWindowW;
    o.outHeight = kWindowH;
    o.format = PixelFormat::Rgb8;
    o.model = m;
    o.depthReference = false;
    return o;
}

ig::Pose framePose() {
    return test::lookingDown(-35.0);
}

// The field a little later: moved, turned and rolled, so the warp has parallax to fit.
ig::Pose fieldPose() {
    ig::Pose p = framePose();
    p.position += glm::dvec3{3.0, 5.0, -1.0};
    p.yaw += 0.01;
    p.pitch -= 0.005;
    p.roll = 0.02;
    return p;
}

Field warped(const ig::RenderedFrame& frame, WarpModel model, double fieldFocal,
             bool reference = false) {
    PrpOptions o = options(model);
    o.depthReference = reference;
    Field field;
    PostRenderingProcessor(o).process(frame, fieldPose(), 0.0, 0, field, std::nullopt, fieldFocal);
    return field;
}

// Mean absolute difference of two RGB fields, levels per channel.
double meanDifference(const Field& a, const Field& b) {
    EXPECT_EQ(a.pixels.size(), b.pixels.size());
    double sum = 0.0;
    for (std::size_t i = 0; i < a.pixels.size(); ++i)
        sum += std::abs(static_cast<int>(a.pixels[i]) - static_cast<int>(b.pixels[i]));
    return sum / static_cast<double>(a.pixels.size());
}

// Largest distance over a grid of output pixels between where `q` sends each and the rendered
// pixel of `frame` that truly shows what the field's camera (focal length `fieldFocal`, roll
// included) sees there (the ground plane, or a sky direction).
double warpError(const Quadratic& q, const ig::RenderedFrame& frame, double fieldFocal) {
    ig::Intrinsics window = frame.intrinsics.window();
    window.focal = fieldFocal;
    const ig::Camera field(fieldPose(), window);
    const ig::Camera source(frame.pose, frame.intrinsics);
    double worst = 0.0;
    for (int y = 4; y < kWindowH; y += 8) {
        for (int x = 4; x < kWindowW; x += 8) {
            glm::dvec3 dir;
            const double t = test::groundDistance(field, x + 0.5, y + 0.5, dir);
            const auto p = std::isfinite(t) ? source.project(field.pose().position + t * dir, 1.0)
                                            : source.project(dir, 0.0);
            if (!p) continue;
            worst = std::max(worst, glm::length(q({x + 0.5, y + 0.5}) - *p));
        }
    }
    return worst;
}

// The change of focal length is a scaling about the window centre composed with the roll and
// the output scaling, and the hold mapping scales the same way.
TEST(FieldOfView, GeometryScalesAboutTheWindowCentre) {
    const ig::Intrinsics in = intrinsicsAt(kHfovA);
    std::mt19937 rng(3);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    for (const double fieldFocal : {0.5 * in.focal, 0.8 * in.focal, 1.3 * in.focal}) {
        const OutputGeometry g = OutputGeometry::of(in, 2 * kWindowW, 3 * kWindowH, fieldFocal);
        const OutputGeometry same = OutputGeometry::of(in, 2 * kWindowW, 3 * kWindowH);
        const double k = in.focal / fieldFocal;
        EXPECT_DOUBLE_EQ(g.zoom(), k);
        EXPECT_EQ(g.fieldWindow().focal, fieldFocal);
        const glm::dvec2 c{0.5 * kWindowW, 0.5 * kWindowH};
        for (const double roll : {0.0, 0.3, -2.0}) {
            const Affine2 zoomed = g.unrolledFromOutput(roll);
            const Affine2 plain = same.unrolledFromOutput(roll);
            for (int i = 0; i < 50; ++i) {
                const glm::dvec2 p{u(rng) * g.width, u(rng) * g.height};
                const glm::dvec2 want = c + k * (plain(p) - c);
                EXPECT_NEAR(zoomed(p).x, want.x, 1e-9);
                EXPECT_NEAR(zoomed(p).y, want.y, 1e-9);
            }
        }
        const Affine2 hold = g.sourceFromOutputHold();
        const glm::dvec2 centre = hold({0.5 * g.width, 0.5 * g.height});
        EXPECT_NEAR(centre.x, c.x + kMargin, 1e-9);
        EXPECT_NEAR(centre.y, c.y + kMargin, 1e-9);
        EXPECT_NEAR(hold.m00, k * kWindowW / g.width, 1e-15);
        EXPECT_NEAR(hold.m11, k * kWindowH / g.height, 1e-15);
    }
}

// A field at the frame's own focal length, given or not, is the field of today bit for bit:
// pixels and warp, every model.
TEST(FieldOfView, TheFramesOwnFocalLengthChangesNoBit) {
    const ig::RenderedFrame frame = test::renderPlane(framePose(), intrinsicsAt(kHfovA));
    for (const WarpModel m : {WarpModel::Poly, WarpModel::Affine, WarpModel::Homography,
                              WarpModel::Depth, WarpModel::Auto, WarpModel::Hold}) {
        for (const bool reference : {false, true}) {
            if (reference && m != WarpModel::Depth) continue;
            const Field plain = warped(frame, m, 0.0, reference);
            const Field own = warped(frame, m, frame.intrinsics.focal, reference);
            const std::string what =
                std::string(warpModelName(m)) + (reference ? " (reference)" : "");
            EXPECT_EQ(plain.pixels, own.pixels) << what;
            EXPECT_EQ(plain.warp.a, own.warp.a) << what;
            EXPECT_EQ(plain.warp.b, own.warp.b) << what;
            EXPECT_EQ(plain.warp.h, own.warp.h) << what;
            EXPECT_EQ(plain.edgeSamples, own.edgeSamples) << what;
        }
    }
}

// A frame rendered at field of view A warped to a field at B against a frame truly rendered at
// B from the same pose, zooming in (0.8 rad) and out (1.1 rad, still inside the margins).
// Geometry: the quadratic's largest error against the true mapping (every output pixel's
// ground point projected into the frame), in field pixels, is within twice the error of the fit
// to the frame rendered at B plus 0.02 px (measured: 0.001 to 0.003 px for both; the nine
// control points are other ground points in the two frames, so the fits differ by their own
// residuals, not by the zoom). Pixels: the two fields differ by under 1.5 levels on average
// (measured 0.4 to 1.0 for poly and depth): the same scene resampled bilinearly from two
// pixel grids of different pitch.
TEST(FieldOfView, FieldFromAnotherFieldOfViewMatchesAFrameRenderedAtIt) {
    const ig::RenderedFrame frameA = test::renderPlane(framePose(), intrinsicsAt(kHfovA));
    for (const double hfovB : {0.8, 1.1}) {
        const ig::RenderedFrame frameB = test::renderPlane(framePose(), intrinsicsAt(hfovB));
        const double focalB = frameB.intrinsics.focal;
        const double toField = focalB / frameA.intrinsics.focal;  // field px per frame-A px
        for (const WarpModel m : {WarpModel::Poly, WarpModel::Depth}) {
            const std::string what =
                std::string(warpModelName(m)) + " at " + std::to_string(hfovB) + " rad";
            const Field fromA = warped(frameA, m, focalB);
            const Field fromB = warped(frameB, m, 0.0);
            EXPECT_EQ(fromA.warp.fallback, Fallback::None) << what;
            EXPECT_EQ(fromA.edgeSamples, 0u) << what;
            const double errA = warpError(quadraticOf(fromA.warp), frameA, focalB) * toField;
            const double errB = warpError(quadraticOf(fromB.warp), frameB, focalB);
            EXPECT_LE(errA, 2.0 * errB + 0.02) << what << ": " << errA << " px against " << errB;
            const double diff = meanDifference(fromA, fromB);
            EXPECT_LT(diff, 1.5) << what;
            // Not the same field by accident: the frame unscaled is far off.
            const Field unscaled = warped(frameA, m, 0.0);
            EXPECT_GT(meanDifference(unscaled, fromB), 4.0 * diff + 2.0) << what;
            std::printf("%s: warp error %.4f px (frame at B %.4f), mean difference %.3f\n",
                        what.c_str(), errA, errB, diff);
        }
    }
}

// Zooming out beyond the frame's margins: the field shows the edge fill there (never a
// crash), for every model, and the rest is the frame scaled.
TEST(FieldOfView, ZoomingOutBeyondTheMarginsFillsTheEdges) {
    const ig::RenderedFrame frame = test::renderPlane(framePose(), intrinsicsAt(kHfovA));
    const double wide = ig::Intrinsics::fromFov(kWindowW, kWindowH, 1.6).focal;
    for (const WarpModel m : {WarpModel::Poly, WarpModel::Affine, WarpModel::Homography,
                              WarpModel::Depth, WarpModel::Auto, WarpModel::Hold}) {
        const Field f = warped(frame, m, wide);
        EXPECT_GT(f.edgeSamples, 0u) << warpModelName(m);
        EXPECT_EQ(f.pixels.size(), static_cast<std::size_t>(kWindowW) * f.lines * 3);
    }
}

}  // namespace
}  // namespace prp
