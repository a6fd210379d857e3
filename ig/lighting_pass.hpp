// Sun lighting applied when a frame is made (deferred): mean normals per display level, a sun
// that follows the simulated clock, and the pass that lights a finished frame from its depth
// with the haze recomposed exactly (docs/design/appearance.md).
#pragma once

#include "ig/appearance.hpp"
#include "ig/caster.hpp"
#include "ig/frame.hpp"
#include "ig/haze_pass.hpp"

#include <limits>
#include <memory>
#include <vector>

namespace ig {

// Normals of a map at every display level: level 0 holds each sample's unit normal (central
// differences, as TerrainLighting), level k + 1 the [1 2 1] x [1 2 1] / 16 mean of level k's
// around the same point (the display pyramid's filter, so level k's sample covers the same
// ground as its colour), NOT renormalised: Lambert of the mean normal is the mean of the
// samples' Lambert terms wherever none faces away from the sun.
class TerrainNormals {
  public:
    explicit TerrainNormals(const TerrainMap& map);
    int levelCount() const { return static_cast<int>(levels_.size()); }
    int width(int k) const { return levels_[k].width; }
    int height(int k) const { return levels_[k].height; }
    // Three floats (x east, y north, z up) per sample, row-major, rows south first.
    const float* samples(int k) const { return levels_[k].normals.data(); }
    double spacingX() const { return spacingX_; }
    double spacingY() const { return spacingY_; }
    // Bilinear normal of level k at world (x, y) (clamped to the map).
    void normalAt(int k, double x, double y, float n[3]) const;

  private:
    struct Level {
        int width = 0, height = 0;
        LargeVector<float> normals;
    };
    std::vector<Level> levels_;
    double spacingX_ = 1.0, spacingY_ = 1.0;
};

// The sun as a function of simulated time t (seconds; a frame's `time`).
struct SunClock {
    Sun sun;                   // at t = 0 (fixed sun mode)
    double azimuthRate = 0.0;  // fixed sun mode: radians of azimuth per second, clockwise
    // Almanac mode: the sun over (latitudeDeg, longitudeDeg) at J2000 day `days` + t * speed.
    bool almanac = false;
    double latitudeDeg = 0.0, longitudeDeg = 0.0, days = 0.0;
    double speed = 1.0;  // sun seconds per simulated second
    Sun at(double t) const;
};

// What the pass needs: the normals, the sun, how light scales the colour.
//   ramp (photo = false):  out = albedo * (ambient + (1 - ambient) * max(0, n . s))
//   photo (photo = true):  the same factor divided by its value on flat ground (shading boost)
struct SunLighting {
    std::shared_ptr<const TerrainNormals> normals;
    SunClock clock;
    double ambient = 0.3;
    bool photo = false;
    // Normals of level 0 at every distance instead of the level the caster used there.
    bool levelZeroNormals = false;
};

// The levels a caster drew at each horizontal distance D from the eye: band k covers
// [d0 * 2^k, d0 * 2^(k+1)) and blends toward level k + 1 with weight D / (d0 * 2^k) - 1; band
// topLevel extends to infinity unblended (the multiresolution march's rule). d0 = +inf: level 0
// everywhere.
struct LevelBands {
    double d0 = std::numeric_limits<double>::infinity();
    int topLevel = 0;
};

// Lights a finished frame in place. The caster wrote colour = a (1 - f) + h f (a the albedo,
// h the horizon colour, f = 1 - exp(-depth / hazeDistance), 0 without haze or with a height
// fall-off, which hazeFrame applies after the light); each terrain pixel
// becomes h f + L (colour - h f), L the light at its hit point (pixel centre ray at its depth)
// under lighting.clock.at(frame.time). Sky (depth +inf), pixels with NaN, negative or infinite
// depth and pixels of voxel objects (objectId != 0) are left as they are. Rows go to the
// library's workers (`threads` as RenderOptions::threads); the image does not depend on them.
void lightFrame(const SunLighting& lighting, const SkyModel& sky, const LevelBands& bands,
                const Camera& camera, RenderedFrame& frame, int threads = 0);
// The same, one pixel at a time in double precision from the camera's ray for each pixel: the
// slow twin tests compare lightFrame with (within one grey level).
void lightFrameReference(const SunLighting& lighting, const SkyModel& sky, const LevelBands& bands,
                         const Camera& camera, RenderedFrame& frame);

// The light factor L at world (x, y) seen from horizontal distance `horizontal` (which picks
// the level) under `sun`: what lightFrame multiplies by.
double lightFactor(const SunLighting& lighting, const LevelBands& bands, const Sun& sun, double x,
                   double y, double horizontal);

// A caster's passes over the finished frame: lights it when options.lighting is set, then
// hazes it when the haze has a height fall-off (the casters drew it without haze).
inline void finishLighting(const RenderOptions& options, const LevelBands& bands,
                           const Camera& camera, RenderedFrame& frame) {
    if (options.lighting)
        lightFrame(*options.lighting, options.sky, bands, camera, frame, options.threads);
    hazeFrame(options.sky, camera, frame, options.threads);
}
// Whether finishLighting changes a frame.
inline bool finishPassesOn(const RenderOptions& options) {
    return options.lighting != nullptr || deferredHaze(options.sky);
}

}  // namespace ig
