// Output fields of the post-rendering processor: parity, timing, pixel formats and warp record.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string_view>
#include <vector>

#include "base/video_timing.hpp"

namespace prp {

// FieldParity, pixel format and field timing are the ones every module uses (base/video_timing).
using base::bytesPerPixel;
using base::fieldFirstLine;
using base::fieldLines;
using base::FieldParity;
using base::fieldParity;
using base::fieldTime;
using base::kFieldPeriod;
using base::parsePixelFormat;
using base::PixelFormat;

// How a field is made from the latest rendered frame. Auto picks Poly or Depth per field by the
// quadratic's measured error on check points (PrpOptions::autoThresholdPx).
enum class WarpModel { Poly, Affine, Homography, Depth, Hold, Auto };
// What the fit fell back to when the model's own fit was unusable.
enum class Fallback { None, Affine, Rotation, Hold };

// "poly" | "affine" | "homography" | "depth" | "hold" | "auto"; empty for anything else.
std::optional<WarpModel> parseWarpModel(std::string_view name);
std::string_view warpModelName(WarpModel model);
std::string_view fallbackName(Fallback fallback);

// The warp a field used. For quadratic warps (poly, affine, rotation fallback, hold) `a` and `b`
// map an output-frame point (x, y) (continuous, pixel centres at +0.5, full-frame line numbers)
// to a rendered-frame point: x' = a0 + a1 x + a2 y + a3 xy + a4 x^2 + a5 y^2, likewise y' with b.
// A homography uses `h` instead (row-major 3x3, same coordinates).
struct WarpInfo {
    WarpModel model = WarpModel::Hold;
    Fallback fallback = Fallback::None;
    std::array<double, 6> a{}, b{};
    int rank = 0;             // rank of the fitted system (0 when nothing was fitted)
    double condition = 0.0;   // 2-norm condition number of the (normalised) fitted system
    double residualPx = 0.0;  // RMS fit residual over the used points, rendered-frame pixels
    int pointsUsed = 0;       // control points used by the fit
    bool projective = false;  // true: `h` holds the warp (homography model)
    std::array<double, 9> h{};
    // Auto: the quadratic's largest error on the check points, rendered pixels (-1: not measured).
    double checkErrorPx = -1.0;
    // Auto: the field wanted the depth model, whose recent fields took longer than
    // PrpOptions::autoDepthBudget: the quadratic warped it.
    bool depthOverBudget = false;
    // Auto on a deadline: the depth model was still unfinished at PrpOptions::autoDepthBudget
    // and was abandoned; the quadratic warped the field.
    bool depthAbandoned = false;
};

// One field: only the lines of its parity. `pixels` is reused from field to field.
struct Field {
    std::uint64_t index = 0;
    FieldParity parity = FieldParity::Bottom;
    double time = 0.0;                // the instant the field shows, seconds
    std::uint64_t frameSequence = 0;  // rendered frame it came from
    double frameTime = 0.0;           // that frame's pose time
    double frameAge = 0.0;            // time - frameTime
    int width = 0;
    int frameHeight = 0;  // lines of the full (woven) frame
    int lines = 0;        // lines of this field
    PixelFormat format = PixelFormat::Uyvy;
    std::vector<std::uint8_t> pixels;
    std::size_t stride = 0;  // bytes per field line
    WarpInfo warp;
    std::uint64_t edgeSamples = 0;  // samples that fell outside the rendered frame (edge repeated)
    std::uint64_t holeSamples = 0;  // depth model: pixels no rendered pixel landed on
    double warpMs = 0.0;            // time spent in process(), milliseconds
    // Moving objects re-stamped at the field's instant, and the field pixels that rewrote.
    int restampedObjects = 0;
    std::uint64_t restampedPixels = 0;
    double gain = 1.0;  // AGC gain applied to this field
    // Object id per pixel of this field's lines (width * lines, line by line), warped with the
    // colour (the nearest rendered pixel at each colour sample point); empty when the frame
    // carries no object ids.
    std::vector<std::uint16_t> objectId;

    const std::uint8_t* line(int fieldLine) const { return pixels.data() + fieldLine * stride; }
    // Frame line number of field line `fieldLine`.
    int frameLine(int fieldLine) const { return 2 * fieldLine + fieldFirstLine(parity); }
};

}  // namespace prp
