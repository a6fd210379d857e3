#include "prp/field.hpp"

namespace prp {

Parity fieldParity(std::uint64_t fieldIndex) {
    return fieldIndex % 2 == 0 ? Parity::Bottom : Parity::Top;
}

double fieldTime(double t0, std::uint64_t fieldIndex) {
    return t0 + static_cast<double>(fieldIndex) * kFieldPeriod;
}

int fieldLines(int frameHeight, Parity parity) {
    if (frameHeight <= 0) return 0;
    return parity == Parity::Top ? (frameHeight + 1) / 2 : frameHeight / 2;
}

int bytesPerPixel(PixelFormat format) {
    switch (format) {
        case PixelFormat::Rgb8:
            return 3;
        case PixelFormat::Y8:
            return 1;
        case PixelFormat::Uyvy:
            return 2;
    }
    return 2;
}

std::optional<WarpModel> parseWarpModel(std::string_view name) {
    if (name == "poly") return WarpModel::Poly;
    if (name == "affine") return WarpModel::Affine;
    if (name == "homography") return WarpModel::Homography;
    if (name == "depth") return WarpModel::Depth;
    if (name == "hold") return WarpModel::Hold;
    return std::nullopt;
}

std::string_view warpModelName(WarpModel model) {
    switch (model) {
        case WarpModel::Poly:
            return "poly";
        case WarpModel::Affine:
            return "affine";
        case WarpModel::Homography:
            return "homography";
        case WarpModel::Depth:
            return "depth";
        case WarpModel::Hold:
            return "hold";
    }
    return "?";
}

std::string_view fallbackName(Fallback fallback) {
    switch (fallback) {
        case Fallback::None:
            return "none";
        case Fallback::Affine:
            return "affine";
        case Fallback::Rotation:
            return "rotation";
        case Fallback::Hold:
            return "hold";
    }
    return "?";
}

std::optional<PixelFormat> parsePixelFormat(std::string_view name) {
    if (name == "rgb8") return PixelFormat::Rgb8;
    if (name == "y8") return PixelFormat::Y8;
    if (name == "uyvy") return PixelFormat::Uyvy;
    return std::nullopt;
}

}  // namespace prp
