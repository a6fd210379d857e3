#include "prp/warp_fit.hpp"

#include "ig/caster.hpp"

#include <Eigen/Dense>
#include <glm/geometric.hpp>

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>
#include <span>

namespace prp {

namespace {

// Root-mean-square distance, in source pixels, between where `warp` sends each field point and
// the source point it should reach.
template <class Warp>
double rmsResidual(const Warp& warp, std::span<const Correspondence> points) {
    double sum = 0.0;
    for (const Correspondence& c : points) {
        const glm::dvec2 d = warp(c.field) - c.source;
        sum += d.x * d.x + d.y * d.y;
    }
    return std::sqrt(sum / static_cast<double>(points.size()));
}

// Fixed-capacity matrices: a fit allocates nothing on the heap.
template <int Cols, int MaxRows>
using DesignMatrix = Eigen::Matrix<double, Eigen::Dynamic, Cols, Eigen::ColMajor, MaxRows, Cols>;
using Column9 = Eigen::Matrix<double, Eigen::Dynamic, 1, Eigen::ColMajor, 9, 1>;

bool finite(glm::dvec2 p) {
    return std::isfinite(p.x) && std::isfinite(p.y);
}

// Centring and isotropic scaling so the points have centroid 0 and RMS radius sqrt(2).
struct Normaliser {
    glm::dvec2 mean{0.0};
    double scale = 1.0;  // normalised = (p - mean) * scale

