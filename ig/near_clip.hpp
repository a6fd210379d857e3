// The near clipping plane of a view (a host's View Definition): what lies nearer the eye than
// the plane is not drawn, and each pixel shows what its ray meets beyond it.
#pragma once

#include "ig/caster.hpp"
#include "ig/lighting_pass.hpp"

#include <cmath>

namespace ig {

// Where the ray along unit direction `dir` from the camera's eye crosses the plane `nearM`
// metres ahead along the view axis (+inf for a ray that never does).
double nearPlaneRange(const Camera& camera, const glm::dvec3& dir, double nearM);

// Whether pixel (x, y) of a frame, its surface at range `depth` along the pixel-centre ray, lies
// nearer than the plane `nearM` ahead of the eye: a bound first (no pixel farther than nearM
// times the widest ratio of range to distance ahead can be), then the pixel's own ratio. Sky
// (+inf) and NaN are not nearer.
class NearerThanPlane {
  public:
    NearerThanPlane(const Intrinsics& in, double nearM)
        : f_(in.focal),
          cx_(in.cx()),
          cy_(in.cy()),
          nearM_(nearM),
          farthest_(nearM * std::hypot(in.focal, std::hypot(0.5 * in.width, 0.5 * in.height)) /
                    in.focal) {}
    bool operator()(double depth, int x, int y) const {
        if (!(depth < farthest_)) return false;
        const double dx = x + 0.5 - cx_, dy = y + 0.5 - cy_;
        return depth * f_ < nearM_ * std::sqrt(f_ * f_ + dx * dx + dy * dy);
    }

  private:
    double f_, cx_, cy_, nearM_, farthest_;
};

// Redraws, after the caster's pixels, each pixel of `frame` whose first surface lies nearer
// than frame.nearM along the view axis: the terrain where the ray enters it beyond the plane
// (entryBeyond: what the plane cuts open shows what lies behind it, or the sky), the objects'
// voxels the ray enters beyond the plane (traceObjects from there), with the reference caster's
// shading, depth and object id, one ray through the pixel's centre. Nothing changes when
// frame.nearM is 0 or no surface is that near; a redrawn pixel lies beyond the plane, so a
// second pass changes nothing. No allocation per pixel.
void clipNearer(const TerrainMap& map, const RenderOptions& options, const Camera& camera,
                RenderedFrame& frame);

// The passes every caster runs over its finished pixels: the near plane, then the sun and the
// height haze (finishLighting).
inline void finishPasses(const TerrainMap& map, const RenderOptions& options,
                         const LevelBands& bands, const Camera& camera, RenderedFrame& frame) {
    clipNearer(map, options, camera, frame);
    finishLighting(options, bands, camera, frame);
}

}  // namespace ig
