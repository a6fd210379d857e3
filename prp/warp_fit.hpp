// Warp fitting: quadratic (Cohen-Or sec. 4), affine and homography fits to control points, roll.
#pragma once

#include "ig/camera.hpp"
#include "ig/frame.hpp"
#include "prp/field.hpp"

#include <glm/vec2.hpp>

#include <array>
#include <cstddef>
#include <span>

namespace prp {

// Affine map (x, y) -> (m00 x + m01 y + tx, m10 x + m11 y + ty).
struct Affine2 {
    double m00 = 1.0, m01 = 0.0, m10 = 0.0, m11 = 1.0, tx = 0.0, ty = 0.0;

    glm::dvec2 operator()(glm::dvec2 p) const {
        return {m00 * p.x + m01 * p.y + tx, m10 * p.x + m11 * p.y + ty};
    }
};

// Second-degree map: x' = a0 + a1 x + a2 y + a3 xy + a4 x^2 + a5 y^2, y' likewise with b.
struct Quadratic {
    std::array<double, 6> a{}, b{};

    static Quadratic identity();
    static Quadratic fromAffine(const Affine2& m);
    glm::dvec2 operator()(glm::dvec2 p) const;
    bool isFinite() const;
};

// sourceFromArgument composed with an affine argument: returns Q' with Q'(p) = q(m(p)), exactly.
Quadratic composeAffine(const Quadratic& q, const Affine2& m);

// Projective map, row-major 3x3: (x, y) -> ((h0 x + h1 y + h2) / w, (h3 x + h4 y + h5) / w),
// w = h6 x + h7 y + h8.
struct Homography {
    std::array<double, 9> h{1, 0, 0, 0, 1, 0, 0, 0, 1};

    glm::dvec2 operator()(glm::dvec2 p) const;
};
Homography composeAffine(const Homography& hm, const Affine2& m);

// One control point seen in both images: `field` in the field's un-rolled window (window
// pixels, no margins), `source` in the rendered frame (margins included).
struct Correspondence {
    glm::dvec2 field{0.0};
    glm::dvec2 source{0.0};
};

// Outcome of one least-squares fit.
struct FitResult {
    bool ok = false;  // full rank, condition below kMaxCondition, finite
    int rank = 0;
    double condition = 0.0;   // 2-norm condition number of the design matrix actually solved
    double residualPx = 0.0;  // RMS residual, source pixels
    int points = 0;
};
struct QuadraticFit : FitResult {
    Quadratic warp;
};
struct HomographyFit : FitResult {
    Homography warp;
};

// Relative singular-value threshold for the numerical rank.
inline constexpr double kRankTolerance = 1e-9;
// Largest condition number of the (normalised) design matrix a fit may have to be used.
inline constexpr double kMaxCondition = 1e3;
// Largest second-order displacement a quadratic warp may add over the output window, as a
// fraction of the window's half-diagonal (in source pixels); beyond it the fit is taken to be
// wild (an almost degenerate point set interpolated exactly) and the fallback is used.
inline constexpr double kMaxCurvatureFraction = 0.5;

// Least-squares fits of source = f(field). `normalise` centres and scales the field coordinates
// first (the default; without it raw pixel coordinates make the quadratic's design matrix
// condition number ~1e6). Needs >= 6 points (quadratic), >= 3 (affine), >= 4 (homography, DLT
// with Hartley normalisation of both point sets). Non-finite input makes the fit fail.
QuadraticFit fitQuadratic(std::span<const Correspondence> points, bool normalise = true);
QuadraticFit fitAffine(std::span<const Correspondence> points, bool normalise = true);
HomographyFit fitHomography(std::span<const Correspondence> points);
// Condition number of the quadratic fit's 6-column design matrix (its normal equations have
// the square of it).
double quadraticDesignCondition(std::span<const Correspondence> points, bool normalise);

// Control points of `frame` projected into the un-rolled camera at `fieldPose` with the frame's
// window intrinsics (no margins; a field of another focal length is composed afterwards, by
// OutputGeometry::unrolledFromOutput). Points behind that camera or non-finite are dropped; sky
// directions (w = 0) are dropped unless `useSky`. Returns the number written to `out`.
std::size_t controlCorrespondences(const ig::RenderedFrame& frame, const ig::Pose& fieldPose,
                                   bool useSky, std::array<Correspondence, 9>& out);
// Rotation-only correspondences: the control pixels' viewing directions (no parallax).
std::size_t rotationCorrespondences(const ig::RenderedFrame& frame, const ig::Pose& fieldPose,
                                    std::array<Correspondence, 9>& out);

// Geometry of the output: a `width` x `height` frame showing the rendered frame's window, seen
// at the field's own focal length (its field of view), which may differ from the frame's.
struct OutputGeometry {
    int width = 0;
    int height = 0;
    int windowWidth = 0;  // rendered window (margins excluded)
    int windowHeight = 0;
    int margin = 0;
    double focal = 0.0;          // the field's focal length, window pixels (0: the frame's)
    double renderedFocal = 0.0;  // the rendered frame's focal length

