// Terrain loading: height and colour images (PNG, JPEG, GeoTIFF and other GDAL rasters) ->
// TerrainMap.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "ig/terrain.hpp"

namespace ig {

// What the user named on the command line. docs/formats.md describes the formats and conventions.
struct TerrainSource {
    std::string heightPath;         // PNG (8/16-bit grey), grey JPEG, or any GDAL raster (band 1)
    std::string colorPath;          // optional RGB or grey image; empty -> shaded from the heights
    std::optional<double> spacing;  // metres between samples; overrides the georeference
    std::optional<double> heightScale;   // metres per raw unit (default 1)
    std::optional<double> heightOffset;  // metres added (default 0)
    // Height (metres) given to the samples the file marks as having no data (its no-data value,
    // its mask, NaN); unset: they are interpolated from the samples around them (fillVoids).
    std::optional<double> voidHeight;
};

// Fills the samples of a w x h grid (rows contiguous) whose `valid` entry is 0 from the valid
// ones around them, smoothly: push-pull over a pyramid of 2 x 2 means of the valid samples
// (each level's holes take the bilinear interpolation of the next coarser level). Valid samples
// are left as they are. Returns how many were filled; throws std::invalid_argument when there is
// no valid sample or the sizes disagree.
std::size_t fillVoids(std::vector<double>& values, const std::vector<std::uint8_t>& valid, int w,
                      int h);

// Default spacing when neither the user nor the file gives one, metres.
inline constexpr double kDefaultSpacing = 10.0;

// Loads a terrain; throws InputError naming the file and the problem.
TerrainMap loadTerrain(const TerrainSource& src);
// The shipped Puget Sound map: 1025 x 1025 heights at 160 m, 0.1 m per unit, hypsometric texture.
TerrainMap loadPugetSound();
// The shipped Goleta map: 512 x 512 float GeoTIFF heights and an RGB orthophoto, WGS84.
TerrainMap loadGoleta();

// Length of one degree on the WGS84 ellipsoid at geodetic latitude `latitude` (radians), metres.
double metresPerDegreeLatitude(double latitude);
double metresPerDegreeLongitude(double latitude);

}  // namespace ig