    static Normaliser of(std::span<const Correspondence> points, bool field) {
        Normaliser n;
        for (const Correspondence& c : points)
            n.mean += field ? c.field : c.source;
        n.mean /= static_cast<double>(points.size());
        double sum = 0.0;
        for (const Correspondence& c : points) {
            const glm::dvec2 d = (field ? c.field : c.source) - n.mean;
            sum += d.x * d.x + d.y * d.y;
        }
        const double rms = std::sqrt(sum / static_cast<double>(points.size()));
        n.scale = rms > 0.0 ? std::sqrt(2.0) / rms : 1.0;
        return n;
    }
    Affine2 affine() const { return {scale, 0.0, 0.0, scale, -mean.x * scale, -mean.y * scale}; }
};

bool allFinite(std::span<const Correspondence> points) {
    return std::all_of(points.begin(), points.end(),
                       [](const Correspondence& c) { return finite(c.field) && finite(c.source); });
}

// Rank and condition from singular values (descending).
template <class Values>
void rankAndCondition(const Values& s, int columns, FitResult& r) {
    const double smax = s.size() > 0 ? s(0) : 0.0;
    r.rank = 0;
    for (Eigen::Index i = 0; i < s.size(); ++i) {
        if (s(i) > smax * kRankTolerance && s(i) > 0.0) ++r.rank;
    }
    const double smin = s.size() >= columns ? s(columns - 1) : 0.0;
    r.condition = smin > 0.0 ? smax / smin : std::numeric_limits<double>::infinity();
}

template <int Cols>
QuadraticFit fitPolynomial(std::span<const Correspondence> points, bool normalise) {
    QuadraticFit r;
    r.points = static_cast<int>(points.size());
    if (points.size() < static_cast<std::size_t>(Cols) || points.size() > 9 || !allFinite(points)) {
        return r;
    }
    const Affine2 norm = normalise ? Normaliser::of(points, true).affine() : Affine2{};
    const Eigen::Index n = static_cast<Eigen::Index>(points.size());
    DesignMatrix<Cols, 9> m(n, Cols);
    Eigen::Matrix<double, Eigen::Dynamic, 2, Eigen::ColMajor, 9, 2> rhs(n, 2);
    for (Eigen::Index i = 0; i < n; ++i) {
        const glm::dvec2 u = norm(points[i].field);
        m(i, 0) = 1.0;
        m(i, 1) = u.x;
        m(i, 2) = u.y;
        if constexpr (Cols == 6) {
            m(i, 3) = u.x * u.y;
            m(i, 4) = u.x * u.x;
            m(i, 5) = u.y * u.y;
        }
        rhs(i, 0) = points[i].source.x;
        rhs(i, 1) = points[i].source.y;
    }
    Eigen::JacobiSVD<DesignMatrix<Cols, 9>> svd(m, Eigen::ComputeThinU | Eigen::ComputeThinV);
    rankAndCondition(svd.singularValues(), Cols, r);
    if (r.rank < Cols) return r;
    const Eigen::Matrix<double, Cols, 2> coef = svd.solve(rhs);
    Quadratic q;
    for (int k = 0; k < Cols; ++k) {
        q.a[k] = coef(k, 0);
        q.b[k] = coef(k, 1);
    }
    q = composeAffine(q, norm);
    r.residualPx = rmsResidual(q, points);
    r.warp = q;
    r.ok = q.isFinite() && std::isfinite(r.residualPx) && r.condition <= kMaxCondition;
    return r;
}

Affine2 inverse(const Affine2& m) {
    const double det = m.m00 * m.m11 - m.m01 * m.m10;
    Affine2 r;
    r.m00 = m.m11 / det;
    r.m01 = -m.m01 / det;
    r.m10 = -m.m10 / det;
    r.m11 = m.m00 / det;
    r.tx = -(r.m00 * m.tx + r.m01 * m.ty);
    r.ty = -(r.m10 * m.tx + r.m11 * m.ty);
    return r;
}

ig::Pose unrolled(ig::Pose pose) {
    pose.roll = 0.0;
    return pose;
}

WarpInfo infoFrom(const Quadratic& q, const FitResult& fit, WarpModel model, Fallback fallback) {
    WarpInfo info;
    info.model = model;
    info.fallback = fallback;
    info.a = q.a;
    info.b = q.b;
    info.rank = fit.rank;
    info.condition = fit.condition;
    info.residualPx = fit.residualPx;
    info.pointsUsed = fit.points;
    return info;
}

bool bounded(const Quadratic& q, const OutputGeometry& g) {
    return q.isFinite() && quadraticBound(q, g.width, g.height) < kMaxSourceCoordinate;
}

// Positive denominator over the whole output rectangle (checked at its corners: it is linear).
bool projectiveUsable(const Homography& hm, const OutputGeometry& g) {
    for (const double y : {0.0, static_cast<double>(g.height)}) {
        for (const double x : {0.0, static_cast<double>(g.width)}) {
            const double w = hm.h[6] * x + hm.h[7] * y + hm.h[8];
            if (!(w > 1e-9)) return false;
            const glm::dvec2 p = hm({x, y});
            if (!finite(p) || std::abs(p.x) > kMaxSourceCoordinate ||
                std::abs(p.y) > kMaxSourceCoordinate) {
                return false;
            }
        }
    }
    return true;
}

}  // namespace

Quadratic Quadratic::identity() {
    return fromAffine(Affine2{});
}

Quadratic Quadratic::fromAffine(const Affine2& m) {
    Quadratic q;
    q.a = {m.tx, m.m00, m.m01, 0.0, 0.0, 0.0};
    q.b = {m.ty, m.m10, m.m11, 0.0, 0.0, 0.0};
    return q;
}

glm::dvec2 Quadratic::operator()(glm::dvec2 p) const {
    const double x = p.x, y = p.y;
    return {a[0] + a[1] * x + a[2] * y + a[3] * x * y + a[4] * x * x + a[5] * y * y,
            b[0] + b[1] * x + b[2] * y + b[3] * x * y + b[4] * x * x + b[5] * y * y};
}

bool Quadratic::isFinite() const {
    for (int k = 0; k < 6; ++k) {
        if (!std::isfinite(a[k]) || !std::isfinite(b[k])) return false;
    }
    return true;
}

Quadratic composeAffine(const Quadratic& q, const Affine2& m) {
    // x = ax X + bx Y + gx, y = ay X + by Y + gy substituted into each polynomial.
    const double ax = m.m00, bx = m.m01, gx = m.tx;
    const double ay = m.m10, by = m.m11, gy = m.ty;
    auto one = [&](const std::array<double, 6>& c) {
        std::array<double, 6> r;
        r[0] = c[0] + c[1] * gx + c[2] * gy + c[3] * gx * gy + c[4] * gx * gx + c[5] * gy * gy;
        r[1] = c[1] * ax + c[2] * ay + c[3] * (ax * gy + ay * gx) + 2.0 * c[4] * ax * gx +
               2.0 * c[5] * ay * gy;
        r[2] = c[1] * bx + c[2] * by + c[3] * (bx * gy + by * gx) + 2.0 * c[4] * bx * gx +
               2.0 * c[5] * by * gy;
        r[3] = c[3] * (ax * by + ay * bx) + 2.0 * c[4] * ax * bx + 2.0 * c[5] * ay * by;
        r[4] = c[3] * ax * ay + c[4] * ax * ax + c[5] * ay * ay;
        r[5] = c[3] * bx * by + c[4] * bx * bx + c[5] * by * by;
        return r;
    };
    Quadratic r;
    r.a = one(q.a);
    r.b = one(q.b);
    return r;
}

glm::dvec2 Homography::operator()(glm::dvec2 p) const {
    const double w = h[6] * p.x + h[7] * p.y + h[8];
    return {(h[0] * p.x + h[1] * p.y + h[2]) / w, (h[3] * p.x + h[4] * p.y + h[5]) / w};
}

Homography composeAffine(const Homography& hm, const Affine2& m) {
    const std::array<double, 9> a{m.m00, m.m01, m.tx, m.m10, m.m11, m.ty, 0.0, 0.0, 1.0};
    Homography r;
    for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j) {
            r.h[3 * i + j] =
                hm.h[3 * i] * a[j] + hm.h[3 * i + 1] * a[3 + j] + hm.h[3 * i + 2] * a[6 + j];
        }
    }
    return r;
}

