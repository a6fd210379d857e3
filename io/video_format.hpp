// Video formats, field buffers and the pixel conversions shared by the frame sinks.
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

namespace io {

enum class FieldParity { Top, Bottom };     // Top = frame lines 0,2,4,...; Bottom = lines 1,3,5,...
enum class PixelFormat { Uyvy, Y8, Rgb8 };  // Uyvy = BT.601 Y'CbCr 4:2:2, 2 bytes per pixel

// One output video format; `height` counts the lines of the full (woven) frame.
struct VideoFormat {
    int width = 720;
    int height = 486;
    PixelFormat format = PixelFormat::Uyvy;
};

// One field handed to a sink: `lines` rows of `format().width` pixels, `stride` bytes apart.
struct FieldBuffer {
    std::uint64_t index = 0;
    FieldParity parity = FieldParity::Bottom;
    double time = 0.0;  // seconds, the instant the field shows
    const std::uint8_t* data = nullptr;
    std::size_t stride = 0;
    int lines = 0;
};

inline constexpr double kNtscFieldPeriod = 1001.0 / 60000.0;  // seconds per NTSC field

int bytesPerPixel(PixelFormat format);
const char* pixelFormatName(PixelFormat format);  // "uyvy", "y8", "rgb8"
std::optional<PixelFormat> parsePixelFormat(std::string_view name);
// Lines of a field of `parity` in a frame of `frameHeight` lines, and the frame line it starts at.
int fieldLines(int frameHeight, FieldParity parity);
int fieldFirstLine(FieldParity parity);
// NTSC order: field 0 is Bottom, then alternating.
FieldParity fieldParityOf(std::uint64_t fieldIndex);
// Empty when `format` is usable; otherwise what is wrong with it.
std::string checkVideoFormat(const VideoFormat& format);
// Fills `pixels` pixels of `format` with black (Y' 16, Cb Cr 128 for Y'CbCr; 0 for Y8 and RGB).
void fillBlack(PixelFormat format, std::uint8_t* row, int pixels);

// Row conversions (BT.601, studio range for Y'CbCr, full range for RGB and Y8).
void uyvyRowToRgb(const std::uint8_t* uyvy, int width, std::uint8_t* rgb);
void rgbRowToUyvy(const std::uint8_t* rgb, int width, std::uint8_t* uyvy);  // width even
void rowToRgb(PixelFormat format, const std::uint8_t* row, int width, std::uint8_t* rgb);
// Splits one row into planar 4:2:2 (`y` width samples, `cb`/`cr` width/2 samples); Y8 gives
// only `y`. Width even for Uyvy and Rgb8.
void rowToPlanar422(PixelFormat format, const std::uint8_t* row, int width, std::uint8_t* y,
                    std::uint8_t* cb, std::uint8_t* cr);

}  // namespace io
