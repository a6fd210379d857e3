// Command-line pieces every program shares: terrain flags, image size and pose parsing.
#pragma once

#include "ig/camera.hpp"
#include "ig/terrain.hpp"

#include <CLI/CLI.hpp>

#include <functional>
#include <optional>
#include <string>
#include <utility>

namespace ig {

// Terrain flags: --height FILE [--color FILE] [--spacing M] [--height-scale M]
// [--height-offset M], or --synthetic SIZE[:SEED]. Neither: the shipped Puget Sound map.
struct TerrainOptions {
    std::string height;
    std::string color;
    std::optional<double> spacing;
    std::optional<double> heightScale;
    std::optional<double> heightOffset;
    std::optional<double> voidHeight;
    std::string synthetic;
};

void addTerrainOptions(CLI::App& app, TerrainOptions& options);
// Loads what the flags name; throws InputError. The numbers are checked first against ranges
// that make physical sense (spacing 1 mm..100 km, height scale 1e-6..1e4 m per unit, offset and
// void height within +-100 km).
TerrainMap loadTerrainFromOptions(const TerrainOptions& options);
// One line describing a loaded map, for logs.
std::string describeTerrain(const TerrainMap& map);

// "WxH" -> {W, H}; throws InputError naming `what`.
std::pair<int, int> parseSize(const std::string& text, const std::string& what = "--size");
// "x,y,z,yaw,pitch,roll" in metres and degrees; z written "+H" means H metres above the terrain
// under (x, y). Throws InputError naming `what`.
Pose parsePose(const std::string& text, const TerrainMap& map, const std::string& what = "--pose");
// A view of any map when the user names none: over the south-west quarter, 15 % of the relief
// and 50 m above the ground (and at least 60 % of the relief above the lowest point), heading for
// the far corner, 8 degrees down. Stick flights over such maps start there too.
Pose defaultViewPose(const TerrainMap& map);

// Runs a program's body: an InputError prints "NAME: message" and exits 2, any other exception
// prints "NAME: error: message" and exits 1; otherwise the body's own exit code.
int runProgram(const char* name, const std::function<int()>& body);
}  // namespace ig