QuadraticFit fitQuadratic(std::span<const Correspondence> points, bool normalise) {
    return fitPolynomial<6>(points, normalise);
}

QuadraticFit fitAffine(std::span<const Correspondence> points, bool normalise) {
    return fitPolynomial<3>(points, normalise);
}

double quadraticDesignCondition(std::span<const Correspondence> points, bool normalise) {
    if (points.empty() || points.size() > 9 || !allFinite(points)) {
        return std::numeric_limits<double>::infinity();
    }
    const Affine2 norm = normalise ? Normaliser::of(points, true).affine() : Affine2{};
    DesignMatrix<6, 9> m(static_cast<Eigen::Index>(points.size()), 6);
    for (Eigen::Index i = 0; i < m.rows(); ++i) {
        const glm::dvec2 u = norm(points[i].field);
        m.row(i) << 1.0, u.x, u.y, u.x * u.y, u.x * u.x, u.y * u.y;
    }
    Eigen::JacobiSVD<DesignMatrix<6, 9>> svd(m);
    FitResult r;
    rankAndCondition(svd.singularValues(), 6, r);
    return r.condition;
}

// GCC 12 reports Eigen's fixed-capacity SVD storage as maybe-uninitialized (a false positive).
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#endif
HomographyFit fitHomography(std::span<const Correspondence> points) {
    HomographyFit r;
    r.points = static_cast<int>(points.size());
    if (points.size() < 4 || points.size() > 9 || !allFinite(points)) return r;
    const Affine2 tu = Normaliser::of(points, true).affine();
    const Affine2 tp = Normaliser::of(points, false).affine();
    const Eigen::Index n = static_cast<Eigen::Index>(points.size());
    DesignMatrix<9, 18> m(2 * n, 9);
    for (Eigen::Index i = 0; i < n; ++i) {
        const glm::dvec2 u = tu(points[i].field);
        const glm::dvec2 p = tp(points[i].source);
        m.row(2 * i) << u.x, u.y, 1.0, 0.0, 0.0, 0.0, -p.x * u.x, -p.x * u.y, -p.x;
        m.row(2 * i + 1) << 0.0, 0.0, 0.0, u.x, u.y, 1.0, -p.y * u.x, -p.y * u.y, -p.y;
    }
    Eigen::JacobiSVD<DesignMatrix<9, 18>> svd(m, Eigen::ComputeFullV);
    // The solution is the null vector: the system has rank 8 when well posed.
    const auto& s = svd.singularValues();
    const double smax = s(0);
    r.rank = 0;
    for (Eigen::Index i = 0; i < s.size(); ++i) {
        if (s(i) > smax * kRankTolerance) ++r.rank;
    }
    r.condition =
        s.size() >= 8 && s(7) > 0.0 ? smax / s(7) : std::numeric_limits<double>::infinity();
    if (r.rank < 8) return r;
    const Column9 v = svd.matrixV().col(8);
    Homography hn;
    for (int k = 0; k < 9; ++k)
        hn.h[k] = v(k);
    // source = tp^-1 * hn * tu.
    Homography h = composeAffine(hn, tu);
    const Affine2 ti = inverse(tp);
    Homography out;
    const std::array<double, 9> a{ti.m00, ti.m01, ti.tx, ti.m10, ti.m11, ti.ty, 0.0, 0.0, 1.0};
    for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j) {
            out.h[3 * i + j] =
                a[3 * i] * h.h[j] + a[3 * i + 1] * h.h[3 + j] + a[3 * i + 2] * h.h[6 + j];
        }
    }
    const double scale = out.h[8] != 0.0 ? out.h[8] : 1.0;
    for (double& e : out.h)
        e /= scale;
    r.residualPx = rmsResidual(out, points);
    r.warp = out;
    r.ok = std::isfinite(r.residualPx) && r.condition <= kMaxCondition * kMaxCondition;
    return r;
}
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic pop
#endif

