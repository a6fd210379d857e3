// Sun lighting of terrain (a colour ramp by elevation, normals from the heights, Lambert at a
// sun that can change without reloading), the sun's position from a date and time, and the
// per-frame choice of vertical rays per pixel from the pitch (docs/design/appearance.md).
#pragma once

#include "ig/camera.hpp"
#include "ig/terrain.hpp"

#include <glm/vec3.hpp>

#include <string>

namespace ig {

// A sun: azimuth clockwise from north (toward east), elevation above the horizon; radians.
struct Sun {
    double azimuth = 0.0;
    double elevation = 0.0;
};

// Unit vector toward the sun (x east, y north, z up).
glm::dvec3 sunDirection(const Sun& sun);

// The sun seen from latitude/longitude (degrees, north and east positive) at a UTC instant
// (days since 2000-01-01 12:00 UTC, J2000), by the NOAA low-precision solar position (about
// 0.01 degree over 1950..2050; no refraction).
Sun sunAt(double latitudeDeg, double longitudeDeg, double daysSinceJ2000);
// "YYYY-MM-DD,HH:MM[:SS]" (UTC) -> days since J2000; throws InputError naming `what`.
double parseUtcDateTime(const std::string& text, const std::string& what);

// Natural colours by elevation in metres, for terrain without a photo: water blue at the map's
// lowest level where it is flat, lowland green, forest, rock, snow above about 2900 m. Maps
// with little relief (under 300 m) spread the same ramp over their own range instead.
LargeVector<Rgb8> elevationRampAlbedo(const TerrainMap& map);
// The same ramp over `map` with the range and water level of `rangeOf` (a map nested in it, as
// an inset: both then take the same colour at the same height).
LargeVector<Rgb8> elevationRampAlbedo(const TerrainMap& map, const TerrainMap& rangeOf);

// The lighting of one map: its albedo (a ramp or the photo) and a unit normal per sample from
// central differences of the heights, kept so a new sun only re-lights (no reload, no normals
// again). relight() writes the map's colours:
//   ramp:  albedo * (ambient + (1 - ambient) * max(0, n . s))
//   photo: albedo * that / (the same for flat ground), a shading boost that leaves flat ground
//          as photographed (clamped to 255).
// The display pyramid averages the lit colours, so each coarser level shows the mean radiance
// of its samples (what supersampling converges to) rather than a light from a smoothed normal.
class TerrainLighting {
  public:
    enum class Albedo { Ramp, Photo };
    TerrainLighting(const TerrainMap& map, Albedo albedo, double ambient = 0.3);
    void relight(TerrainMap& map, const Sun& sun) const;
    // Light of one sample under `sun` (the factor relight multiplies the ramp albedo by).
    double light(int ix, int iy, const Sun& sun) const;

  private:
    int width_ = 0, height_ = 0;
    Albedo kind_;
    double ambient_;
    LargeVector<Rgb8> albedo_;
    LargeVector<float> normals_;  // 3 per sample
};

// Vertical rays per pixel for a view (the "auto" supersample): a pixel whose ray meets flat
// ground at depression d below the horizon covers 1 / sin(d) times as much ground along the
// view as across it (Cohen-Or sec. 2). The frame takes the depression halfway (in angle) through
// the part of the image that looks below the horizon, and casts ceil(stretch / 2) rays, at
// most `maxRays`; 1 when no row looks down or the view is steep (stretch <= 2, pitch below
// about -30 degrees for a 60 x 40 degree view).
int autoSupersample(const Pose& pose, const Intrinsics& intrinsics, int maxRays);
// The stretch that rule uses (1 / sin of that depression; +inf when no row looks down).
double footprintStretch(const Pose& pose, const Intrinsics& intrinsics);

}  // namespace ig
