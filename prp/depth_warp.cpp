#include "prp/depth_warp.hpp"

#include "prp/warp_apply_kernel.hpp"

#include <glm/geometric.hpp>

#include <algorithm>
#include <cmath>
#include <limits>

namespace prp {

using namespace detail;

namespace {

// An empty z-buffer entry of the fast path (inverse depths): behind sky and every point.
constexpr float kNoPoint = -1.0f;
constexpr float kInf = std::numeric_limits<float>::infinity();

}  // namespace

std::optional<DepthMethod> parseDepthMethod(const std::string& text) {
    if (text == "gather") return DepthMethod::Gather;
    if (text == "splat") return DepthMethod::Splat;
    return std::nullopt;
}

const char* depthMethodName(DepthMethod method) {
    return method == DepthMethod::Gather ? "gather" : "splat";
}

bool depthKernelSupported(DepthKernel kernel) {
    switch (kernel) {
        case DepthKernel::Auto:
        case DepthKernel::Scalar:
            return true;
        case DepthKernel::Avx2:
#if VIG_PRP_HAVE_AVX2
            return cpuHasAvx2();
#else
            return false;
#endif
    }
    return false;
}

DepthProjection DepthProjection::of(const ig::RenderedFrame& frame, const ig::Pose& fieldPose,
                                    const OutputGeometry& geometry) {
    DepthProjection p;
    const ig::Intrinsics& in = frame.intrinsics;
    const ig::CameraBasis src = ig::CameraBasis::fromPose(frame.pose);
    const ig::CameraBasis dst = ig::CameraBasis::fromPose(fieldPose);
    // Source camera axes (a along right, b along up, c along forward) in the field camera.
    const glm::dvec3 rows[3] = {dst.right, dst.up, dst.forward};
    const glm::dvec3 cols[3] = {src.right, src.up, src.forward};
    const glm::dvec3 offset = frame.pose.position - fieldPose.position;
    for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j)
            p.m[3 * i + j] = static_cast<float>(glm::dot(rows[i], cols[j]));
        p.t[i] = static_cast<float>(glm::dot(rows[i], offset));
    }
    p.cx = static_cast<float>(in.cx());
    p.cy = static_cast<float>(in.cy());
    p.f = static_cast<float>(in.focal);
    const double sx = static_cast<double>(geometry.width) / geometry.windowWidth;
    const double sy = static_cast<double>(geometry.height) / geometry.windowHeight;
    p.ox = static_cast<float>(0.5 * geometry.windowWidth * sx);
    p.oy = static_cast<float>(0.5 * geometry.windowHeight * sy);
    // Projected with the field's focal length; an output pixel spans zoom() / s rendered pixels.
    const double fieldFocal = geometry.focal > 0.0 ? geometry.focal : in.focal;
    const double k = geometry.zoom();
    p.kx = static_cast<float>(fieldFocal * sx);
    p.ky = static_cast<float>(fieldFocal * sy);
    p.j[0] = static_cast<float>(k / sx);
    p.j[3] = static_cast<float>(k / sy);
    p.outWidth = geometry.width;
    p.outHeight = geometry.height;
    return p;
}

DepthProjection DepthProjection::withJacobian(const Quadratic& q) const {
    // Q(X, Y) = c0 + c1 X + c2 Y + c3 X Y + c4 X^2 + c5 Y^2, at the output's centre.
    const double x = 0.5 * outWidth, y = 0.5 * outHeight;
    const auto dX = [&](const std::array<double, 6>& c) {
        return c[1] + c[3] * y + 2.0 * c[4] * x;
    };
    const auto dY = [&](const std::array<double, 6>& c) {
        return c[2] + c[3] * x + 2.0 * c[5] * y;
    };
    const double m[4] = {dX(q.a), dY(q.a), dX(q.b), dY(q.b)};
    DepthProjection p = *this;
    for (const double v : m) {
        if (!(std::abs(v) <= kMaxJacobian)) return p;
    }
    for (int i = 0; i < 4; ++i)
        p.j[i] = static_cast<float>(m[i]);
    return p;
}

