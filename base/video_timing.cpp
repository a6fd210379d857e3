#include "base/video_timing.hpp"

namespace base {

double fieldTime(double t0, std::uint64_t index) {
    // index * 1001 is exact in 64 bits for any run shorter than ~10^10 years; one rounding.
    return t0 + static_cast<double>(index * static_cast<std::uint64_t>(kFieldPeriodNumerator)) /
                    static_cast<double>(kFieldPeriodDenominator);
}

std::int64_t fieldTimeNs(std::uint64_t index) {
    // 1001/60000 s = 50050000/3 ns.
    return static_cast<std::int64_t>(index * 50050000ull / 3ull);
}

FieldParity fieldParity(std::uint64_t index) {
    return index % 2 == 0 ? FieldParity::Bottom : FieldParity::Top;
}

int fieldFirstLine(FieldParity parity) {
    return parity == FieldParity::Top ? 0 : 1;
}

int fieldLines(int frameHeight, FieldParity parity) {
    if (frameHeight <= 0) return 0;
    return parity == FieldParity::Top ? (frameHeight + 1) / 2 : frameHeight / 2;
}

int bytesPerPixel(PixelFormat format) {
    switch (format) {
        case PixelFormat::Uyvy:
            return 2;
        case PixelFormat::Y8:
            return 1;
        case PixelFormat::Rgb8:
            return 3;
    }
    return 2;
}

const char* pixelFormatName(PixelFormat format) {
    switch (format) {
        case PixelFormat::Uyvy:
            return "uyvy";
        case PixelFormat::Y8:
            return "y8";
        case PixelFormat::Rgb8:
            return "rgb8";
    }
    return "?";
}

std::optional<PixelFormat> parsePixelFormat(std::string_view name) {
    if (name == "uyvy") return PixelFormat::Uyvy;
    if (name == "y8" || name == "grey" || name == "gray") return PixelFormat::Y8;
    if (name == "rgb8" || name == "rgb") return PixelFormat::Rgb8;
    return std::nullopt;
}

}  // namespace base
