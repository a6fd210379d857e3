// Terrain loading: height and colour images (PNG, JPEG, GeoTIFF and other GDAL rasters) ->
// TerrainMap.
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "ig/terrain.hpp"

namespace ig {

// Largest image accepted, samples (width x height): the renderer's map limit.
inline constexpr std::size_t kMaxImageSamples = std::size_t{1} << 30;
// Largest map a terrain database pages (its arrays are address space reserved, not memory).
inline constexpr std::size_t kMaxPagedSamples = std::size_t{1} << 36;

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
    // Largest height or colour image accepted, samples; a header claiming more is refused before
    // anything is allocated for it.
    std::size_t maxSamples = kMaxImageSamples;
    // A file's bytes when they are already in memory (non-empty): decoded as the file would be,
    // its path only naming it in messages (no world file or other file beside it is looked for).
    // Pipes and other files that cannot seek are read into memory by the loader itself.
    std::span<const std::uint8_t> heightBytes, colorBytes;
};

// Fills the samples of a w x h grid (rows contiguous) whose `valid` entry is 0 from the valid
// ones around them, smoothly: push-pull over a pyramid of 2 x 2 means of the valid samples
// (each level's holes take the bilinear interpolation of the next coarser level). Valid samples
// are left as they are. Returns how many were filled. At least one valid sample and sizes that
// agree are the caller's to ensure (CHECKed).
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

// The WGS 84 latitude and longitude (degrees) of a georeferenced map's sample (0, 0), through
// GDAL/PROJ; empty when the map has no georeference or it cannot be transformed.
std::optional<std::array<double, 2>> geodeticOrigin(const Georeference& georeference);

// Length of one degree on the WGS84 ellipsoid at geodetic latitude `latitude` (radians), metres.
double metresPerDegreeLatitude(double latitude);
double metresPerDegreeLongitude(double latitude);

}  // namespace ig