namespace detail {

// The operations and their order are the AVX2 kernels', lane for lane (this file and that one
// are compiled without floating-point contraction).
void scaleDepthRowScalar(const DepthProjection& p, const float* depth, int begin, int end, int y,
                         float* scaled) {
    const float b = p.cy - (static_cast<float>(y) + 0.5f);
    const float bbff = b * b + p.f * p.f;
    const float aOff = 0.5f - p.cx;
    for (int x = begin; x < end; ++x) {
        const float d = depth[x];
        const float a = static_cast<float>(x) + aOff;
        const float len = std::sqrt(a * a + bbff);
        const bool terrain = d < kInf && d > -kInf;
        scaled[x] = (terrain ? d : 1.0f) / len;
    }
}

void projectRowScalar(const DepthProjection& p, const float* depth, const float* scaled, int begin,
                      int end, int y, int firstLine, const ProjectedRow& out) {
    const float b = p.cy - (static_cast<float>(y) + 0.5f);
    const float rowR = p.m[1] * b + p.m[2] * p.f;
    const float rowU = p.m[4] * b + p.m[5] * p.f;
    const float rowW = p.m[7] * b + p.m[8] * p.f;
    const float aOff = 0.5f - p.cx;
    const float yc = static_cast<float>(y) + 0.5f;
    const float ow = static_cast<float>(p.outWidth);
    const float lineOff = static_cast<float>(firstLine) - 0.5f;
    const float lines = static_cast<float>((p.outHeight - firstLine + 1) / 2);
    for (int x = begin; x < end; ++x) {
        const float d = depth[x];
        const float a = static_cast<float>(x) + aOff;
        const bool terrain = d < kInf && d > -kInf;
        const bool sky = d == kInf;
        // The point is s (a, b, f) in the source camera (sky: the unit direction); in the field
        // camera M s (a, b, f) + t (no translation for a direction): one division gives both
        // coordinates and the inverse depth along the field camera's axis.
        const float sc = scaled[x];
        const float r = sc * (p.m[0] * a + rowR) + (terrain ? p.t[0] : 0.0f);
        const float u = sc * (p.m[3] * a + rowU) + (terrain ? p.t[1] : 0.0f);
        const float w = sc * (p.m[6] * a + rowW) + (terrain ? p.t[2] : 0.0f);
        const float zInv = 1.0f / w;
        const float qx = p.ox + p.kx * (r * zInv);
        const float qy = p.oy - p.ky * (u * zInv);
        // The field line whose centre is nearest: each line stands for two output rows.
        const float line = (qy - lineOff) * 0.5f;
        const bool inside = (terrain || sky) && zInv > 0.0f && zInv < 1e6f && qx >= 0.0f &&
                            qx < ow && line >= 0.0f && line < lines;
        const std::int32_t ix = inside ? static_cast<std::int32_t>(qx) : 0;
        const std::int32_t iy = inside ? static_cast<std::int32_t>(line) : 0;
        out.index[x] = inside ? iy * p.outWidth + ix : -1;
        out.zInv[x] = terrain ? zInv : kSkyInverseDepth;
        // From the landing point to its output pixel's centre, taken back to the frame.
        const float dx = static_cast<float>(ix) + 0.5f - qx;
        const float dy = static_cast<float>(2 * iy + firstLine) + 0.5f - qy;
        out.sx[x] = (static_cast<float>(x) + 0.5f) + (p.j[0] * dx + p.j[1] * dy);
        out.sy[x] = yc + (p.j[2] * dx + p.j[3] * dy);
    }
}

// Max and min as the vector instructions compute them: the second operand when either is NaN.
inline float maxLikeVector(float a, float b) {
    return a > b ? a : b;
}
inline float minLikeVector(float a, float b) {
    return a < b ? a : b;
}

// The operations and their order are the AVX2 kernel's, lane for lane.
int gatherLineScalar(const DepthProjection& p, const GatherLine& l, const float* depth, int width,
                     int height, int begin, int end, std::int32_t* px, std::int32_t* py,
                     std::uint8_t* unsettled, float* distOut) {
    const float ff = p.f * p.f;
    const float m2f = p.m[2] * p.f, m5f = p.m[5] * p.f, m8f = p.m[8] * p.f;
    const float xMax = static_cast<float>(width - 1), yMax = static_cast<float>(height - 1);
    const float parallax = gatherParallaxScale(p);
    int count = 0;
    for (int x = begin; x < end; ++x) {
        const float qx = static_cast<float>(x) + 0.5f;
        float sx = l.x0 + qx * (l.x1 + qx * l.x2);
        float sy = l.y0 + qx * (l.y1 + qx * l.y2);
        const float jxx = l.x1 + qx * l.x2x2, jxy = l.xy0 + qx * l.xy1;
        const float jyx = l.y1 + qx * l.y2x2, jyy = l.yy0 + qx * l.yy1;
        bool valid = true;
        float distFirst = 0.0f, dist = 0.0f, dMin = 0.0f, dMax = 0.0f, rx = 0.0f, ry = 0.0f;
        for (int step = 0; step < kGatherSteps; ++step) {
            if (step == 0) {
                // The first step: the depth of the rendered pixel that contains the point
                // (clamped to the frame; NaN to 0).
                const std::int32_t ix =
                    static_cast<std::int32_t>(minLikeVector(maxLikeVector(sx, 0.0f), xMax));
                const std::int32_t iy =
                    static_cast<std::int32_t>(minLikeVector(maxLikeVector(sy, 0.0f), yMax));
                const float g = depth[iy * width + ix];
                // Terrain or sky (+inf); NaN, zero and negative depths are not.
                valid = valid && g > 0.0f;
                // Sky as a far point: its parallax is below any float's resolution there.
                dist = minLikeVector(g, kGatherFar);
                distFirst = dist;
            } else {
                // Later steps: bilinear between the four rendered pixel centres around it.
                const float fx = minLikeVector(maxLikeVector(sx - 0.5f, 0.0f), xMax);
                const float fy = minLikeVector(maxLikeVector(sy - 0.5f, 0.0f), yMax);
                const std::int32_t ix = std::min(static_cast<std::int32_t>(fx), width - 2);
                const std::int32_t iy = std::min(static_cast<std::int32_t>(fy), height - 2);
                const float wx = fx - static_cast<float>(ix), wy = fy - static_cast<float>(iy);
                const float* t = depth + (iy * width + ix);
                valid =
                    valid && t[0] > 0.0f && t[1] > 0.0f && t[width] > 0.0f && t[width + 1] > 0.0f;
                const float d00 = minLikeVector(t[0], kGatherFar);
                const float d01 = minLikeVector(t[1], kGatherFar);
                const float d10 = minLikeVector(t[width], kGatherFar);
                const float d11 = minLikeVector(t[width + 1], kGatherFar);
                const float top = d00 + wx * (d01 - d00);
                const float bottom = d10 + wx * (d11 - d10);
                dist = top + wy * (bottom - top);
                dMin = minLikeVector(minLikeVector(d00, d01), minLikeVector(d10, d11));
                dMax = maxLikeVector(maxLikeVector(d00, d01), maxLikeVector(d10, d11));
            }
            // The point (dist / len) (a, b, f), scaled by len / dist: one division for both
            // coordinates, as the splat's projection.
            const float a = sx - p.cx;
            const float b = p.cy - sy;
            const float len = std::sqrt((a * a + b * b) + ff);
            const float r = dist * ((p.m[0] * a + p.m[1] * b) + m2f) + len * p.t[0];
            const float u = dist * ((p.m[3] * a + p.m[4] * b) + m5f) + len * p.t[1];
            const float w = dist * ((p.m[6] * a + p.m[7] * b) + m8f) + len * p.t[2];
            valid = valid && w > 0.0f;
            const float inv = 1.0f / w;
            rx = qx - (p.ox + p.kx * (r * inv));
            ry = l.row - (p.oy - p.ky * (u * inv));
            sx = sx + (jxx * rx + jxy * ry);
            sy = sy + (jyx * rx + jyy * ry);
        }
        const bool settled = valid && std::fabs(rx) <= kGatherSettledPx &&
                             std::fabs(ry) <= kGatherSettledPx &&
                             // 1 / dMin - 1 / dMax and 1 / distFirst - 1 / dist, without dividing.
                             (dMax - dMin) * parallax <= kGatherEdgePx * (dMin * dMax) &&
                             !((dist - distFirst) * parallax > kGatherEdgePx * (distFirst * dist));
        const float cx = minLikeVector(maxLikeVector(sx, -16384.0f), 16384.0f);
        const float cy = minLikeVector(maxLikeVector(sy, -16384.0f), 16384.0f);
        px[x] = static_cast<std::int32_t>(cx * 0x1p16f) - kPointHalf;
        py[x] = static_cast<std::int32_t>(cy * 0x1p16f) - kPointHalf;
        unsettled[x] = settled ? 0 : 1;
        distOut[x] = dist;
        count += settled ? 0 : 1;
    }
    return count;
}

}  // namespace detail

