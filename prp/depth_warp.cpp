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
    p.kx = static_cast<float>(in.focal * sx);
    p.ky = static_cast<float>(in.focal * sy);
    p.invSx = static_cast<float>(1.0 / sx);
    p.invSy = static_cast<float>(1.0 / sy);
    p.outWidth = geometry.width;
    p.outHeight = geometry.height;
    return p;
}

namespace detail {

// The operations and their order are the AVX2 kernel's, lane for lane (this file and that one
// are compiled without floating-point contraction).
void projectRowScalar(const DepthProjection& p, const float* depth, int begin, int end, int y,
                      int firstLine, const ProjectedRow& out) {
    const float b = p.cy - (static_cast<float>(y) + 0.5f);
    const float bbff = b * b + p.f * p.f;
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
        const float len = std::sqrt(a * a + bbff);
        const bool terrain = d < kInf && d > -kInf;
        const bool sky = d == kInf;
        // The point is (d / len) (a, b, f) in the source camera (a direction for sky); scaled
        // by len / d it needs one division for both coordinates and, times len, the depth.
        const float dd = terrain ? d : 1.0f;
        const float r = dd * (p.m[0] * a + rowR) + (terrain ? p.t[0] * len : 0.0f);
        const float u = dd * (p.m[3] * a + rowU) + (terrain ? p.t[1] * len : 0.0f);
        const float wl = dd * (p.m[6] * a + rowW) + (terrain ? p.t[2] * len : 0.0f);
        const float inv = 1.0f / wl;
        const float zInv = len * inv;  // 1 / depth along the field camera's axis
        const float qx = p.ox + p.kx * (r * inv);
        const float qy = p.oy - p.ky * (u * inv);
        // The field line whose centre is nearest: each line stands for two output rows.
        const float line = (qy - lineOff) * 0.5f;
        const bool inside = (terrain || sky) && zInv > 0.0f && zInv < 1e6f && qx >= 0.0f &&
                            qx < ow && line >= 0.0f && line < lines;
        const std::int32_t ix = inside ? static_cast<std::int32_t>(qx) : 0;
        const std::int32_t iy = inside ? static_cast<std::int32_t>(line) : 0;
        out.index[x] = inside ? iy * p.outWidth + ix : -1;
        out.zInv[x] = terrain ? zInv : kSkyInverseDepth;
        out.sx[x] = (static_cast<float>(x) + 0.5f) + (static_cast<float>(ix) + 0.5f - qx) * p.invSx;
        out.sy[x] = yc + (static_cast<float>(2 * iy + firstLine) + 0.5f - qy) * p.invSy;
    }
}

}  // namespace detail

void DepthWarp::reserve(int frameWidth, int frameHeight, std::size_t fieldPixels) {
    const std::size_t row = static_cast<std::size_t>(
        std::ceil(std::hypot(static_cast<double>(frameWidth), static_cast<double>(frameHeight))));
    const std::size_t rowLength = std::max(rowIndex_.size(), row + 2);
    rowIndex_.resize(rowLength);
    rowZInv_.resize(rowLength);
    rowSx_.resize(rowLength);
    rowSy_.resize(rowLength);
    if (depth_.size() < fieldPixels) {
        depth_.resize(fieldPixels);
        pointX_.resize(fieldPixels);
        pointY_.resize(fieldPixels);
    }
}

