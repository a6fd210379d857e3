// Applying a warp to one field: fixed-point forward differences, bilinear taps, fused colour.
#pragma once

#include "ig/caster.hpp"
#include "ig/terrain.hpp"
#include "prp/field.hpp"
#include "prp/warp_fit.hpp"

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string_view>

namespace prp {

// The rendered colour being sampled (at least 2 x 2 pixels).
struct SourceView {
    const ig::Rgb8* pixels = nullptr;
    int width = 0;
    int height = 0;
};

// The field being written: `lines` lines of `width` pixels; field line L is output-frame line
// firstLine + 2 L.
struct FieldView {
    std::uint8_t* pixels = nullptr;
    std::size_t stride = 0;
    int width = 0;
    int firstLine = 0;
    int lines = 0;
    PixelFormat format = PixelFormat::Rgb8;
};

struct ApplyResult {
    std::uint64_t edgeSamples = 0;  // samples outside the source (edge pixels repeated)
    std::uint64_t lumaSum = 0;      // sum of full-range luma of the written pixels (AGC only)
};

// Unity gain in the Q8 gain used by the kernels.
inline constexpr int kUnityGain = 256;

// Implementation of the per-pixel kernel of applyQuadratic. All give bit-identical fields and
// counts; Auto takes the fastest one the running processor supports (AVX-512 with VBMI, else
// AVX2, else Scalar). A kernel the processor cannot run, or a source it cannot take (more than 2^31
// bytes, narrower than 3 or lower than 2 pixels; gain outside 0..65536), falls back to Scalar.
enum class WarpKernel { Auto, Scalar, Avx2, Avx512 };
// Whether the running processor (and this build) can run `kernel`.
bool warpKernelSupported(WarpKernel kernel);

// Warps `source` into `field` through `sourceFromOutput`: per row the quadratic is evaluated by
// forward differences in 32.32 fixed point, each sample is bilinear (8-bit weights) and the
// colour is converted in the same pass. `gainQ8` != kUnityGain scales RGB first (AGC); `agc`
// also accumulates luma. The quadratic must be bounded by kMaxSourceCoordinate (fitWarp
// guarantees it).
ApplyResult applyQuadratic(const SourceView& source, const Quadratic& sourceFromOutput,
                           const FieldView& field, int gainQ8, bool agc,
                           WarpKernel kernel = WarpKernel::Auto);
// Samples given source points: field line L's pixel x at (xs, ys)[L * stride + x], rendered-frame
// coordinates minus half a pixel in 16.16 fixed point (the quadratic kernel's 32.32 points
// shifted right by 16: the same 8-bit weights), with the same bilinear taps, edge handling and
// colour conversion. Kernels as for applyQuadratic (AVX-512 runs the AVX2 kernel).
ApplyResult applyPoints(const SourceView& source, const std::int32_t* xs, const std::int32_t* ys,
                        std::size_t stride, const FieldView& field, int gainQ8, bool agc,
                        WarpKernel kernel = WarpKernel::Auto);
// Same with a projective map (one division per pixel); its denominator must be positive.
ApplyResult applyHomography(const SourceView& source, const Homography& sourceFromOutput,
                            const FieldView& field, int gainQ8, bool agc);
// What a field shows where it samples outside the rendered frame: the edge pixel repeated; the
// sky colour of each pixel's ray above the horizon and the edge pixel below (Sky); or the sky
// above and the haze (horizon) colour below (SkyHaze).
enum class EdgeFill { Repeat, Sky, SkyHaze };
std::string_view edgeFillName(EdgeFill fill);
// "repeat" | "sky" | "sky-haze"; empty otherwise.
std::optional<EdgeFill> parseEdgeFill(std::string_view name);

// Out-of-frame fill: what an output pixel whose source point lies outside the rendered frame
// shows instead of the frame's repeated edge pixel — the sky colour for the pixel's ray
// direction above the horizon, by the casters' SkyModel; below it the haze (horizon) colour
// when `hazeBelow`, else the repeated edge pixel (terrain continues past the edge at about
// the same distance; measured in docs/design/appearance.md).
struct OutsideFill {
    ig::SkyModel sky;
    bool hazeBelow = false;
    // Output pixel centre (X, Y) looks along focal forward + (sx X - cx) right - (sy Y - cy) up
    // (the field camera's orthonormal basis; only the vertical components are kept).
    double focal = 1.0, cx = 0.0, cy = 0.0, sx = 1.0, sy = 1.0;
    double forwardZ = 0.0, rightZ = 0.0, upZ = 0.0;