float gatherParallaxScale(const DepthProjection& p) {
    const float t = std::sqrt((p.t[0] * p.t[0] + p.t[1] * p.t[1]) + p.t[2] * p.t[2]);
    return t * std::max(p.kx, p.ky);
}

GatherLine GatherLine::of(const Quadratic& q, double row) {
    // Q(X, Y) = c0 + c1 X + c2 Y + c3 X Y + c4 X^2 + c5 Y^2 at Y = row.
    GatherLine l;
    l.row = static_cast<float>(row);
    const auto along = [row](const std::array<double, 6>& c, float& v0, float& v1, float& v2,
                             float& v2x2, float& vy0, float& vy1) {
        v0 = static_cast<float>(c[0] + c[2] * row + c[5] * row * row);
        v1 = static_cast<float>(c[1] + c[3] * row);
        v2 = static_cast<float>(c[4]);
        v2x2 = static_cast<float>(2.0 * c[4]);
        vy0 = static_cast<float>(c[2] + 2.0 * c[5] * row);
        vy1 = static_cast<float>(c[3]);
    };
    along(q.a, l.x0, l.x1, l.x2, l.x2x2, l.xy0, l.xy1);
    along(q.b, l.y0, l.y1, l.y2, l.y2x2, l.yy0, l.yy1);
    return l;
}