DepthWarpResult DepthWarp::apply(const ig::RenderedFrame& frame, const ig::Rgb8* color,
                                 const ig::Pose& fieldPose, const OutputGeometry& geometry,
                                 const Quadratic& holeWarp, const FieldView& field, int gainQ8,
                                 bool agc, DepthKernel kernel) {
    const int w = frame.width(), h = frame.height();
    const std::size_t fieldPixels =
        static_cast<std::size_t>(field.width) * static_cast<std::size_t>(field.lines);
    depth_.assign(fieldPixels, kNoPoint);
    pointX_.resize(fieldPixels);
    pointY_.resize(fieldPixels);
    // Row buffers only grow (reserve() makes them as long as a frame's diagonal).
    if (rowIndex_.size() < static_cast<std::size_t>(w)) {
        rowIndex_.resize(static_cast<std::size_t>(w));
        rowZInv_.resize(rowIndex_.size());
        rowSx_.resize(rowIndex_.size());
        rowSy_.resize(rowIndex_.size());
    }

    const DepthProjection proj = DepthProjection::of(frame, fieldPose, geometry);
    const ProjectedRow row{rowIndex_.data(), rowZInv_.data(), rowSx_.data(), rowSy_.data()};
    bool avx2 = false;
#if VIG_PRP_HAVE_AVX2
    avx2 = kernel != DepthKernel::Scalar && cpuHasAvx2();
#else
    (void)kernel;
#endif
    float* __restrict zBuf = depth_.data();
    std::int32_t* __restrict px = pointX_.data();
    std::int32_t* __restrict py = pointY_.data();
    for (int y = 0; y < h; ++y) {
        const float* d = frame.depth.data() + static_cast<std::size_t>(y) * w;
#if VIG_PRP_HAVE_AVX2
        if (avx2) {
            projectRowAvx2(proj, d, w, y, field.firstLine, row);
        } else {
            projectRowScalar(proj, d, 0, w, y, field.firstLine, row);
        }
#else
        projectRowScalar(proj, d, 0, w, y, field.firstLine, row);
#endif
        // The z-test on inverse depths, in scan order (a tie keeps the first). Points become
        // the given points' 16.16 fixed point minus half a pixel (scaling a float by 2^16 is exact;
        // a landing point is within a pixel or two of its rendered pixel).
        for (int x = 0; x < w; ++x) {
            const std::int32_t o = row.index[x];
            if (o >= 0 && row.zInv[x] > zBuf[o]) {
                zBuf[o] = row.zInv[x];
                px[o] = static_cast<std::int32_t>(row.sx[x] * 0x1p16f) - kPointHalf;
                py[o] = static_cast<std::int32_t>(row.sy[x] * 0x1p16f) - kPointHalf;
            }
        }
    }

    // Holes: the farther of the line's two neighbours that has a point of its own (background
    // first) shifted by one output pixel, else the quadratic's point. Filled in place: a hole's
    // neighbours are read only where the z-buffer says they have their own point.
    DepthWarpResult result;
    const std::int32_t shift = static_cast<std::int32_t>(static_cast<double>(proj.invSx) * 0x1p16);
    // The quadratic's 32.32 points (bounded by kMaxSourceCoordinate = 2^20) to 16.16: the
    // same 8-bit weights; beyond 16.16's range they are outside the frame either way.
    constexpr std::int64_t kPointLimit = std::int64_t{1} << 46;
    const auto toPoint = [](std::int64_t v) {
        return static_cast<std::int32_t>(std::clamp(v, -kPointLimit, kPointLimit - 1) >>
                                         (kFracBits - kPointFracBits));
    };
    for (int line = 0; line < field.lines; ++line) {
        const std::size_t at = static_cast<std::size_t>(line) * field.width;
        const float* z = zBuf + at;
        std::int32_t* lx = px + at;
        std::int32_t* ly = py + at;
        // The quadratic by forward differences along the line, as its own kernel steps it.
        QuadraticRows q{holeWarp};
        q.start(field.firstLine + 2 * line + 0.5);
        for (int k = 0; k < field.width; ++k, q.next()) {
            if (z[k] != kNoPoint) continue;
            ++result.holes;
            const float left = k > 0 ? z[k - 1] : kNoPoint;
            const float right = k + 1 < field.width ? z[k + 1] : kNoPoint;
            if (left != kNoPoint && (right == kNoPoint || left <= right)) {
                lx[k] = lx[k - 1] + shift;
                ly[k] = ly[k - 1];
            } else if (right != kNoPoint) {
                lx[k] = lx[k + 1] - shift;
                ly[k] = ly[k + 1];
            } else {
                lx[k] = toPoint(q.x);
                ly[k] = toPoint(q.y);
            }
        }
    }
    const ApplyResult r =
        applyPoints({color, w, h}, px, py, static_cast<std::size_t>(field.width), field, gainQ8,
                    agc, kernel == DepthKernel::Scalar ? WarpKernel::Scalar : WarpKernel::Auto);
    result.edgeSamples = r.edgeSamples;
    result.lumaSum = r.lumaSum;
    return result;
}

}  // namespace prp
