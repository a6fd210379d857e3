// Camera poses for accuracy tests and evaluation tools: a deterministic sweep over a map, or a
// list read from a file.
#pragma once

#include "ig/camera.hpp"
#include "ig/terrain.hpp"

#include <string>
#include <string_view>
#include <vector>

namespace ig {

// `count` poses (count >= 2) over the map's interior: headings covering 0..360 degrees, pitch
// from +10 to -85 degrees, altitude above the terrain from 5 m to 20 km (log-spaced), roll 0.
// The three sweeps are interleaved with different strides so every combination region is hit.
std::vector<Pose> sweepPoses(const TerrainMap& map, int count);

// A pose list: one x,y,z,yaw,pitch,roll per line (metres, degrees; z written +H is H above the
// terrain under x,y); spaces are ignored, '#' starts a comment, blank lines are skipped. Throws
// InputError naming `name` and the line ("NAME line N: ...") when a line is bad or there is no
// pose, quoting at most a bounded part of the line. `lines`, when given, receives the line
// number of each pose.
std::vector<Pose> parsePoseList(std::string_view text, const TerrainMap& map,
                                const std::string& name, std::vector<int>* lines = nullptr);

}  // namespace ig