std::size_t rolledFrameDiagonal(int width, int height) {
    return static_cast<std::size_t>(
        std::ceil(std::hypot(static_cast<double>(width), static_cast<double>(height))));
}

void DepthWarp::reserve(int frameWidth, int frameHeight, std::size_t fieldPixels) {
    const std::size_t row = rolledFrameDiagonal(frameWidth, frameHeight);
    // Room from the first frame on for the frames widened for any roll (rolledFrameRoomPixels),
    // grown only when a frame needs more than there is: growing on a frame's diagonal instead
    // reallocated (and copied) the scaled depths on the field thread at 48 degrees of bank, 11 ms
    // of a 16.7 ms field.
    if (rowIndex_.size() < row + 2) {
        const std::size_t rowLength = 2 * row + 2;
        rowIndex_.resize(rowLength);
        rowZInv_.resize(rowLength);
        rowSx_.resize(rowLength);
        rowSy_.resize(rowLength);
    }
    const std::size_t pixels =
        static_cast<std::size_t>(frameWidth) * static_cast<std::size_t>(frameHeight);
    if (pixels > scaled_.capacity()) {
        scaled_.reserve(std::max(pixels, rolledFrameRoomPixels(frameWidth, frameHeight)));
    }
    if (depth_.size() < fieldPixels) {
        depth_.resize(fieldPixels);
        pointX_.resize(fieldPixels);
        pointY_.resize(fieldPixels);
        unsettled_.resize(fieldPixels);
        gatherDist_.resize(fieldPixels);
    }
    // ceil(W / w) ceil(L / l) <= W L / (w l) + W / w + L / l + 1 <= W L (1 / (w l) + 1 / w + 1 / l)
    // + 1.
    const std::size_t tiles = fieldPixels / (kGatherTileWidth * kGatherTileLines) +
                              fieldPixels / kGatherTileWidth + fieldPixels / kGatherTileLines + 1;
    if (tileUnsettled_.size() < tiles) tileUnsettled_.resize(tiles);
}

bool DepthWarp::useAvx2(DepthKernel kernel) const {
#if VIG_PRP_HAVE_AVX2
    return kernel != DepthKernel::Scalar && cpuHasAvx2();
#else
    (void)kernel;
    return false;
#endif
}