std::size_t controlCorrespondences(const ig::RenderedFrame& frame, const ig::Pose& fieldPose,
                                   bool useSky, std::array<Correspondence, 9>& out) {
    if (!fieldPose.isFinite()) return 0;
    const ig::Camera cam(unrolled(fieldPose), frame.intrinsics.window());
    std::size_t n = 0;
    for (const ig::ControlPoint& cp : frame.controlPoints) {
        const glm::dvec4& w = cp.world;
        if (!finite(cp.pixel) || !std::isfinite(w.x) || !std::isfinite(w.y) ||
            !std::isfinite(w.z) || !std::isfinite(w.w)) {
            continue;
        }
        const bool sky = w.w == 0.0;
        if (sky && !useSky) continue;
        glm::dvec3 p{w.x, w.y, w.z};
        double ww = 1.0;
        if (!sky) {
            p /= w.w;
        } else {
            ww = 0.0;
        }
        const auto q = cam.project(p, ww);
        if (!q || !finite(*q)) continue;
        out[n++] = {*q, cp.pixel};
    }
    return n;
}

std::size_t rotationCorrespondences(const ig::RenderedFrame& frame, const ig::Pose& fieldPose,
                                    std::array<Correspondence, 9>& out) {
    if (!fieldPose.isFinite() || !frame.pose.isFinite()) return 0;
    const ig::Camera src(frame.pose, frame.intrinsics);
    const ig::Camera cam(unrolled(fieldPose), frame.intrinsics.window());
    const auto pixels = ig::controlPointPixels(frame.intrinsics);
    std::size_t n = 0;
    for (const glm::dvec2& px : pixels) {
        const auto q = cam.project(src.rayDirection(px.x, px.y), 0.0);
        if (!q || !finite(*q)) continue;
        out[n++] = {*q, px};
    }
    return n;
}

OutputGeometry OutputGeometry::of(const ig::Intrinsics& rendered, int outWidth, int outHeight,
                                  double fieldFocal) {
    OutputGeometry g;
    g.width = outWidth;
    g.height = outHeight;
    g.windowWidth = rendered.windowWidth();
    g.windowHeight = rendered.windowHeight();
    g.margin = rendered.margin;
    g.renderedFocal = rendered.focal;
    g.focal = fieldFocal > 0.0 ? fieldFocal : rendered.focal;
    return g;
}

double OutputGeometry::zoom() const {
    // Equal focal lengths give exactly 1, so a field at the frame's field of view is warped
    // bit for bit as without the factor.
    return focal > 0.0 && renderedFocal > 0.0 ? renderedFocal / focal : 1.0;
}

ig::Intrinsics OutputGeometry::fieldWindow() const {
    ig::Intrinsics in;
    in.width = windowWidth;
    in.height = windowHeight;
    in.margin = 0;
    in.focal = focal > 0.0 ? focal : renderedFocal;
    return in;
}

