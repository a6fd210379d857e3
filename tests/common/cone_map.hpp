// A cone of slope `slope` standing on a plane, apex `peak` metres high at the centre of an n x n
// map (1 m spacing, millimetre heights), one colour: the lighting tests' known shape.
#pragma once

#include "ig/terrain.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>

namespace vig_test {

inline ig::TerrainMap coneMap(int n, double slope, double peak,
                              ig::Rgb8 color = ig::Rgb8{100, 100, 100}) {
    ig::TerrainMap map(n, n, 1.0, 1.0, 0.001, 0.0);
    const double c = 0.5 * (n - 1);
    for (int iy = 0; iy < n; ++iy) {
        for (int ix = 0; ix < n; ++ix) {
            const double r = std::hypot(ix - c, iy - c);
            map.setRaw(
                ix, iy,
                static_cast<std::uint16_t>(std::lround(std::max(0.0, peak - slope * r) / 0.001)));
            map.setColor(ix, iy, color);
        }
    }
    map.updateRange();
    return map;
}

}  // namespace vig_test