const float* DepthWarp::scaledDepth(const ig::RenderedFrame& frame, const DepthProjection& p,
                                    bool avx2) {
    const int w = frame.width(), h = frame.height();
    if (scaledFrom_ == frame.depth.data() && scaledSequence_ == frame.sequence &&
        scaledWidth_ == w && scaledHeight_ == h && scaledCx_ == p.cx && scaledCy_ == p.cy &&
        scaledF_ == p.f) {
        return scaled_.data();
    }
    scaled_.resize(static_cast<std::size_t>(w) * static_cast<std::size_t>(h));
    for (int y = 0; y < h; ++y) {
        const std::size_t at = static_cast<std::size_t>(y) * w;
#if VIG_PRP_HAVE_AVX2
        if (avx2) {
            scaleDepthRowAvx2(p, frame.depth.data() + at, 0, w, y, scaled_.data() + at);
            continue;
        }
#else
        (void)avx2;
#endif
        scaleDepthRowScalar(p, frame.depth.data() + at, 0, w, y, scaled_.data() + at);
    }
    scaledFrom_ = frame.depth.data();
    scaledSequence_ = frame.sequence;
    scaledWidth_ = w;
    scaledHeight_ = h;
    scaledCx_ = p.cx;
    scaledCy_ = p.cy;
    scaledF_ = p.f;
    return scaled_.data();
}

void DepthWarp::prepareFrame(const ig::RenderedFrame& frame, DepthKernel kernel) {
    if (frame.depth.size() != static_cast<std::size_t>(frame.width()) * frame.height()) return;
    // What scaleDepthRow reads of the projection: the frame's own centre and focal length, as
    // DepthProjection::of sets them.
    DepthProjection p;
    p.cx = static_cast<float>(frame.intrinsics.cx());
    p.cy = static_cast<float>(frame.intrinsics.cy());
    p.f = static_cast<float>(frame.intrinsics.focal);
    scaledDepth(frame, p, useAvx2(kernel));
    touchRoom(scaled_);  // what lies past the frame's depths is never read
}

void DepthWarp::splatRows(const DepthProjection& proj, const ig::RenderedFrame& frame,
                          int firstLine, int fieldWidth, int y0, int y1, int x0, int x1, bool clip,
                          int l0, int l1, int c0, int c1, bool avx2) {
    const int w = frame.width();
    const ProjectedRow row{rowIndex_.data(), rowZInv_.data(), rowSx_.data(), rowSy_.data()};
    float* __restrict zBuf = depth_.data();
    std::int32_t* __restrict px = pointX_.data();
    std::int32_t* __restrict py = pointY_.data();
    const float* scaled = scaledDepth(frame, proj, avx2);
    for (int y = y0; y < y1; ++y) {
        const std::size_t at = static_cast<std::size_t>(y) * w;
        const float* d = frame.depth.data() + at;
#if VIG_PRP_HAVE_AVX2
        if (avx2) {
            projectRowAvx2(proj, d, scaled + at, x0, x1, y, firstLine, row);
        } else {
            projectRowScalar(proj, d, scaled + at, x0, x1, y, firstLine, row);
        }
#else
        (void)avx2;
        projectRowScalar(proj, d, scaled + at, x0, x1, y, firstLine, row);
#endif
        // The z-test on inverse depths, in scan order (a tie keeps the first). Points become
        // the given points' 16.16 fixed point minus half a pixel (scaling a float by 2^16 is
        // exact; a landing point is within a pixel or two of its rendered pixel).
        for (int x = x0; x < x1; ++x) {
            const std::int32_t o = row.index[x];
            if (o < 0) continue;
            if (clip) {
                const int line = o / fieldWidth, col = o - line * fieldWidth;
                if (line < l0 || line >= l1 || col < c0 || col >= c1) continue;
            }
            if (row.zInv[x] > zBuf[o]) {
                zBuf[o] = row.zInv[x];
                px[o] = static_cast<std::int32_t>(row.sx[x] * 0x1p16f) - kPointHalf;
                py[o] = static_cast<std::int32_t>(row.sy[x] * 0x1p16f) - kPointHalf;
            }
        }
    }
}