Affine2 OutputGeometry::windowFromOutput() const {
    return {static_cast<double>(windowWidth) / width,   0.0, 0.0,
            static_cast<double>(windowHeight) / height, 0.0, 0.0};
}

Affine2 OutputGeometry::unrolledFromOutput(double roll) const {
    // A camera rolled by r sees the un-rolled image rotated: u - c = R(r) (w - c) with
    // R = [cos -sin; sin cos] in image axes (x right, y down). A field of focal length f' shows
    // what the frame's focal length f puts at u - c = (f / f') R(r) (w - c): the change of field
    // of view is a scaling about the same centre, composed the same way.
    const Affine2 s = windowFromOutput();
    const double k = zoom();
    const double c = std::cos(roll), sn = std::sin(roll);
    const double cx = 0.5 * windowWidth, cy = 0.5 * windowHeight;
    Affine2 r;
    r.m00 = k * c * s.m00;
    r.m01 = k * -sn * s.m11;
    r.m10 = k * sn * s.m00;
    r.m11 = k * c * s.m11;
    r.tx = cx - k * (c * cx - sn * cy);
    r.ty = cy - k * (sn * cx + c * cy);
    return r;
}

Affine2 OutputGeometry::sourceFromOutputHold() const {
    Affine2 m = windowFromOutput();
    const double k = zoom();
    const double cx = 0.5 * windowWidth, cy = 0.5 * windowHeight;
    m.m00 *= k;
    m.m11 *= k;
    m.tx += cx - k * cx + margin;
    m.ty += cy - k * cy + margin;
    return m;
}

double quadraticCurvature(const Quadratic& q, int width, int height) {
    const double hw = 0.5 * width, hh = 0.5 * height;
    auto one = [&](const std::array<double, 6>& c) {
        return std::abs(c[3]) * hw * hh + std::abs(c[4]) * hw * hw + std::abs(c[5]) * hh * hh;
    };
    return std::max(one(q.a), one(q.b));
}

double quadraticBound(const Quadratic& q, int width, int height) {
    const double w = width, h = height;
    auto one = [&](const std::array<double, 6>& c) {
        return std::abs(c[0]) + std::abs(c[1]) * w + std::abs(c[2]) * h + std::abs(c[3]) * w * h +
               std::abs(c[4]) * w * w + std::abs(c[5]) * h * h;
    };
    return std::max(one(q.a), one(q.b));
}

Quadratic quadraticOf(const WarpInfo& info) {
    Quadratic q;
    q.a = info.a;
    q.b = info.b;
    return q;
}

WarpInfo fitWarp(const ig::RenderedFrame& frame, const ig::Pose& fieldPose,
                 const OutputGeometry& geometry, const FitOptions& options,
                 const WarpInfo* previous) {
    const Quadratic hold = Quadratic::fromAffine(geometry.sourceFromOutputHold());
    if (options.model == WarpModel::Hold || options.model == WarpModel::Depth) {
        FitResult none;
        return infoFrom(hold, none, WarpModel::Hold, Fallback::None);
    }
    const bool poseOk = fieldPose.isFinite();
    const Affine2 argument = geometry.unrolledFromOutput(poseOk ? fieldPose.roll : 0.0);
    std::array<Correspondence, 9> pts;
    const std::size_t n =
        poseOk ? controlCorrespondences(frame, fieldPose, options.useSky, pts) : 0;
    const std::span<const Correspondence> used(pts.data(), n);

    if (options.model == WarpModel::Homography) {
        const HomographyFit fit = fitHomography(used);
        if (fit.ok) {
            const Homography hm = composeAffine(fit.warp, argument);
            if (projectiveUsable(hm, geometry)) {
                WarpInfo info = infoFrom(Quadratic{}, fit, WarpModel::Homography, Fallback::None);
                info.projective = true;
                info.h = hm.h;
                return info;
            }
        }
    } else if (options.model == WarpModel::Poly) {
        const QuadraticFit fit = fitQuadratic(used);
        const Quadratic q = composeAffine(fit.warp, argument);
        const double limit =
            kMaxCurvatureFraction * 0.5 * std::hypot(geometry.windowWidth, geometry.windowHeight);
        if (fit.ok && bounded(q, geometry) &&
            quadraticCurvature(fit.warp, geometry.windowWidth, geometry.windowHeight) <= limit) {
            return infoFrom(q, fit, options.model, Fallback::None);
        }
    }
    // Affine: the model itself, or the first fallback.
    {
        const QuadraticFit fit = fitAffine(used);
        const Quadratic q = composeAffine(fit.warp, argument);
        if (fit.ok && bounded(q, geometry)) {
            return infoFrom(q, fit, options.model,
                            options.model == WarpModel::Affine ? Fallback::None : Fallback::Affine);
        }
    }
    // Rotation only: viewing directions of the control pixels, no parallax.
    if (poseOk) {
        std::array<Correspondence, 9> dirs;
        const std::size_t nd = rotationCorrespondences(frame, fieldPose, dirs);
        const std::span<const Correspondence> d(dirs.data(), nd);
        QuadraticFit fit = fitQuadratic(d);
        if (!fit.ok) fit = fitAffine(d);
        const Quadratic q = composeAffine(fit.warp, argument);
        if (fit.ok && bounded(q, geometry)) {
            return infoFrom(q, fit, options.model, Fallback::Rotation);
        }
    }
    // Hold the previous field's warp, or show the frame as it is.
    WarpInfo info;
    const bool previousOk =
        previous != nullptr &&
        (previous->projective ? std::all_of(previous->h.begin(), previous->h.end(),
                                            [](double e) { return std::isfinite(e); })
                              : quadraticOf(*previous).isFinite());
    if (previousOk) {
        info = *previous;
    } else {
        info = infoFrom(hold, FitResult{}, options.model, Fallback::Hold);
    }
    info.model = options.model;
    info.fallback = Fallback::Hold;
    info.rank = 0;
    info.pointsUsed = static_cast<int>(n);
    return info;
}

