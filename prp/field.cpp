#include "prp/field.hpp"

namespace prp {

std::optional<WarpModel> parseWarpModel(std::string_view name) {
    if (name == "poly") return WarpModel::Poly;
    if (name == "affine") return WarpModel::Affine;
    if (name == "homography") return WarpModel::Homography;
    if (name == "depth") return WarpModel::Depth;
    if (name == "hold") return WarpModel::Hold;
    if (name == "auto") return WarpModel::Auto;
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
        case WarpModel::Auto:
            return "auto";
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

}  // namespace prp