std::uint64_t DepthWarp::fillHoles(const DepthProjection& proj, const Quadratic& holeWarp,
                                   const FieldView& field, int l0, int l1, int c0, int c1) {
    // Holes: the farther of the line's two neighbours that has a point of its own (background
    // first) moved by one output pixel (taken back to the frame by the Jacobian), else the
    // quadratic's point. Filled in place: a hole's neighbours are read only where the z-buffer
    // says they have their own point.
    std::uint64_t holes = 0;
    const std::int32_t shiftX = static_cast<std::int32_t>(static_cast<double>(proj.j[0]) * 0x1p16);
    const std::int32_t shiftY = static_cast<std::int32_t>(static_cast<double>(proj.j[2]) * 0x1p16);
    // The quadratic's 32.32 points (bounded by kMaxSourceCoordinate = 2^20) to 16.16: the
    // same 8-bit weights; beyond 16.16's range they are outside the frame either way.
    constexpr std::int64_t kPointLimit = std::int64_t{1} << 46;
    const auto toPoint = [](std::int64_t v) {
        return static_cast<std::int32_t>(std::clamp(v, -kPointLimit, kPointLimit - 1) >>
                                         (kFracBits - kPointFracBits));
    };
    for (int line = l0; line < l1; ++line) {
        const std::size_t at = static_cast<std::size_t>(line) * field.width;
        const float* z = depth_.data() + at;
        std::int32_t* lx = pointX_.data() + at;
        std::int32_t* ly = pointY_.data() + at;
        // The quadratic by forward differences along the line, as its own kernel steps it.
        QuadraticRows q{holeWarp};
        q.start(field.firstLine + 2 * line + 0.5);
        for (int k = 0; k < c0; ++k)
            q.next();
        for (int k = c0; k < c1; ++k, q.next()) {
            if (z[k] != kNoPoint) continue;
            ++holes;
            const float left = k > c0 ? z[k - 1] : kNoPoint;
            const float right = k + 1 < c1 ? z[k + 1] : kNoPoint;
            if (left != kNoPoint && (right == kNoPoint || left <= right)) {
                lx[k] = lx[k - 1] + shiftX;
                ly[k] = ly[k - 1] + shiftY;
            } else if (right != kNoPoint) {
                lx[k] = lx[k + 1] - shiftX;
                ly[k] = ly[k + 1] - shiftY;
            } else {
                lx[k] = toPoint(q.x);
                ly[k] = toPoint(q.y);
            }
        }
    }
    return holes;
}

std::uint64_t DepthWarp::splatTile(const DepthProjection& proj, const ig::RenderedFrame& frame,
                                   const Quadratic& holeWarp, const FieldView& field, int l0,
                                   int l1, int c0, int c1, bool avx2) {
    // The rendered pixels that may land in the tile: around the points of its settled pixels
    // and the quadratic's points of all of them, widened by the largest correction the steps
    // made to the quadratic there (parallax) and two pixels.
    double minX = std::numeric_limits<double>::infinity(), maxX = -minX, minY = minX, maxY = -minX;
    double correction = 0.0;
    bool anySettled = false;
    for (int line = l0; line < l1; ++line) {
        const std::size_t at = static_cast<std::size_t>(line) * field.width;
        const double row = field.firstLine + 2 * line + 0.5;
        for (int k = c0; k < c1; ++k) {
            const glm::dvec2 s = holeWarp({k + 0.5, row});
            if (!(std::isfinite(s.x) && std::isfinite(s.y))) continue;
            minX = std::min(minX, s.x);
            maxX = std::max(maxX, s.x);
            minY = std::min(minY, s.y);
            maxY = std::max(maxY, s.y);
            if (unsettled_[at + k] != 0) continue;
            const double gx = (pointX_[at + k] + kPointHalf) * 0x1p-16;
            const double gy = (pointY_[at + k] + kPointHalf) * 0x1p-16;
            minX = std::min(minX, gx);
            maxX = std::max(maxX, gx);
            minY = std::min(minY, gy);
            maxY = std::max(maxY, gy);
            correction = std::max({correction, std::abs(gx - s.x), std::abs(gy - s.y)});
            anySettled = true;
        }
    }
    // Without a settled pixel nothing says how far the points are from the quadratic's.
    const double margin = 2.0 + (anySettled ? correction : 16.0);
    const auto clampTo = [](double v, int hi) {
        return static_cast<int>(std::clamp(v, 0.0, static_cast<double>(hi)));
    };
    const int x0 = clampTo(std::floor(minX - margin), frame.width());
    const int x1 = clampTo(std::ceil(maxX + margin) + 1.0, frame.width());
    const int y0 = clampTo(std::floor(minY - margin), frame.height());
    const int y1 = clampTo(std::ceil(maxY + margin) + 1.0, frame.height());
    for (int line = l0; line < l1; ++line) {
        float* z = depth_.data() + static_cast<std::size_t>(line) * field.width;
        std::fill(z + c0, z + c1, kNoPoint);
    }
    if (x0 < x1 && y0 < y1) {
        splatRows(proj, frame, field.firstLine, field.width, y0, y1, x0, x1, true, l0, l1, c0, c1,
                  avx2);
    }
    return fillHoles(proj, holeWarp, field, l0, l1, c0, c1);
}

