// The depth model on a field's budget: a float forward splat with a z-test, holes from a quadratic.
#pragma once

#include "ig/camera.hpp"
#include "ig/frame.hpp"
#include "prp/warp_apply.hpp"
#include "prp/warp_fit.hpp"

#include <cstdint>
#include <vector>

namespace prp {

// Source-row projection kernel of the depth model. Both give the same bits (same float
// operations in the same order, no fused multiply-add); Auto takes AVX2 where the processor has it.
enum class DepthKernel { Auto, Scalar, Avx2 };
bool depthKernelSupported(DepthKernel kernel);

// Per-field constants taking a rendered pixel and its depth to an output-frame point, in float.
// A pixel (x, y) is the source-camera point (d / l) (a, b, f) with a = x + 0.5 - cx,
// b = cy - (y + 0.5), l = |(a, b, f)| and d its depth (sky: d = 1 and no translation: a
// direction). In the field's camera (roll included), scaled by l / d, it is
// (r, u, w) = d M (a, b, f) + l t; it lands at qx = ox + kx r / w, qy = oy - ky u / w (output
// pixels, full-frame lines), at inverse depth l / w along the field camera's axis.
struct DepthProjection {
    float cx = 0, cy = 0, f = 0;
    float m[9]{};  // row-major: rows are the field camera's right, up, forward in source axes
    float t[3]{};  // source eye minus field eye, in the field camera's axes
    float ox = 0, oy = 0, kx = 0, ky = 0;
    float invSx = 1, invSy = 1;  // window pixels per output pixel
    int outWidth = 0, outHeight = 0;

    static DepthProjection of(const ig::RenderedFrame& frame, const ig::Pose& fieldPose,
                              const OutputGeometry& geometry);
};

// Depth of sky splats in the double-precision reference: behind every terrain point.
inline constexpr float kSkySplat = 1e38f;
// Inverse depth of sky splats in the fast path: behind every terrain point.
inline constexpr float kSkyInverseDepth = 0.0f;

// One rendered row projected into one field: per pixel the field-buffer index it lands on
// (fieldLine * outWidth + x, the field line whose centre is nearest: each stands for two output
// rows; -1: off the output or behind the eye), its inverse depth along the field camera's axis
// (nearer is larger; kSkyInverseDepth for sky) and the source point that lands on that output
// pixel's centre (first order: the output scaling about the pixel).
struct ProjectedRow {
    std::int32_t* index;
    float* zInv;
    float* sx;
    float* sy;
};

namespace detail {
// Pixels [begin, end) of rendered row y (`depth` and `out` indexed from the row's start).
void projectRowScalar(const DepthProjection& p, const float* depth, int begin, int end, int y,
                      int firstLine, const ProjectedRow& out);
#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
// The same eight pixels at a time; needs AVX2.
void projectRowAvx2(const DepthProjection& p, const float* depth, int width, int y, int firstLine,
                    const ProjectedRow& out);
#endif
}  // namespace detail

struct DepthWarpResult {
    std::uint64_t edgeSamples = 0;  // samples outside the rendered frame (edge repeated)
    std::uint64_t lumaSum = 0;
    std::uint64_t holes = 0;  // output pixels no rendered pixel landed on (quadratic used)
};

// The depth model's fast path, with its scratch buffers (sized on first use, then reused).
class DepthWarp {
  public:
    // Splats every rendered pixel of `frame` (colour `color`, which may be a filtered copy)
    // into the lines of `field` by the field pose (roll included), nearest output pixel, nearer
    // points winning; each output pixel then samples bilinearly at the source point that lands
    // on its centre, and an output pixel no source pixel reached samples at `holeWarp`'s point.
    DepthWarpResult apply(const ig::RenderedFrame& frame, const ig::Rgb8* color,
                          const ig::Pose& fieldPose, const OutputGeometry& geometry,
                          const Quadratic& holeWarp, const FieldView& field, int gainQ8, bool agc,
                          DepthKernel kernel = DepthKernel::Auto);
    // Sizes the scratch buffers for frames like `frameWidth` x `frameHeight` (rows as long as
    // its diagonal: any roll the renderer widens the frame for) and fields of `fieldPixels`,
    // so a field that takes the depth warp first later allocates nothing.
    void reserve(int frameWidth, int frameHeight, std::size_t fieldPixels);

    // The points the last apply() sampled (field line L's pixel x at [L * field width + x];
    // 16.16 fixed point, as applyPoints takes them).
    const std::int32_t* pointsX() const { return pointX_.data(); }
    const std::int32_t* pointsY() const { return pointY_.data(); }

  private:
    std::vector<float> depth_;                   // one field: the z-buffer (inverse depths)
    std::vector<std::int32_t> pointX_, pointY_;  // one field: the points sampled (16.16)
    std::vector<std::int32_t> rowIndex_;         // one rendered row
    std::vector<float> rowZInv_, rowSx_, rowSy_;
};

}  // namespace prp
