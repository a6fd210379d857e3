// Object ids through a field's warp: each output pixel takes the id of the rendered pixel nearest
// the point its colour is sampled at (no blending), for every warp model.
#pragma once

#include "prp/warp_fit.hpp"

#include <cstddef>
#include <cstdint>

namespace prp {

// The rendered frame's object-id image (0: terrain or sky).
struct IdSource {
    const std::uint16_t* ids = nullptr;
    int width = 0;
    int height = 0;
};

// One field's ids: `lines` lines of `width`, line L is output-frame line firstLine + 2 L.
struct IdFieldView {
    std::uint16_t* ids = nullptr;
    std::size_t stride = 0;  // elements per line
    int width = 0;
    int firstLine = 0;
    int lines = 0;
};

// The id at a sample point given as the colour kernels hold it: the rendered-frame point minus
// half a pixel, 32.32 fixed point. The point is clamped as the bilinear sampler clamps it (edge
// repeated), then rounded to the nearest pixel centre: the tap of the colour sample with the
// larger weight along each axis (the nearer one; ties go right and down).
inline std::uint16_t nearestId(const IdSource& s, std::int64_t px, std::int64_t py) {
    constexpr int kFrac = 32;
    constexpr std::int64_t kHalf = std::int64_t{1} << (kFrac - 1);
    const std::int64_t maxX = (static_cast<std::int64_t>(s.width - 1) << kFrac) - 1;
    const std::int64_t maxY = (static_cast<std::int64_t>(s.height - 1) << kFrac) - 1;
    px = px < 0 ? 0 : (px > maxX ? maxX : px);
    py = py < 0 ? 0 : (py > maxY ? maxY : py);
    const std::size_t x = static_cast<std::size_t>((px + kHalf) >> kFrac);
    const std::size_t y = static_cast<std::size_t>((py + kHalf) >> kFrac);
    return s.ids[y * static_cast<std::size_t>(s.width) + x];
}

// The same points as applyQuadratic, applyHomography and applyPoints (prp/warp_apply.hpp) walk.
void warpIdsQuadratic(const IdSource& source, const Quadratic& sourceFromOutput,
                      const IdFieldView& field);
void warpIdsHomography(const IdSource& source, const Homography& sourceFromOutput,
                       const IdFieldView& field);
// Points as applyPoints takes them (16.16 fixed point).
void warpIdsPoints(const IdSource& source, const std::int32_t* xs, const std::int32_t* ys,
                   std::size_t stride, const IdFieldView& field);

}  // namespace prp