void DepthWarp::markDepthJumps(const DepthProjection& proj, const FieldView& field, int tilesAcross,
                               int tilesDown) {
    // Neighbouring output pixels whose settled depths land more than kGatherJumpPx apart by
    // parallax (|1 / d1 - 1 / d2| P > E, as (|d1 - d2| P > E d1 d2) without dividing) straddle a
    // depth edge: beside it a pixel may have settled on a surface that a nearer one hides. The
    // tiles around the edge, as far as that parallax reaches, take the splat.
    const float parallax = gatherParallaxScale(proj);
    const float* dist = gatherDist_.data();
    std::uint16_t* tiles = tileUnsettled_.data();
    const auto mark = [&](int line, int x, float d1, float d2) {
        const double reach =
            std::min(std::abs(1.0 / d1 - 1.0 / d2) * parallax, 4.0 * kGatherTileWidth) + 1.0;
        const int t0 = std::max(0, static_cast<int>((x - reach) / kGatherTileWidth));
        const int t1 = std::min(tilesAcross - 1, static_cast<int>((x + reach) / kGatherTileWidth));
        const int b0 = std::max(0, static_cast<int>((line - 0.5 * reach) / kGatherTileLines));
        const int b1 =
            std::min(tilesDown - 1, static_cast<int>((line + 0.5 * reach) / kGatherTileLines));
        for (int b = b0; b <= b1; ++b) {
            for (int t = t0; t <= t1; ++t) {
                std::uint16_t& n = tiles[static_cast<std::size_t>(b) * tilesAcross + t];
                n = std::max<std::uint16_t>(n, 1);
            }
        }
    };
    const auto jump = [parallax](float d1, float d2) {
        return std::abs(d1 - d2) * parallax > kGatherJumpPx * (d1 * d2);
    };
    for (int line = 0; line < field.lines; ++line) {
        const float* row = dist + static_cast<std::size_t>(line) * field.width;
        const float* above = line > 0 ? row - field.width : nullptr;
        for (int x = 0; x < field.width; ++x) {
            if (x > 0 && jump(row[x], row[x - 1])) mark(line, x, row[x], row[x - 1]);
            if (above != nullptr && jump(row[x], above[x])) mark(line, x, row[x], above[x]);
        }
    }
}

