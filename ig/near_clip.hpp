// The near clipping plane of a view (a host's View Definition): what lies nearer the eye than
// the plane is not drawn, and each pixel shows what its ray meets beyond it.
#pragma once

#include "ig/caster.hpp"
#include "ig/lighting_pass.hpp"

namespace ig {

// Where the ray along unit direction `dir` from the camera's eye crosses the plane `nearM`
// metres ahead along the view axis (+inf for a ray that never does).
double nearPlaneRange(const Camera& camera, const glm::dvec3& dir, double nearM);

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
