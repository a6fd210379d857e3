#include "ig/slope_bound.hpp"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <limits>

namespace ig {

namespace {

void blockGeometry(const TerrainMap& map, int& blocksX, int& blocksY, double& metresX,
                   double& metresY) {
    blocksX = SlopeBlocks::blocksAlong(map.width());
    blocksY = SlopeBlocks::blocksAlong(map.height());
    metresX = SlopeBlocks::kBlock * map.spacingX();
    metresY = SlopeBlocks::kBlock * map.spacingY();
}

}  // namespace

float SlopeBlocks::boundOf(int dx, int dy, double sx, double sy) {
    const double gx = dx * sx, gy = dy * sy;
    const double g = std::sqrt(gx * gx + gy * gy);
    float f = static_cast<float>(g);
    if (f < g) f = std::nextafter(f, std::numeric_limits<float>::infinity());
    return f;
}

SlopeBlocks::SlopeBlocks(const TerrainMap& map, const float* bounds) : bound_(bounds) {
    blockGeometry(map, blocksX_, blocksY_, blockMetresX_, blockMetresY_);
    invBlockX_ = 1.0 / blockMetresX_;
    invBlockY_ = 1.0 / blockMetresY_;
}

SlopeBlocks::SlopeBlocks(const TerrainMap& map) {
    blockGeometry(map, blocksX_, blocksY_, blockMetresX_, blockMetresY_);
    invBlockX_ = 1.0 / blockMetresX_;
    invBlockY_ = 1.0 / blockMetresY_;
    // Per block, as TerrainMap's global bound: the largest sample differences.
    std::vector<int> dx(static_cast<std::size_t>(blocksX_) * blocksY_, 0), dy(dx.size(), 0);
    for (int cy = 0; cy + 1 < map.height(); ++cy) {
        const int by = cy / kBlock;
        for (int cx = 0; cx + 1 < map.width(); ++cx) {
            const int h00 = map.raw(cx, cy), h10 = map.raw(cx + 1, cy);
            const int h01 = map.raw(cx, cy + 1), h11 = map.raw(cx + 1, cy + 1);
            const std::size_t b = static_cast<std::size_t>(by) * blocksX_ + cx / kBlock;
            dx[b] = std::max({dx[b], std::abs(h10 - h00), std::abs(h11 - h01)});
            dy[b] = std::max({dy[b], std::abs(h01 - h00), std::abs(h11 - h10)});
        }
    }
    owned_.resize(dx.size());
    const double sx = std::abs(map.heightScale()) / map.spacingX();
    const double sy = std::abs(map.heightScale()) / map.spacingY();
    for (std::size_t k = 0; k < owned_.size(); ++k)
        owned_[k] = boundOf(dx[k], dy[k], sx, sy);
    bound_ = owned_.data();
}

double SlopeBlocks::at(double x, double y) const {
    const double fx = std::clamp(x * invBlockX_, 0.0, blocksX_ - 1.0);
    const double fy = std::clamp(y * invBlockY_, 0.0, blocksY_ - 1.0);
    return bound_[static_cast<std::size_t>(fy) * blocksX_ + static_cast<std::size_t>(fx)];
}

double SlopeBlocks::maxOver(double x0, double y0, double x1, double y1) const {
    const int bx0 = static_cast<int>(std::clamp(x0 * invBlockX_, 0.0, blocksX_ - 1.0));
    const int bx1 = static_cast<int>(std::clamp(x1 * invBlockX_, 0.0, blocksX_ - 1.0));
    const int by0 = static_cast<int>(std::clamp(y0 * invBlockY_, 0.0, blocksY_ - 1.0));
    const int by1 = static_cast<int>(std::clamp(y1 * invBlockY_, 0.0, blocksY_ - 1.0));
    float m = 0.0f;
    for (int by = by0; by <= by1; ++by) {
        const float* row = bound_ + static_cast<std::size_t>(by) * blocksX_;
        for (int bx = bx0; bx <= bx1; ++bx)
            m = std::max(m, row[bx]);
    }
    return m;
}

void WedgeSlope::reset(const SlopeBlocks* blocks, glm::dvec2 eye, glm::dvec2 a, glm::dvec2 b,
                       double reach, double globalBound) {
    global_ = globalBound;
    filled_ = 0;
    blocks_ = nullptr;
    const double la = std::hypot(a.x, a.y), lb = std::hypot(b.x, b.y);
    // The directions between a and b (linear in the row) sweep the shorter arc from a to b
    // when that arc is under a right angle.
    if (!blocks || !(la > 0.0) || !(lb > 0.0) || !(a.x * b.x + a.y * b.y > 0.0) || !(reach > 0.0) ||
        !std::isfinite(reach)) {
        return;
    }
    blocks_ = blocks;
    eye_ = eye;
    const glm::dvec2 ua = a / la, ub = b / lb;
    const glm::dvec2 mid = ua + ub;
    axis_ = mid / std::hypot(mid.x, mid.y);
    // Half the wedge's width per unit along the bisector: tan of the half angle.
    const double halfTan =
        std::abs(ua.x * axis_.y - ua.y * axis_.x) / (ua.x * axis_.x + ua.y * axis_.y);
    side_ = glm::dvec2{-axis_.y, axis_.x} * halfTan;
    piece_ = std::min(blocks->blockMetresX(), blocks->blockMetresY());
    step_ = std::max(piece_, reach / kRings);
    invStep_ = 1.0 / step_;
}

void WedgeSlope::fill(int last) {
    const int slices = static_cast<int>(std::ceil(step_ / piece_));
    for (; filled_ <= last; ++filled_) {
        double m = filled_ > 0 ? profile_[filled_ - 1] : 0.0;
        for (int k = 0; k < slices; ++k) {
            // The slice between p0 and p1 along the bisector, in pieces across.
            const double p0 = filled_ * step_ + step_ * k / slices;
            const double p1 = filled_ * step_ + step_ * (k + 1) / slices;
            const glm::dvec2 c0 = eye_ + p0 * axis_, c1 = eye_ + p1 * axis_;
            const glm::dvec2 h0 = p0 * side_, h1 = p1 * side_;
            const double width = 2.0 * p1 * std::hypot(side_.x, side_.y);
            const int pieces = std::max(1, static_cast<int>(std::ceil(width / piece_)));
            for (int j = 0; j < pieces; ++j) {
                const double t0 = -1.0 + 2.0 * j / pieces, t1 = -1.0 + 2.0 * (j + 1) / pieces;
                const glm::dvec2 q[4] = {c0 + t0 * h0, c0 + t1 * h0, c1 + t0 * h1, c1 + t1 * h1};
                double x0 = q[0].x, x1 = q[0].x, y0 = q[0].y, y1 = q[0].y;
                for (const glm::dvec2& v : q) {
                    x0 = std::min(x0, v.x);
                    x1 = std::max(x1, v.x);
                    y0 = std::min(y0, v.y);
                    y1 = std::max(y1, v.y);
                }
                // A hundredth of a block more on every side against rounding at block edges.
                const double pad = 0.01 * piece_;
                m = std::max(m, blocks_->maxOver(x0 - pad, y0 - pad, x1 + pad, y1 + pad));
            }
        }
        profile_[filled_] = m;
    }
}

}  // namespace ig
