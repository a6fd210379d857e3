// The slow straight flight the level-blending tests fly: frame-to-frame mean absolute colour
// difference (per cent) of a caster's frames, 6 m apart diagonally at 250 m over a map's
// (1500, 1500), pitch -4 degrees, 160x90 pixels. A wave or a popping level shows as a spike.
#pragma once

#include "ig/caster.hpp"
#include "ig/image_compare.hpp"

#include <algorithm>
#include <vector>

namespace vig_test {

inline std::vector<double> slowFlightDifferences(const ig::Caster& caster,
                                                 const ig::TerrainMap& map, int frames) {
    const ig::Intrinsics in = ig::Intrinsics::fromFov(160, 90, ig::degToRad(60));
    std::vector<double> diffs;
    std::vector<ig::Rgb8> prev;
    for (int i = 0; i < frames; ++i) {
        ig::Pose pose;
        pose.position = {1500.0 + 6.0 * i, 1500.0 + 6.0 * i, 0.0};
        pose.position.z = 250.0 + map.surfaceHeight(1500.0, 1500.0);
        pose.yaw = ig::degToRad(45.0);
        pose.pitch = ig::degToRad(-4.0);
        auto frame = ig::renderFrame(caster, map, pose, in);
        if (!prev.empty()) diffs.push_back(ig::meanAbsErrorPct(frame.color, prev));
        prev = std::move(frame.color);
    }
    return diffs;
}

inline double median(std::vector<double> v) {
    std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
    return v[v.size() / 2];
}

}  // namespace vig_test