DepthWarpResult DepthWarp::apply(const ig::RenderedFrame& frame, const ig::Rgb8* color,
                                 const ig::Pose& fieldPose, const OutputGeometry& geometry,
                                 const Quadratic& holeWarp, const FieldView& field, int gainQ8,
                                 bool agc, DepthKernel kernel, DepthMethod method,
                                 std::chrono::steady_clock::time_point giveUpAt) {
    const int w = frame.width(), h = frame.height();
    const std::size_t fieldPixels =
        static_cast<std::size_t>(field.width) * static_cast<std::size_t>(field.lines);
    reserve(0, 0, fieldPixels);  // sized already when the processor reserved
    // Row buffers only grow (reserve() makes them as long as a frame's diagonal).
    if (rowIndex_.size() < static_cast<std::size_t>(w)) {
        rowIndex_.resize(static_cast<std::size_t>(w));
        rowZInv_.resize(rowIndex_.size());
        rowSx_.resize(rowIndex_.size());
        rowSy_.resize(rowIndex_.size());
    }
    const DepthProjection proj =
        DepthProjection::of(frame, fieldPose, geometry).withJacobian(holeWarp);
    const bool avx2 = useAvx2(kernel);
    DepthWarpResult result;
    const bool deadline = giveUpAt != std::chrono::steady_clock::time_point::max();
    const auto late = [&] {
        if (!deadline || std::chrono::steady_clock::now() <= giveUpAt) return false;
        result = DepthWarpResult{};
        result.abandoned = true;
        return true;
    };

    // The gather's bilinear taps need two rendered pixels each way.
    bool splatAll = method == DepthMethod::Splat || w < 2 || h < 2;
    if (!splatAll) {
        // The gather, tile by tile; count the pixels that did not settle per tile.
        const int tilesAcross = (field.width + kGatherTileWidth - 1) / kGatherTileWidth;
        const int tilesDown = (field.lines + kGatherTileLines - 1) / kGatherTileLines;
        std::uint16_t* tiles = tileUnsettled_.data();
        std::fill(tiles, tiles + static_cast<std::size_t>(tilesAcross) * tilesDown, 0);
        for (int line = 0; line < field.lines; ++line) {
            if (line % kCheckRows == kCheckRows - 1 && late()) return result;
            const std::size_t at = static_cast<std::size_t>(line) * field.width;
            const GatherLine gl = GatherLine::of(holeWarp, field.firstLine + 2 * line + 0.5);
            std::uint16_t* band = tiles + static_cast<std::size_t>(line / kGatherTileLines) *
                                              static_cast<std::size_t>(tilesAcross);
            for (int t = 0; t < tilesAcross; ++t) {
                const int c0 = t * kGatherTileWidth;
                const int c1 = std::min(field.width, c0 + kGatherTileWidth);
                int n = 0;
#if VIG_PRP_HAVE_AVX2
                if (avx2) {
                    n = gatherLineAvx2(proj, gl, frame.depth.data(), w, h, c0, c1,
                                       pointX_.data() + at, pointY_.data() + at,
                                       unsettled_.data() + at, gatherDist_.data() + at);
                } else {
                    n = gatherLineScalar(proj, gl, frame.depth.data(), w, h, c0, c1,
                                         pointX_.data() + at, pointY_.data() + at,
                                         unsettled_.data() + at, gatherDist_.data() + at);
                }
#else
                n = gatherLineScalar(proj, gl, frame.depth.data(), w, h, c0, c1,
                                     pointX_.data() + at, pointY_.data() + at,
                                     unsettled_.data() + at, gatherDist_.data() + at);
#endif
                band[t] = static_cast<std::uint16_t>(band[t] + n);
                result.unsettled += static_cast<std::uint64_t>(n);
            }
        }
        markDepthJumps(proj, field, tilesAcross, tilesDown);
        std::size_t splatTiles = 0;
        for (std::size_t i = 0; i < static_cast<std::size_t>(tilesAcross) * tilesDown; ++i)
            splatTiles += tiles[i] != 0 ? 1 : 0;
        if (splatTiles > kGatherMaxSplatShare * static_cast<double>(tilesAcross) * tilesDown) {
            splatAll = true;
        } else {
            for (int ty = 0; ty < tilesDown; ++ty) {
                if (late()) return result;
                for (int tx = 0; tx < tilesAcross; ++tx) {
                    if (tiles[static_cast<std::size_t>(ty) * tilesAcross + tx] == 0) continue;
                    const int l0 = ty * kGatherTileLines;
                    const int l1 = std::min(field.lines, l0 + kGatherTileLines);
                    const int c0 = tx * kGatherTileWidth;
                    const int c1 = std::min(field.width, c0 + kGatherTileWidth);
                    result.holes += splatTile(proj, frame, holeWarp, field, l0, l1, c0, c1, avx2);
                    result.splatPixels += static_cast<std::uint64_t>(l1 - l0) * (c1 - c0);
                }
            }
        }
    }
    if (splatAll) {
        std::fill(depth_.begin(), depth_.begin() + static_cast<std::ptrdiff_t>(fieldPixels),
                  kNoPoint);
        // Row after row as at once (the z-test keeps the same points in the same order).
        for (int y = 0; y < h; y += kCheckRows) {
            if (late()) return result;
            splatRows(proj, frame, field.firstLine, field.width, y, std::min(h, y + kCheckRows), 0,
                      w, false, 0, 0, 0, 0, avx2);
        }
        if (late()) return result;
        result.holes = fillHoles(proj, holeWarp, field, 0, field.lines, 0, field.width);
        result.splatPixels = fieldPixels;
    }
    if (late()) return result;
    const auto committed = std::chrono::steady_clock::now();
    const ApplyResult r = applyPoints(
        {color, w, h}, pointX_.data(), pointY_.data(), static_cast<std::size_t>(field.width), field,
        gainQ8, agc, kernel == DepthKernel::Scalar ? WarpKernel::Scalar : WarpKernel::Auto);
    result.edgeSamples = r.edgeSamples;
    result.lumaSum = r.lumaSum;
    result.tailSeconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - committed).count();
    return result;
}

}  // namespace prp