std::size_t checkCorrespondences(const ig::RenderedFrame& frame, const ig::Pose& fieldPose,
                                 const OutputGeometry& geometry,
                                 std::array<Correspondence, kCheckPointCount>& out) {
    if (!fieldPose.isFinite() || !frame.pose.isFinite()) return 0;
    const ig::Intrinsics& in = frame.intrinsics;
    if (frame.depth.size() !=
        static_cast<std::size_t>(in.width) * static_cast<std::size_t>(in.height)) {
        return 0;
    }
    const ig::Camera src(frame.pose, in);
    const ig::Camera cam(fieldPose, geometry.fieldWindow());
    const double sx = static_cast<double>(geometry.width) / geometry.windowWidth;
    const double sy = static_cast<double>(geometry.height) / geometry.windowHeight;
    std::size_t n = 0;
    for (int j = 0; j < kCheckGrid; ++j) {
        for (int i = 0; i < kCheckGrid; ++i) {
            const int x = in.margin + static_cast<int>((i + 0.5) * in.windowWidth() / kCheckGrid);
            const int y = in.margin + static_cast<int>((j + 0.5) * in.windowHeight() / kCheckGrid);
            const double d = frame.depth[static_cast<std::size_t>(y) * in.width + x];
            const glm::dvec2 pixel{x + 0.5, y + 0.5};
            const glm::dvec3 dir = glm::normalize(src.rayDirection(pixel.x, pixel.y));
            std::optional<glm::dvec2> q;
            if (std::isfinite(d) && d >= 0.0) {
                q = cam.project(frame.pose.position + d * dir, 1.0);
            } else if (d == std::numeric_limits<double>::infinity()) {
                q = cam.project(dir, 0.0);
            }
            if (!q || !finite(*q)) continue;
            out[n++] = {{q->x * sx, q->y * sy}, pixel};
        }
    }
    return n;
}

double warpCheckError(const WarpInfo& warp, std::span<const Correspondence> pairs) {
    double worst = 0.0;
    const Quadratic q = quadraticOf(warp);
    const Homography hm{warp.h};
    for (const Correspondence& c : pairs) {
        const glm::dvec2 p = warp.projective ? hm(c.field) : q(c.field);
        const double e = std::hypot(p.x - c.source.x, p.y - c.source.y);
        if (!std::isfinite(e)) return std::numeric_limits<double>::infinity();
        worst = std::max(worst, e);
    }
    return worst;
}

}  // namespace prp
