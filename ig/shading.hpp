// Colour of a hit (bilinear from the map), of the sky, and distance haze — shared by all casters.
#pragma once

#include "ig/caster.hpp"
#include "ig/terrain.hpp"

#include <algorithm>
#include <cmath>

namespace ig {

// Sky colour for a unit direction whose vertical component is dz: horizon colour at and below
// the horizon, blending to the zenith colour straight up.
inline Rgb8 skyColor(const SkyModel& sky, double dz) {
    const double t = std::sqrt(std::clamp(dz, 0.0, 1.0));
    auto mix = [t](std::uint8_t a, std::uint8_t b) {
        return static_cast<std::uint8_t>(a + (b - a) * t + 0.5);
    };
    return Rgb8{mix(sky.horizon.r, sky.zenith.r), mix(sky.horizon.g, sky.zenith.g),
                mix(sky.horizon.b, sky.zenith.b)};
}

// Whether the casters draw the haze themselves: it is on and has no height fall-off (with one,
// the haze pass applies it from the depth).
[[gnu::always_inline]] inline bool hazeInKernel(const SkyModel& sky) {
    return sky.hazeDistance > 0.0 && !(sky.hazeFalloff > 0.0);
}

// Distance haze: blends a colour (0..255 per channel) seen from `distance` metres toward the
// horizon colour by 1 - exp(-distance / hazeDistance); no change unless hazeInKernel().
[[gnu::always_inline]] inline void applyHaze(const SkyModel& sky, float rgb[3], double distance) {
    if (hazeInKernel(sky)) {
        const float k = static_cast<float>(1.0 - std::exp(-distance / sky.hazeDistance));
        rgb[0] += (sky.horizon.r - rgb[0]) * k;
        rgb[1] += (sky.horizon.g - rgb[1]) * k;
        rgb[2] += (sky.horizon.b - rgb[2]) * k;
    }
}

// A colour of 0..255 floats to bytes, rounded to nearest and clamped.
[[gnu::always_inline]] inline Rgb8 quantizeColor(const float rgb[3]) {
    auto q = [](float v) { return static_cast<std::uint8_t>(std::clamp(v + 0.5f, 0.0f, 255.0f)); };
    return Rgb8{q(rgb[0]), q(rgb[1]), q(rgb[2])};
}

// Terrain colour at world (x, y) seen from `distance` metres: bilinear map colour, hazed.
inline Rgb8 terrainColor(const TerrainMap& map, const SkyModel& sky, double x, double y,
                         double distance) {
    float c[3];
    map.surfaceColor(x, y, c);
    applyHaze(sky, c, distance);
    return quantizeColor(c);
}

}  // namespace ig
