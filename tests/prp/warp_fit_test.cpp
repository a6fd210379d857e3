#include "prp/warp_fit.hpp"

#include "ig/caster.hpp"
#include "prp/synthetic_frame.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <numbers>
#include <random>
#include <vector>

namespace prp {
namespace {

constexpr double kPi = std::numbers::pi;

std::vector<Correspondence> gridThrough(const Quadratic& q, double w, double h) {
    std::vector<Correspondence> pts;
    for (double fy : {1.0 / 6, 0.5, 5.0 / 6}) {
        for (double fx : {1.0 / 6, 0.5, 5.0 / 6}) {
            const glm::dvec2 u{fx * w, fy * h};
            pts.push_back({u, q(u)});
        }
    }
    return pts;
}

Quadratic randomQuadratic(std::mt19937& rng, double scale) {
    std::uniform_real_distribution<double> d(-1.0, 1.0);
    Quadratic q;
    q.a = {d(rng) * 50,    1 + 0.1 * d(rng), 0.1 * d(rng),
           scale * d(rng), scale * d(rng),   scale * d(rng)};
    q.b = {d(rng) * 50,    0.1 * d(rng),   1 + 0.1 * d(rng),
           scale * d(rng), scale * d(rng), scale * d(rng)};
    return q;
}

TEST(Quadratic, ComposeAffineMatchesDirectEvaluation) {
    std::mt19937 rng(7);
    std::uniform_real_distribution<double> d(-2.0, 2.0);
    for (int trial = 0; trial < 50; ++trial) {
        const Quadratic q = randomQuadratic(rng, 1e-3);
        const Affine2 m{d(rng), d(rng), d(rng), d(rng), 100 * d(rng), 100 * d(rng)};
        const Quadratic c = composeAffine(q, m);
        for (int k = 0; k < 10; ++k) {
            const glm::dvec2 p{300 * d(rng), 300 * d(rng)};
            const glm::dvec2 want = q(m(p));
            const glm::dvec2 got = c(p);
            EXPECT_NEAR(got.x, want.x, 1e-8 * (1 + std::abs(want.x)));
            EXPECT_NEAR(got.y, want.y, 1e-8 * (1 + std::abs(want.y)));
        }
    }
}

TEST(QuadraticFit, RecoversExactQuadraticsFromNinePoints) {
    std::mt19937 rng(11);
    for (int trial = 0; trial < 40; ++trial) {
        const Quadratic q = randomQuadratic(rng, 2e-4);
        const auto pts = gridThrough(q, 720, 486);
        const QuadraticFit fit = fitQuadratic(pts);
        ASSERT_TRUE(fit.ok);
        EXPECT_EQ(fit.rank, 6);
        EXPECT_LT(fit.residualPx, 1e-8);
        for (double y = 0; y <= 486; y += 81) {
            for (double x = 0; x <= 720; x += 90) {
                const glm::dvec2 e = fit.warp({x, y}) - q({x, y});
                EXPECT_LT(std::hypot(e.x, e.y), 1e-7);
            }
        }
    }
}

TEST(QuadraticFit, NormalisationTamesTheCondition) {
    // The nine-point grid of a 720 x 486 window in raw pixel coordinates.
    const auto pts = gridThrough(Quadratic::identity(), 720, 486);
    const double raw = quadraticDesignCondition(pts, false);
    const double normalised = quadraticDesignCondition(pts, true);
    EXPECT_GT(raw, 1e5);          // near 1e6 ...
    EXPECT_GT(raw * raw, 1e10);   // ... and its normal equations near 1e12
    EXPECT_LT(normalised, 20.0);  // centred and scaled: a well-posed system
    // Both solve the exact problem here, but only the normalised fit passes the conditioning
    // check: raw coordinates would be rejected as ill-conditioned.
    EXPECT_TRUE(fitQuadratic(pts, true).ok);
    EXPECT_FALSE(fitQuadratic(pts, false).ok);
}

TEST(QuadraticFit, CollinearPointsHaveRankThree) {
    std::vector<Correspondence> pts;
    for (int i = 0; i < 9; ++i) {
        const glm::dvec2 u{40.0 + 70.0 * i, 30.0 + 45.0 * i};
        pts.push_back({u, u + glm::dvec2{3.0, -2.0}});
    }
    const QuadraticFit q = fitQuadratic(pts);
    EXPECT_FALSE(q.ok);
    EXPECT_EQ(q.rank, 3);
    const QuadraticFit a = fitAffine(pts);
    EXPECT_FALSE(a.ok);
    EXPECT_EQ(a.rank, 2);
}

TEST(QuadraticFit, PointsOnAConicHaveRankFive) {
    for (const double e : {1.0, 0.6, 1.7}) {
        std::vector<Correspondence> pts;
        for (int i = 0; i < 9; ++i) {
            const double t = 2 * kPi * i / 9.0;
            const glm::dvec2 u{360 + 200 * std::cos(t), 243 + 200 * e * std::sin(t)};
            pts.push_back({u, u});
        }
        const QuadraticFit q = fitQuadratic(pts);
        EXPECT_FALSE(q.ok) << e;
        EXPECT_EQ(q.rank, 5) << e;
        EXPECT_TRUE(fitAffine(pts).ok) << e;
    }
}

TEST(QuadraticFit, TwoRowsHaveRankFive) {
    // The top row in the sky leaves two rows of control points.
    auto pts = gridThrough(Quadratic::identity(), 720, 486);
    pts.erase(pts.begin(), pts.begin() + 3);
    const QuadraticFit q = fitQuadratic(pts);
    EXPECT_FALSE(q.ok);
    EXPECT_EQ(q.rank, 5);
    EXPECT_TRUE(fitAffine(pts).ok);
}

TEST(QuadraticFit, NearSingularSystemsAreRejected) {
    // Points a hair off a conic: full rank, but the quadratic terms are unconstrained.
    for (const double eps : {1e-4, 1e-6, 1e-9}) {
        std::vector<Correspondence> pts;
        for (int i = 0; i < 9; ++i) {
            const double t = 2 * kPi * i / 9.0;
            const double r = 200 + (i == 4 ? eps : 0.0);
            const glm::dvec2 u{360 + r * std::cos(t), 243 + r * std::sin(t)};
            pts.push_back({u, u + glm::dvec2{0.0, 5.0 * (i % 2)}});
        }
        const QuadraticFit q = fitQuadratic(pts);
        EXPECT_FALSE(q.ok) << eps;
        EXPECT_GT(q.condition, kMaxCondition) << eps;
    }
}

TEST(QuadraticFit, NonFiniteInputIsRejected) {
    const double bad[] = {std::numeric_limits<double>::quiet_NaN(),
                          std::numeric_limits<double>::infinity()};
    for (const double v : bad) {
        for (int field = 0; field < 2; ++field) {
            auto pts = gridThrough(Quadratic::identity(), 720, 486);
            (field ? pts[4].field.x : pts[4].source.y) = v;
            EXPECT_FALSE(fitQuadratic(pts).ok);
            EXPECT_FALSE(fitAffine(pts).ok);
            EXPECT_FALSE(fitHomography(pts).ok);
        }
    }
}

TEST(HomographyFit, RecoversProjectiveMaps) {
    std::mt19937 rng(5);
    std::uniform_real_distribution<double> d(-1.0, 1.0);
    for (int trial = 0; trial < 30; ++trial) {
        Homography h;
        h.h = {1 + 0.1 * d(rng), 0.1 * d(rng),  20 * d(rng),   0.1 * d(rng), 1 + 0.1 * d(rng),
               20 * d(rng),      2e-4 * d(rng), 2e-4 * d(rng), 1.0};
        std::vector<Correspondence> pts;
        for (double fy : {0.1, 0.5, 0.9}) {
            for (double fx : {0.1, 0.5, 0.9}) {
                const glm::dvec2 u{fx * 720, fy * 486};
                pts.push_back({u, h(u)});
            }
        }
        const HomographyFit fit = fitHomography(pts);
        ASSERT_TRUE(fit.ok);
        EXPECT_EQ(fit.rank, 8);
        for (const glm::dvec2 p : {glm::dvec2{0, 0}, glm::dvec2{720, 486}, glm::dvec2{300, 100}}) {
            const glm::dvec2 e = fit.warp(p) - h(p);
            EXPECT_LT(std::hypot(e.x, e.y), 1e-6);
        }
    }
}

// --- The full fit on analytic frames --------------------------------------------------------

const ig::Intrinsics kIn = ig::Intrinsics::fromFov(160, 120, 1.0, 16);

OutputGeometry geometry() {
    return OutputGeometry::of(kIn, kIn.windowWidth(), kIn.windowHeight());
}

TEST(FitWarp, SamePoseGivesIdentity) {
    for (const double pitch : {-10.0, -35.0, -60.0, -85.0}) {
        for (const double yaw : {0.0, 1.3, -2.9}) {
            ig::Pose pose = test::lookingDown(pitch);
            pose.yaw = yaw;
            const ig::RenderedFrame f = test::renderPlane(pose, kIn);
            FitOptions terrainOnly;
            terrainOnly.useSky = false;
            int sky = 0;
            for (const auto& cp : f.controlPoints)
                sky += cp.world.w == 0.0;
            // Sky directions in the fit (the default) keep the quadratic; either way the warp
            // is the identity.
            if (sky == 0) {
                EXPECT_EQ(fitWarp(f, pose, geometry(), terrainOnly, nullptr).fallback,
                          Fallback::None);
            }
            const WarpInfo w = fitWarp(f, pose, geometry(), {}, nullptr);
            EXPECT_EQ(w.fallback, Fallback::None) << pitch;
            const Quadratic q = quadraticOf(w);
            for (double y = 0; y <= 120; y += 10) {
                for (double x = 0; x <= 160; x += 10) {
                    const glm::dvec2 e = q({x, y}) - glm::dvec2{x + 16, y + 16};
                    EXPECT_LT(std::hypot(e.x, e.y), 1e-6) << pitch << " " << x << "," << y;
                }
            }
        }
    }
}

TEST(FitWarp, PureRollIsExactlyTheRotation) {
    const ig::Pose pose = test::lookingDown(-40.0);
    const ig::RenderedFrame f = test::renderPlane(pose, kIn);
    const ig::Camera frameCam(pose, kIn);
    for (const double rollDeg : {-30.0, -5.0, 0.5, 12.0, 45.0}) {
        ig::Pose rolled = pose;
        rolled.roll = rollDeg * kPi / 180;
        const WarpInfo w = fitWarp(f, rolled, geometry(), {}, nullptr);
        ASSERT_EQ(w.fallback, Fallback::None);
        const Quadratic q = quadraticOf(w);
        const double c = std::cos(rolled.roll), s = std::sin(rolled.roll);
        // The analytic 2D rotation about the window centre.
        for (double y = 0; y <= 120; y += 15) {
            for (double x = 0; x <= 160; x += 20) {
                const double dx = x - 80, dy = y - 60;
                const glm::dvec2 want{80 + c * dx - s * dy + 16, 60 + s * dx + c * dy + 16};
                const glm::dvec2 e = q({x, y}) - want;
                EXPECT_LT(std::hypot(e.x, e.y), 1e-6) << rollDeg;
            }
        }
        // And the cameras agree: a world point seen by the rolled camera maps to where the
        // frame saw it.
        ig::Intrinsics win = kIn;
        win.width = 160;
        win.height = 120;
        win.margin = 0;
        const ig::Camera rolledCam(rolled, win);
        for (const glm::dvec3 p : {glm::dvec3{1100, 2500, 0}, glm::dvec3{900, 2300, 0}}) {
            const auto qf = rolledCam.project(p);
            const auto pf = frameCam.project(p);
            ASSERT_TRUE(qf && pf);
            const glm::dvec2 e = q(*qf) - *pf;
            EXPECT_LT(std::hypot(e.x, e.y), 1e-6) << rollDeg;
        }
    }
}

TEST(FitWarp, ScalingToAnotherOutputSize) {
    const ig::Pose pose = test::lookingDown(-40.0);
    const ig::RenderedFrame f = test::renderPlane(pose, kIn);
    const OutputGeometry g = OutputGeometry::of(kIn, 320, 180);
    const WarpInfo w = fitWarp(f, pose, g, {}, nullptr);
    const Quadratic q = quadraticOf(w);
    for (const glm::dvec2 p : {glm::dvec2{0, 0}, glm::dvec2{320, 180}, glm::dvec2{100, 50}}) {
        const glm::dvec2 want{p.x * 0.5 + 16, p.y * 120.0 / 180.0 + 16};
        const glm::dvec2 e = q(p) - want;
        EXPECT_LT(std::hypot(e.x, e.y), 1e-6);
    }
}

TEST(FitWarp, SkyInTheTopRowFallsBackToAffine) {
    // Pitch so the horizon lies between the top and middle control rows.
    const ig::Pose pose = test::lookingDown(-8.0);
    const ig::RenderedFrame f = test::renderPlane(pose, kIn);
    int sky = 0;
    for (const auto& cp : f.controlPoints)
        sky += cp.world.w == 0.0;
    ASSERT_EQ(sky, 3);
    ig::Pose moved = pose;
    moved.position.y += 5.0;
    FitOptions terrainOnly;
    terrainOnly.useSky = false;
    const WarpInfo w = fitWarp(f, moved, geometry(), terrainOnly, nullptr);
    EXPECT_EQ(w.fallback, Fallback::Affine);
    EXPECT_EQ(w.pointsUsed, 6);
    EXPECT_LT(quadraticBound(quadraticOf(w), 160, 120), 1000.0);
    // With the sky directions in the fit the quadratic is full rank again.
    FitOptions withSky;
    withSky.useSky = true;
    EXPECT_EQ(fitWarp(f, moved, geometry(), withSky, nullptr).fallback, Fallback::None);
}

TEST(FitWarp, CollinearControlPointsFallBackToRotation) {
    const ig::Pose pose = test::lookingDown(-40.0);
    ig::RenderedFrame f = test::renderPlane(pose, kIn);
    for (int k = 0; k < 9; ++k)
        f.controlPoints[k].world = {1000.0 + 10 * k, 2300.0, 0.0, 1.0};
    ig::Pose moved = pose;
    moved.yaw += 0.01;
    const WarpInfo w = fitWarp(f, moved, geometry(), {}, nullptr);
    EXPECT_EQ(w.fallback, Fallback::Rotation);
    // Rotation only: a small yaw shifts the image sideways by about focal * 0.01 px.
    const glm::dvec2 c = quadraticOf(w)({80, 60});
    EXPECT_NEAR(c.y, 76.0, 1.0);
    EXPECT_NEAR(std::abs(c.x - 96.0), kIn.focal * 0.01, 0.5);
}

TEST(FitWarp, ControlPointsOnAConicFallBackToAffine) {
    // Nine ground points on a circle project onto a conic in any view.
    const ig::Pose pose = test::lookingDown(-50.0);
    ig::RenderedFrame f = test::renderPlane(pose, kIn);
    const ig::Camera cam(pose, kIn);
    for (int k = 0; k < 9; ++k) {
        const double t = 2 * kPi * k / 9;
        const glm::dvec3 p{1150 + 60 * std::cos(t), 2250 + 60 * std::sin(t), 0.0};
        f.controlPoints[k].world = glm::dvec4(p, 1.0);
        f.controlPoints[k].pixel = *cam.project(p);
    }
    ig::Pose moved = pose;
    moved.position.x += 3.0;
    const WarpInfo w = fitWarp(f, moved, geometry(), {}, nullptr);
    EXPECT_EQ(w.fallback, Fallback::Affine);
    EXPECT_LT(quadraticBound(quadraticOf(w), 160, 120), 1000.0);
}

TEST(FitWarp, PointsBehindTheCameraAreDropped) {
    const ig::Pose pose = test::lookingDown(-30.0);
    const ig::RenderedFrame f = test::renderPlane(pose, kIn);
    // Fly past some control points: they end up behind the new camera.
    ig::Pose past = pose;
    past.position.z = 3.0;
    past.pitch = 0.0;
    const glm::dvec3 fwd = ig::CameraBasis::fromPose(pose).forward;
    past.position += glm::dvec3(fwd.x, fwd.y, 0.0) * 800.0;
    std::array<Correspondence, 9> pts;
    const std::size_t n = controlCorrespondences(f, past, false, pts);
    EXPECT_LT(n, 9u);
    EXPECT_GT(n, 0u);
    const WarpInfo w = fitWarp(f, past, geometry(), {}, nullptr);
    // The remaining points lie on one image row: neither the quadratic nor the affine fit is
    // posed, so the rotation-only warp (from the nine viewing directions) is used.
    EXPECT_EQ(w.fallback, Fallback::Rotation);
    EXPECT_TRUE(quadraticOf(w).isFinite());
    EXPECT_LT(quadraticBound(quadraticOf(w), 160, 120), kMaxSourceCoordinate);

    // Turned around: nothing is in front; the previous warp is held.
    ig::Pose back = pose;
    back.yaw += kPi;
    back.pitch = 0.4;
    WarpInfo previous = fitWarp(f, pose, geometry(), {}, nullptr);
    previous.a[0] += 1.25;  // recognisable
    const WarpInfo held = fitWarp(f, back, geometry(), {}, &previous);
    EXPECT_EQ(held.fallback, Fallback::Hold);
    EXPECT_EQ(held.a, previous.a);
    EXPECT_EQ(held.b, previous.b);
    // Without a previous warp: the frame as it is.
    const WarpInfo none = fitWarp(f, back, geometry(), {}, nullptr);
    EXPECT_EQ(none.fallback, Fallback::Hold);
    EXPECT_NEAR(quadraticOf(none)({10, 20}).x, 26.0, 1e-12);
}

TEST(FitWarp, NonFiniteInputEndsInAFallbackNotAWildWarp) {
    const ig::Pose pose = test::lookingDown(-40.0);
    const double nan = std::numeric_limits<double>::quiet_NaN();
    const double inf = std::numeric_limits<double>::infinity();
    ig::Pose moved = pose;
    moved.position.x += 2.0;
    // One bad control point: dropped, the other eight still fit the quadratic.
    for (const double v : {nan, inf}) {
        ig::RenderedFrame f = test::renderPlane(pose, kIn);
        f.controlPoints[2].world.x = v;
        f.controlPoints[7].pixel.y = v;
        const WarpInfo w = fitWarp(f, moved, geometry(), {}, nullptr);
        EXPECT_EQ(w.pointsUsed, 7);
        EXPECT_EQ(w.fallback, Fallback::None);
        EXPECT_TRUE(quadraticOf(w).isFinite());
    }
    // A non-finite pose: hold.
    const ig::RenderedFrame f = test::renderPlane(pose, kIn);
    for (const double v : {nan, inf}) {
        ig::Pose bad = moved;
        bad.roll = v;
        const WarpInfo w = fitWarp(f, bad, geometry(), {}, nullptr);
        EXPECT_EQ(w.fallback, Fallback::Hold);
        EXPECT_TRUE(quadraticOf(w).isFinite());
        bad = moved;
        bad.position.z = v;
        EXPECT_EQ(fitWarp(f, bad, geometry(), {}, nullptr).fallback, Fallback::Hold);
    }
    // Every control point bad: the rotation-only warp from the poses.
    ig::RenderedFrame allBad = test::renderPlane(pose, kIn);
    for (auto& cp : allBad.controlPoints)
        cp.world = {nan, nan, nan, nan};
    EXPECT_EQ(fitWarp(allBad, moved, geometry(), {}, nullptr).fallback, Fallback::Rotation);
}

TEST(FitWarp, EveryModelIsExactAtTheSamePose) {
    const ig::Pose pose = test::lookingDown(-45.0);
    const ig::RenderedFrame f = test::renderPlane(pose, kIn);
    for (const WarpModel m : {WarpModel::Poly, WarpModel::Affine, WarpModel::Homography}) {
        FitOptions o;
        o.model = m;
        const WarpInfo w = fitWarp(f, pose, geometry(), o, nullptr);
        EXPECT_EQ(w.fallback, Fallback::None) << warpModelName(m);
        for (const glm::dvec2 p : {glm::dvec2{0, 0}, glm::dvec2{160, 120}, glm::dvec2{33, 71}}) {
            const glm::dvec2 s = w.projective ? Homography{w.h}(p) : quadraticOf(w)(p);
            EXPECT_NEAR(s.x, p.x + 16, 1e-6) << warpModelName(m);
            EXPECT_NEAR(s.y, p.y + 16, 1e-6) << warpModelName(m);
        }
    }
}

TEST(FitWarp, HomographyIsExactForAPlaneUnderMotion) {
    // Ground plane, no sky: a homography maps one view onto the other exactly.
    const ig::Pose pose = test::lookingDown(-50.0);
    const ig::RenderedFrame f = test::renderPlane(pose, kIn);
    ig::Pose moved = pose;
    moved.position += glm::dvec3{12.0, 20.0, -15.0};
    moved.yaw += 0.05;
    moved.pitch += 0.03;
    moved.roll = 0.1;
    FitOptions o;
    o.model = WarpModel::Homography;
    const WarpInfo w = fitWarp(f, moved, geometry(), o, nullptr);
    ASSERT_EQ(w.fallback, Fallback::None);
    ig::Intrinsics win = kIn;
    win.width = 160;
    win.height = 120;
    win.margin = 0;
    const ig::Camera movedCam(moved, win), frameCam(pose, kIn);
    for (const glm::dvec3 p : {glm::dvec3{1100, 2400, 0}, glm::dvec3{1050, 2350, 0}}) {
        const auto q = movedCam.project(p);
        const auto s = frameCam.project(p);
        ASSERT_TRUE(q && s);
        const glm::dvec2 e = Homography{w.h}(*q) - *s;
        EXPECT_LT(std::hypot(e.x, e.y), 1e-6);
    }
}

}  // namespace
}  // namespace prp
