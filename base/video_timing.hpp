// Video timing, defined once for every module: the NTSC field period, field instants and
// parities, and the pixel formats of output fields.
#pragma once

#include <cstdint>
#include <optional>
#include <string_view>

namespace base {

// Top = frame lines 0, 2, 4, ...; Bottom = frame lines 1, 3, 5, ...
enum class FieldParity { Top, Bottom };
// Uyvy = BT.601 studio-range Y'CbCr 4:2:2, 2 bytes per pixel (Cb Y0 Cr Y1); Y8 = full-range
// luma, 1 byte; Rgb8 = full-range RGB, 3 bytes.
enum class PixelFormat { Uyvy, Y8, Rgb8 };

// Seconds per NTSC field: 1001/60000 (59.94 fields per second).
inline constexpr std::int64_t kFieldPeriodNumerator = 1001;
inline constexpr std::int64_t kFieldPeriodDenominator = 60000;
inline constexpr double kFieldPeriod =
    static_cast<double>(kFieldPeriodNumerator) / static_cast<double>(kFieldPeriodDenominator);

// The instant field `index` shows, for a stream whose field 0 shows at `t0`:
// t0 + index * 1001 / 60000, computed from the index with one rounding of the period (no
// running sum), so instants never drift however long the run.
double fieldTime(double t0, std::uint64_t index);
// The same from 0 in integer nanoseconds, exact to the nanosecond (rounded down).
std::int64_t fieldTimeNs(std::uint64_t index);

// NTSC sends the bottom field first: field 0 is Bottom, then parities alternate.
FieldParity fieldParity(std::uint64_t index);
// First frame line of a parity: 0 for Top, 1 for Bottom.
int fieldFirstLine(FieldParity parity);
// Lines of `parity` in a frame of `frameHeight` lines (0 for a height of 0 or less).
int fieldLines(int frameHeight, FieldParity parity);

int bytesPerPixel(PixelFormat format);  // Uyvy 2 (averaged over a pixel pair), Y8 1, Rgb8 3
const char* pixelFormatName(PixelFormat format);  // "uyvy", "y8", "rgb8"
// "uyvy"; "y8", "grey" or "gray"; "rgb8" or "rgb". Empty for anything else.
std::optional<PixelFormat> parsePixelFormat(std::string_view name);

}  // namespace base
