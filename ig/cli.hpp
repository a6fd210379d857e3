// Command-line pieces every program shares: terrain flags, image size and pose parsing.
#pragma once

#include "ig/appearance.hpp"
#include "ig/camera.hpp"
#include "ig/caster.hpp"
#include "ig/inset.hpp"
#include "ig/lighting_pass.hpp"
#include "ig/terrain.hpp"
#include "ig/terrain_db.hpp"
#include "ig/terrain_io.hpp"

#include <CLI/CLI.hpp>

#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace ig {

// Terrain flags: --height FILE [--color FILE] [--spacing M] [--height-scale M]
// [--height-offset M], or --synthetic SIZE[:SEED], or --db FILE [--cache-mb N] (a terrain
// database from ig-build-db, loaded whole when it fits the budget, else paged where the
// program can). None: the shipped Puget Sound map.
struct TerrainOptions {
    std::string height;
    std::string color;
    std::optional<double> spacing;
    std::optional<double> heightScale;
    std::optional<double> heightOffset;
    std::optional<double> voidHeight;
    std::string synthetic;
    std::string db;
    double cacheMb = 4096;
};
// Whether the flags name no map (the shipped one is used).
bool usesShippedMap(const TerrainOptions& options);

void addTerrainOptions(CLI::App& app, TerrainOptions& options);
// --db with other terrain flags, or a --cache-mb out of range: InputError.
void checkDatabaseOptions(const TerrainOptions& options);
// Memory a database's map takes loaded whole (heights, colours, maxima, pyramid), MB; and
// whether that is over --cache-mb (the map is then rendered paged, or refused).
double databaseMemoryMb(const TerrainDb& db);
bool databaseNeedsPaging(const TerrainOptions& options, const TerrainDb& db);
// Loads what the flags name; throws InputError. The numbers are checked first against ranges
// that make physical sense (spacing 1 mm..100 km, height scale 1e-6..1e4 m per unit, offset and
// void height within +-100 km).
TerrainMap loadTerrainFromOptions(const TerrainOptions& options);
// --synthetic SIZE[:SEED] parsed and checked (SIZE up to maxSize), with --spacing (default
// 10 m); empty when the flag is not given. Throws InputError.
struct SyntheticSpec {
    int size = 0;
    std::uint64_t seed = 1;
    double spacing = 10.0;
};
std::optional<SyntheticSpec> parseSyntheticOption(const TerrainOptions& options, int maxSize);
// The files the flags name, the numbers checked; empty when no --height is given.
std::optional<TerrainSource> terrainSourceFromOptions(const TerrainOptions& options);
// One line describing a loaded map, for logs.
std::string describeTerrain(const TerrainMap& map);

// High-resolution insets (docs/design/insets.md), repeatable:
//   --inset synthetic:X,Y,CX,CY,FACTOR   the synthetic generator's samples over global cells
//                                        [X, X + CX) x [Y, Y + CY), FACTOR times finer (with
//                                        --synthetic: the same seed)
//   --inset HEIGHT[,COLOR]@X,Y,FACTOR    a raster (any --height format) whose first sample lies
//                                        on global sample (X, Y), at the global spacing / FACTOR
//   --inset HEIGHT[,COLOR]               a georeferenced raster in the global map's CRS, placed
//                                        by its georeference (on a global sample, at the global
//                                        spacing over a power of two)
//   --inset-blend CELLS                  fine cells over which an inset's rim blends into the
//                                        global terrain (default 16)
// A raster is cut to whole global cells. The height scale and offset flags apply to both.
struct InsetOptions {
    std::vector<std::string> specs;
    int blendCells = 16;
    bool any() const { return !specs.empty(); }
};
void addInsetOptions(CLI::App& app, InsetOptions& options);
// Nests the insets the flags name into `global` (loaded from `terrain`). Throws InputError
// naming the --inset and what is wrong.
NestedTerrain loadNestedTerrain(TerrainMap global, const TerrainOptions& terrain,
                                const InsetOptions& insets);
// The inset sources the flags name over a global map of `global`'s grid and georeference
// (synthetic insets take --synthetic's seed and spacing, its size up to `syntheticLimit`).
std::vector<InsetSource> insetSources(const GlobalGrid& global, const Georeference& geo,
                                      const TerrainOptions& terrain, const InsetOptions& insets,
                                      int syntheticLimit);
