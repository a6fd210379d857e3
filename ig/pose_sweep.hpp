// A deterministic sweep of camera poses over a map, for accuracy tests and evaluation tools.
#pragma once

#include "ig/camera.hpp"
#include "ig/terrain.hpp"

#include <vector>

namespace ig {

// `count` poses (count >= 2) over the map's interior: headings covering 0..360 degrees, pitch
// from +10 to -85 degrees, altitude above the terrain from 5 m to 20 km (log-spaced), roll 0.
// The three sweeps are interleaved with different strides so every combination region is hit.
std::vector<Pose> sweepPoses(const TerrainMap& map, int count);

}  // namespace ig
