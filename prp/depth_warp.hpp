// The depth model on a field's budget: a per-pixel gather (Newton steps from the quadratic's
// point), and a float forward splat with a z-test (holes from the quadratic) where it does not
// settle.
#pragma once

#include "ig/camera.hpp"
#include "ig/frame.hpp"
#include "prp/warp_apply.hpp"
#include "prp/warp_fit.hpp"

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace prp {

// Source-row projection kernel of the depth model. Both give the same bits (same float
// operations in the same order, no fused multiply-add); Auto takes AVX2 where the processor has it.
enum class DepthKernel { Auto, Scalar, Avx2 };
bool depthKernelSupported(DepthKernel kernel);

// How the depth model finds each output pixel's source point. Gather: per output pixel, Newton
// steps from the quadratic's point against the exact reprojection, the splat in the tiles where
// they do not settle. Splat: every rendered pixel projected and z-tested (the gather's twin).
enum class DepthMethod { Gather, Splat };
// "gather" | "splat"; empty for anything else.
std::optional<DepthMethod> parseDepthMethod(const std::string& text);
const char* depthMethodName(DepthMethod method);

// Per-field constants taking a rendered pixel and its depth to an output-frame point, in float.
// A pixel (x, y) is the source-camera point (d / l) (a, b, f) with a = x + 0.5 - cx,
// b = cy - (y + 0.5), l = |(a, b, f)| and d its depth (sky: d = 1 and no translation: a
// direction). In the field's camera (roll included), scaled by l / d, it is
// (r, u, w) = d M (a, b, f) + l t; it lands at qx = ox + kx r / w, qy = oy - ky u / w (output
// pixels, full-frame lines), at inverse depth l / w along the field camera's axis.
// kx, ky: the field's focal length times the output scaling.
struct DepthProjection {
    float cx = 0, cy = 0, f = 0;
    float m[9]{};  // row-major: rows are the field camera's right, up, forward in source axes
    float t[3]{};  // source eye minus field eye, in the field camera's axes
    float ox = 0, oy = 0, kx = 0, ky = 0;
    // Rendered pixels per output pixel as a matrix (d source / d output, row-major: jxx, jxy,
    // jyx, jyy), taking a landing point's offset from its output pixel's centre back to the
    // frame: the output scaling, zoom included (of()), or the quadratic's Jacobian (withJacobian():
    // the field's rotation, roll and magnification too).
    float j[4]{1, 0, 0, 1};
    int outWidth = 0, outHeight = 0;

    static DepthProjection of(const ig::RenderedFrame& frame, const ig::Pose& fieldPose,
                              const OutputGeometry& geometry);
    // The same with j the Jacobian of `q` (output pixels to rendered pixels, as the quadratic
    // warp maps them) at the output's centre; unchanged where that is not finite or beyond
    // kMaxJacobian.
    DepthProjection withJacobian(const Quadratic& q) const;
    static constexpr double kMaxJacobian = 64.0;
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

// The gather's constants for one field line: its output row centre and the quadratic along it,
// Q(X) = x0 + X (x1 + X x2) (and y), with its Jacobian dQ/dX = x1 + X x2x2, dQ/dY = xy0 + X xy1.
struct GatherLine {
    float row = 0;  // output row centre (full-frame lines)
    float x0 = 0, x1 = 0, x2 = 0, x2x2 = 0, xy0 = 0, xy1 = 0;
    float y0 = 0, y1 = 0, y2 = 0, y2x2 = 0, yy0 = 0, yy1 = 0;

    static GatherLine of(const Quadratic& q, double row);
};

// Gather steps: reprojections per pixel (each followed by a correction); largest residual (output
// pixels, either axis) at the last one for a pixel to count as settled; largest parallax (output
// pixels) between the four depth taps of the last step, and between the surface under the
// quadratic's point and the final one when the former is nearer (an occluder), before a pixel
// counts as on a depth edge.
inline constexpr int kGatherSteps = 2;
inline constexpr float kGatherSettledPx = 0.25f;
inline constexpr float kGatherEdgePx = 1.0f;
// Largest parallax (output pixels) between the depths two neighbouring output pixels settled on
// before the tiles around them take the splat (DepthWarp::apply).
inline constexpr float kGatherJumpPx = 2.0f;
// The depth the gather takes for sky (+inf), so that it interpolates.
inline constexpr float kGatherFar = 1e30f;
// Output pixels of parallax per unit of inverse depth: the translation's length times the larger
// output focal length (a bound on how far two depths at one source point land apart).
float gatherParallaxScale(const DepthProjection& p);

namespace detail {
// Rendered row y's depths as the projection takes them, once per frame (they depend on the frame
// alone, not the field): per pixel the scale s of its point s (a, b, f) along the unnormalised
// ray, d / l for terrain (l = |(a, b, f)|, d the depth: a finite value), 1 / l for anything else
// (sky: the unit direction). Pixels [begin, end); `depth` and `scaled` indexed from the row's
// start.
void scaleDepthRowScalar(const DepthProjection& p, const float* depth, int begin, int end, int y,
                         float* scaled);
// Pixels [begin, end) of rendered row y (`depth`, its scaleDepthRow values `scaled` and `out`
// indexed from the row's start).
void projectRowScalar(const DepthProjection& p, const float* depth, const float* scaled, int begin,
                      int end, int y, int firstLine, const ProjectedRow& out);
// Output pixels [begin, end) of one field line: from the quadratic's point, kGatherSteps times
// x <- x + dQ (q - P(x, 1 / depth at x)) (P: the projection above; the inverse depth bilinear
// between the four rendered pixel centres around x, clamped to the frame, sky 0). Writes the
// final points (16.16, minus half a pixel, as applyPoints takes them) and 1 in `unsettled` where
// the last residual exceeds kGatherSettledPx, a tap was not terrain or sky (NaN, zero, negative
// depth) or a reprojection fell behind the eye, or the taps (or the quadratic's point's surface
// against the final one) differ by more than kGatherEdgePx of parallax; returns how many did not
// settle.
// `dist` receives the depth each pixel settled on (sky: kGatherFar). `depth` is the whole frame
// (width x height); the outputs are indexed from the line's start.
int gatherLineScalar(const DepthProjection& p, const GatherLine& line, const float* depth,
                     int width, int height, int begin, int end, std::int32_t* px, std::int32_t* py,
                     std::uint8_t* unsettled, float* dist);
#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
// The same eight pixels at a time; need AVX2.
void scaleDepthRowAvx2(const DepthProjection& p, const float* depth, int begin, int end, int y,
                       float* scaled);
void projectRowAvx2(const DepthProjection& p, const float* depth, const float* scaled, int begin,
                    int end, int y, int firstLine, const ProjectedRow& out);
// The gather eight pixels at a time (hardware gathers of the depth); the scalar one's bits.
int gatherLineAvx2(const DepthProjection& p, const GatherLine& line, const float* depth, int width,
                   int height, int begin, int end, std::int32_t* px, std::int32_t* py,
                   std::uint8_t* unsettled, float* dist);
#endif
}  // namespace detail

struct DepthWarpResult {
    std::uint64_t edgeSamples = 0;  // samples outside the rendered frame (edge repeated)
    std::uint64_t lumaSum = 0;
    // Output pixels no rendered pixel landed on (a line neighbour's point moved by a pixel, else
    // the quadratic's).
    std::uint64_t holes = 0;
    std::uint64_t unsettled = 0;    // gather: pixels whose steps did not settle
    std::uint64_t splatPixels = 0;  // output pixels made by the splat (tiles, or the whole field)
    // The clock passed apply()'s `giveUpAt` first: nothing of the field is written (the points
    // are incomplete), the other fields are not set.
    bool abandoned = false;
    // Seconds from the last look at the clock (the field's points complete) to the return: the
    // part of the field no deadline can stop, which a caller's deadline must leave room for.
    double tailSeconds = 0.0;
};

// Per-frame buffers' room for a `width` x `height` frame and the frames of the same window the
// renderer widens for any roll: their diagonal stays under twice this frame's and their pixels
// under twice its diagonal squared (a margin grows by at most half the window's diagonal less
// half its shorter side). Sized so from the level frame, a banking flight allocates nothing on
// the field thread.
std::size_t rolledFrameDiagonal(int width, int height);  // this frame's, rounded up
inline std::size_t rolledFrameRoomPixels(int width, int height) {
    const std::size_t d = rolledFrameDiagonal(width, height);
    return 2 * d * d;
}

// Writes `v`'s room past its size once (before a field clock starts), so that frames growing
// into it later fault no pages in; its first size() elements are kept.
template <typename T>
void touchRoom(std::vector<T>& v) {
    const std::size_t n = v.size();
    v.resize(v.capacity());
    v.resize(n);
}

// The depth model's fast path, with its scratch buffers (sized on first use, then reused).
class DepthWarp {
  public:
    // Splat: every rendered pixel of `frame` (colour `color`, which may be a filtered copy) is
    // projected into the lines of `field` by the field pose (roll included), nearest output
    // pixel, nearer points winning; each output pixel then samples bilinearly at the source
    // point that lands on its centre (to first order, by `holeWarp`'s Jacobian), and an output
    // pixel no source pixel reached at the farther of its line neighbours' points moved by a
    // pixel, else at `holeWarp`'s point. Gather: each output pixel's source point by gather steps
    // from `holeWarp`'s point; tiles of kGatherTileWidth x kGatherTileLines with a pixel that did
    // not settle are splatted (only the rendered pixels near theirs), the whole field when more
    // than kGatherMaxSplatShare of the tiles have one. The clock is looked at every kCheckRows
    // rendered rows (or field lines) before the field is written: past `giveUpAt` the warp is
    // abandoned (DepthWarpResult::abandoned), the field left as it was.
    DepthWarpResult apply(const ig::RenderedFrame& frame, const ig::Rgb8* color,
                          const ig::Pose& fieldPose, const OutputGeometry& geometry,
                          const Quadratic& holeWarp, const FieldView& field, int gainQ8, bool agc,
                          DepthKernel kernel = DepthKernel::Auto,
                          DepthMethod method = DepthMethod::Splat,
                          std::chrono::steady_clock::time_point giveUpAt =
                              std::chrono::steady_clock::time_point::max());
    static constexpr int kCheckRows = 16;

    static constexpr int kGatherTileWidth = 64;
    static constexpr int kGatherTileLines = 8;
    static constexpr double kGatherMaxSplatShare = 0.5;
    // Sizes the scratch buffers for frames like `frameWidth` x `frameHeight` and the frames of
    // the same window the renderer widens for any roll (rows up to twice its diagonal, twice its
    // diagonal squared of scaled depths), and fields of `fieldPixels`, so a field that takes the
    // depth warp first later allocates nothing; grown when a frame needs more.
    void reserve(int frameWidth, int frameHeight, std::size_t fieldPixels);

    // Makes `frame`'s per-frame data now (its scaled depths; kept for its fields), so that the
    // first field warped from it does not: before a field clock starts, for its first frame.
    void prepareFrame(const ig::RenderedFrame& frame, DepthKernel kernel = DepthKernel::Auto);

    // The points the last apply() sampled (field line L's pixel x at [L * field width + x];
    // 16.16 fixed point, as applyPoints takes them).
    const std::int32_t* pointsX() const { return pointX_.data(); }
    const std::int32_t* pointsY() const { return pointY_.data(); }
    // Gather: 1 where the last apply()'s steps did not settle (same layout as the points).
    const std::uint8_t* unsettled() const { return unsettled_.data(); }

  private:
    bool useAvx2(DepthKernel kernel) const;
    // Splats rendered rows [y0, y1), columns [x0, x1) into the z-buffer, keeping only points
    // that land in field lines [l0, l1), columns [c0, c1) when `clip`.
    void splatRows(const DepthProjection& proj, const ig::RenderedFrame& frame, int firstLine,
                   int fieldWidth, int y0, int y1, int x0, int x1, bool clip, int l0, int l1,
                   int c0, int c1, bool avx2);
    // Fills the holes of field lines [l0, l1), columns [c0, c1) (neighbours beyond them count as
    // empty); returns how many.
    std::uint64_t fillHoles(const DepthProjection& proj, const Quadratic& holeWarp,
                            const FieldView& field, int l0, int l1, int c0, int c1);
    // Marks for the splat the tiles around output neighbours that settled on depths apart.
    void markDepthJumps(const DepthProjection& proj, const FieldView& field, int tilesAcross,
                        int tilesDown);
    // The splat of one tile: the rendered pixels near its pixels' points.
    std::uint64_t splatTile(const DepthProjection& proj, const ig::RenderedFrame& frame,
                            const Quadratic& holeWarp, const FieldView& field, int l0, int l1,
                            int c0, int c1, bool avx2);

    std::vector<float> depth_;                   // one field: the z-buffer (inverse depths)
    std::vector<std::int32_t> pointX_, pointY_;  // one field: the points sampled (16.16)
    std::vector<std::uint8_t> unsettled_;        // one field: the gather's flags
    std::vector<float> gatherDist_;              // one field: the depth each pixel settled on
    std::vector<std::uint16_t> tileUnsettled_;   // one field: unsettled pixels per tile
    std::vector<std::int32_t> rowIndex_;         // one rendered row
    std::vector<float> rowZInv_, rowSx_, rowSy_;
    // The last frame's scaleDepthRow values, and what they were made from.
    std::vector<float> scaled_;
    const float* scaledFrom_ = nullptr;
    std::uint64_t scaledSequence_ = 0;
    int scaledWidth_ = 0, scaledHeight_ = 0;
    float scaledCx_ = 0, scaledCy_ = 0, scaledF_ = 0;
    // The frame's scaled depths (made once per frame and kept).
    const float* scaledDepth(const ig::RenderedFrame& frame, const DepthProjection& p, bool avx2);
};

}  // namespace prp