    // `fieldFocal` 0: the field shows the frame's field of view.
    static OutputGeometry of(const ig::Intrinsics& rendered, int outWidth, int outHeight,
                             double fieldFocal = 0.0);
    // Rendered window pixels per field window pixel about the window centre (the change of
    // focal length; exactly 1 when the field has the frame's field of view).
    double zoom() const;
    // The field's camera over the window: its focal length, no margin.
    ig::Intrinsics fieldWindow() const;
    // Output pixel -> window pixel (scaling).
    Affine2 windowFromOutput() const;
    // Output pixel of a camera rolled by `roll` at the field's focal length -> un-rolled
    // window pixel at the frame's (rotation and change of focal length about the window
    // centre, composed with the scaling).
    Affine2 unrolledFromOutput(double roll) const;
    // Output pixel -> rendered-frame pixel without motion compensation ("hold"; the change of
    // focal length applied).
    Affine2 sourceFromOutputHold() const;
};

// Bound on |f| over the output rectangle from the coefficients; used to reject wild warps.
double quadraticBound(const Quadratic& q, int width, int height);
// Second-order displacement of `q` over a width x height window about its centre.
double quadraticCurvature(const Quadratic& q, int width, int height);
// Largest source coordinate magnitude a warp may reach to be applied.
inline constexpr double kMaxSourceCoordinate = 1 << 20;

// Options of the fit with fallbacks.
struct FitOptions {
    WarpModel model = WarpModel::Poly;
    bool useSky = true;  // fit sky directions too (points at infinity: no parallax)
};

// The full fit for one field: projects the control points, fits the model, composes roll and
// scaling, and falls back (affine, then rotation-only, then `previous`, else the hold mapping)
// when too few points remain or a fit is rank-deficient, ill-conditioned or wild.
// The result maps output pixels to rendered-frame pixels. Not for WarpModel::Depth (use Hold).
WarpInfo fitWarp(const ig::RenderedFrame& frame, const ig::Pose& fieldPose,
                 const OutputGeometry& geometry, const FitOptions& options,
                 const WarpInfo* previous);

Quadratic quadraticOf(const WarpInfo& info);

// Check points of the automatic model choice: a kCheckGrid x kCheckGrid grid of window pixels
// (cell centres) and the world point each shows, read from the frame's depth (the same
// registration as the control points: the pixel centre's ray at its depth).
inline constexpr int kCheckGrid = 5;
inline constexpr int kCheckPointCount = kCheckGrid * kCheckGrid;
// The check points seen from `fieldPose` (roll included): output pixel (`field`) -> rendered
// pixel (`source`) pairs. Points with no usable depth (NaN, negative), behind the camera or
// non-finite are dropped; sky pixels are directions. Returns the number written.
std::size_t checkCorrespondences(const ig::RenderedFrame& frame, const ig::Pose& fieldPose,
                                 const OutputGeometry& geometry,
                                 std::array<Correspondence, kCheckPointCount>& out);
// Largest distance, in rendered pixels, from `warp` of each pair's output pixel to its rendered
// pixel; 0 without pairs, +inf when a result is not finite.
double warpCheckError(const WarpInfo& warp, std::span<const Correspondence> pairs);

}  // namespace prp
