#include "io/video_format.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>

namespace io {
namespace {

constexpr int kMaxDimension = 8192;

std::uint8_t clampByte(double v) {
    return static_cast<std::uint8_t>(std::clamp(std::lround(v), 0L, 255L));
}

// BT.601 studio-range Y'CbCr of a full-range RGB pixel.
void rgbToYcc(const std::uint8_t* p, double* y, double* cb, double* cr) {
    const double r = p[0], g = p[1], b = p[2];
    *y = 16.0 + (65.481 * r + 128.553 * g + 24.966 * b) / 255.0;
    *cb = 128.0 + (-37.797 * r - 74.203 * g + 112.0 * b) / 255.0;
    *cr = 128.0 + (112.0 * r - 93.786 * g - 18.214 * b) / 255.0;
}

void yccToRgb(int y, int cb, int cr, std::uint8_t* out) {
    const double yy = 1.164383 * (y - 16);
    const double u = cb - 128, v = cr - 128;
    out[0] = clampByte(yy + 1.596027 * v);
    out[1] = clampByte(yy - 0.391762 * u - 0.812968 * v);
    out[2] = clampByte(yy + 2.017232 * u);
}

}  // namespace

std::string checkVideoFormat(const VideoFormat& format) {
    if (format.width <= 0 || format.height < 2 || format.width > kMaxDimension ||
        format.height > kMaxDimension) {
        return "size " + std::to_string(format.width) + "x" + std::to_string(format.height) +
               ": a video frame is 1.." + std::to_string(kMaxDimension) + " pixels wide and 2.." +
               std::to_string(kMaxDimension) + " lines high (two fields)";
    }
    if (format.format != PixelFormat::Y8 && format.width % 2 != 0) {
        return "width " + std::to_string(format.width) + " must be even for 4:2:2 output";
    }
    return {};
}

void fillBlack(PixelFormat format, std::uint8_t* row, int pixels) {
    if (format == PixelFormat::Uyvy) {
        for (int i = 0; i < pixels; ++i) {
            row[2 * i] = 128;
            row[2 * i + 1] = 16;
        }
    } else {
        std::memset(row, 0, static_cast<std::size_t>(pixels) * bytesPerPixel(format));
    }
}

void uyvyRowToRgb(const std::uint8_t* uyvy, int width, std::uint8_t* rgb) {
    for (int x = 0; x + 1 < width; x += 2) {
        const std::uint8_t* p = uyvy + 2 * x;
        yccToRgb(p[1], p[0], p[2], rgb + 3 * x);
        yccToRgb(p[3], p[0], p[2], rgb + 3 * x + 3);
    }
    if (width % 2 != 0) {
        const std::uint8_t* p = uyvy + 2 * (width - 1);
        yccToRgb(p[1], p[0], 128, rgb + 3 * (width - 1));
    }
}

void rgbRowToUyvy(const std::uint8_t* rgb, int width, std::uint8_t* uyvy) {
    for (int x = 0; x + 1 < width; x += 2) {
        double y0, cb0, cr0, y1, cb1, cr1;
        rgbToYcc(rgb + 3 * x, &y0, &cb0, &cr0);
        rgbToYcc(rgb + 3 * x + 3, &y1, &cb1, &cr1);
        std::uint8_t* q = uyvy + 2 * x;
        q[0] = clampByte(0.5 * (cb0 + cb1));
        q[1] = clampByte(y0);
        q[2] = clampByte(0.5 * (cr0 + cr1));
        q[3] = clampByte(y1);
    }
}

void rowToRgb(PixelFormat format, const std::uint8_t* row, int width, std::uint8_t* rgb) {
    switch (format) {
        case PixelFormat::Uyvy:
            uyvyRowToRgb(row, width, rgb);
            return;
        case PixelFormat::Y8:
            for (int x = 0; x < width; ++x)
                rgb[3 * x] = rgb[3 * x + 1] = rgb[3 * x + 2] = row[x];
            return;
        case PixelFormat::Rgb8:
            std::memcpy(rgb, row, static_cast<std::size_t>(width) * 3);
            return;
    }
}

void rowToPlanar422(PixelFormat format, const std::uint8_t* row, int width, std::uint8_t* y,
                    std::uint8_t* cb, std::uint8_t* cr) {
    switch (format) {
        case PixelFormat::Uyvy:
            for (int x = 0; x + 1 < width; x += 2) {
                const std::uint8_t* p = row + 2 * x;
                cb[x / 2] = p[0];
                y[x] = p[1];
                cr[x / 2] = p[2];
                y[x + 1] = p[3];
            }
            return;
        case PixelFormat::Y8:
            std::memcpy(y, row, static_cast<std::size_t>(width));
            return;
        case PixelFormat::Rgb8:
            for (int x = 0; x + 1 < width; x += 2) {
                double y0, cb0, cr0, y1, cb1, cr1;
                rgbToYcc(row + 3 * x, &y0, &cb0, &cr0);
                rgbToYcc(row + 3 * x + 3, &y1, &cb1, &cr1);
                y[x] = clampByte(y0);
                y[x + 1] = clampByte(y1);
                cb[x / 2] = clampByte(0.5 * (cb0 + cb1));
                cr[x / 2] = clampByte(0.5 * (cr0 + cr1));
            }
            return;
    }
}

}  // namespace io