    // The fill of a field whose camera is `pose` (roll included), its output pixels scaled onto
    // the rendered window of `rendered` by `geometry`, at the field's focal length
    // (geometry.focal; the frame's when that is 0).
    static OutsideFill of(const ig::SkyModel& sky, const ig::Intrinsics& rendered,
                          const OutputGeometry& geometry, const ig::Pose& pose);
    // Colour at output pixel centre (x, y); false where the pixel keeps its repeated edge.
    bool colorAt(double x, double y, ig::Rgb8& color) const;
    // colorAt of the n pixel centres (x0 + k + 0.5, y), k < n <= 64, into rgb[3k..3k+2] where
    // has[k]: the same colours, a row at a time (the square roots of one pixel wait for none of
    // the others').
    void colorsAlong(int x0, int n, double y, bool* has, std::uint8_t* rgb) const;
};

// Rewrites the pixels of `field` (written by applyQuadratic / applyHomography with any kernel,
// same source, map, gain and AGC) whose source point lies outside `source` with fill.colorAt,
// and corrects result.lumaSum for them (edgeSamples still counts them). A UYVY pair with one
// pixel outside is written again whole. Nothing to do when result.edgeSamples is 0.
void fillOutside(const SourceView& source, const Quadratic& sourceFromOutput,
                 const FieldView& field, int gainQ8, bool agc, const OutsideFill& fill,
                 ApplyResult& result);
void fillOutside(const SourceView& source, const Homography& sourceFromOutput,
                 const FieldView& field, int gainQ8, bool agc, const OutsideFill& fill,
                 ApplyResult& result);
// fillOutside's slow twin (tests): every pixel with its point outside written again, one at a
// time, colour by colour as the kernels and the fill give them.
void fillOutsidePerPixel(const SourceView& source, const Quadratic& sourceFromOutput,
                         const FieldView& field, int gainQ8, bool agc, const OutsideFill& fill,
                         ApplyResult& result);
// The same for the points applyPoints sampled (the depth model's).
void fillOutside(const SourceView& source, const std::int32_t* xs, const std::int32_t* ys,
                 std::size_t stride, const FieldView& field, int gainQ8, bool agc,
                 const OutsideFill& fill, ApplyResult& result);

// Converts one row of interleaved RGB8 pixels into `format` (with gain), adding luma to
// `lumaSum` when `agc`.
void convertRow(const std::uint8_t* rgb, int width, PixelFormat format, int gainQ8, bool agc,
                std::uint8_t* out, std::uint64_t& lumaSum);

// BT.601 studio-range Y'CbCr of 8-bit R'G'B' (Y' 16..235, Cb/Cr 16..240), integer arithmetic as
// in the kernels. Chroma of a pixel pair uses the pair's summed components.
struct YCbCr {
    std::uint8_t y = 16, cb = 128, cr = 128;
};
YCbCr bt601(int r, int g, int b);
std::uint8_t bt601Luma(int r, int g, int b);
// Cb, Cr of the mean of two pixels given their component sums (0..510).
void bt601ChromaOfSum(int rSum, int gSum, int bSum, std::uint8_t& cb, std::uint8_t& cr);
// Full-range grey (Y8 output): 0.299 R + 0.587 G + 0.114 B.
std::uint8_t greyOf(int r, int g, int b);

}  // namespace prp
