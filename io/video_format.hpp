// Video formats, field buffers and the pixel conversions shared by the frame sinks.
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

#include "base/video_timing.hpp"

namespace io {

// Parity, pixel format and field timing are the ones every module uses (base/video_timing).
using base::bytesPerPixel;
using base::fieldFirstLine;
using base::fieldLines;
using base::FieldParity;
using base::fieldParity;
using base::kFieldPeriod;
using base::parsePixelFormat;
using base::PixelFormat;
using base::pixelFormatName;

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