// Whether --db names a database holding insets (loadNestedTerrain nests them).
bool databaseHasInsets(const TerrainOptions& terrain);

// Appearance flags every rendering program shares (docs/design/appearance.md):
//   --haze METRES|auto         distance for a 63 % blend to the horizon colour (0: off; auto: a
//                              quarter of the map's larger extent)
//   --haze-falloff METRES      height fall-off of the haze: density exp(-z / H), the haze
//                              distance holding at z = 0 (0: off, the plain distance haze)
//   --supersample N|auto[:MAX] vertical rays per pixel, fixed or chosen per frame from the pitch
//   --colors image|ramp|auto   the colour image (or, without one, the heights shaded at load by
//                              a fixed sun), or the elevation colour ramp lit by --sun (auto:
//                              an image given with --color, else the ramp)
//   --sun AZ,EL                sun azimuth (clockwise from north) and elevation, degrees; lights
//                              terrain without a colour image (the ramp); with one, only --shade
//   --sun-time DATE,TIME[,LAT,LON]  the sun at a UTC instant seen from LAT,LON (degrees; the
//                              shipped map's centre when omitted over it)
//   --shade                    the sun also shades the colour image (flat ground unchanged)
//   --sun-rate DEG_PER_S       the sun moves with the frames' simulated time: with --sun its
//                              azimuth turns at this rate; with --sun-time the clock runs at
//                              this many degrees of the Earth's turn per second (default: real
//                              time, 15 degrees an hour)
// The sun lights each frame as it is made (ig/lighting_pass.hpp): a sun that moves costs no
// rebuild.
// The defaults are the program's: `defaults` as given before parsing.
struct AppearanceOptions {
    std::string haze = "0";
    std::string hazeFalloff = "0";
    std::string supersample = "1";
    std::string colors = "image";
    std::string sun;
    std::string sunTime;
    std::string sunRate;
    bool shade = false;
};
void addAppearanceOptions(CLI::App& app, AppearanceOptions& options);
// What the flags asked for, parsed and checked (InputError naming the flag).
struct Appearance {
    double hazeDistance = 0.0;
    double hazeFalloff = 0.0;  // scale height, metres (0: off)
    int supersample = 1;       // kSupersampleAuto: per frame
    int supersampleMax = 4;
    bool ramp = false;       // colour by the elevation ramp
    std::optional<Sun> sun;  // lighting on when set: the sun at time 0
    SunClock sunClock;       // the sun at any frame time (sunClock.at(0) == *sun)
    bool shade = false;      // the sun shades the colour image too
};
Appearance parseAppearance(const AppearanceOptions& options, const TerrainOptions& terrain,
                           const TerrainMap& map);
// Applies it: the ramp's albedo into `map` when it asks for the ramp, the haze, supersampling
// and sun lighting (the normals of `map`) of `render`.
void applyAppearance(const Appearance& appearance, TerrainMap& map, RenderOptions& render);
// The same over a terrain with insets: the ramp over every map, the lighting by the global
// map's normals (the nested caster lights each inset by its own).
void applyAppearance(const Appearance& appearance, NestedTerrain& terrain, RenderOptions& render);
// Whether the terrain flags give a colour image (the shipped map's included).
bool terrainHasImage(const TerrainOptions& terrain);
// The shipped map's centre, degrees (for --sun-time without LAT,LON).
inline constexpr double kPugetSoundLatitude = 46.88, kPugetSoundLongitude = -122.36;

// "WxH" -> {W, H}; throws InputError naming `what`.
std::pair<int, int> parseSize(const std::string& text, const std::string& what = "--size");
// "x,y,z,yaw,pitch,roll" in metres and degrees; z written "+H" means H metres above the ground
// under (x, y) (a map's surface, or a nested terrain's). Throws InputError naming `what`.
Pose parsePose(const std::string& text, const Ground& ground, const std::string& what = "--pose");
// A view of any map when the user names none: over the south-west quarter, 15 % of the relief
// and 50 m above the ground (and at least 60 % of the relief above the lowest point), heading for
// the far corner, 8 degrees down. Stick flights over such maps start there too.
Pose defaultViewPose(const TerrainMap& map);

// Runs a program's body: an InputError prints "NAME: message" and exits 2, any other exception
// prints "NAME: error: message" and exits 1; otherwise the body's own exit code.
int runProgram(const char* name, const std::function<int()>& body);
}  // namespace ig
