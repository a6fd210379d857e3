// Factories of the individual casters (internal to ig).
#pragma once

#include "ig/caster.hpp"
#include "ig/lighting_pass.hpp"
#include "ig/object_trace.hpp"
#include "ig/shading.hpp"
#include "ig/surface_hit.hpp"

#include <memory>

namespace ig {

std::unique_ptr<Caster> makeReferenceCaster(const TerrainMap& map, const RenderOptions& options);
std::unique_ptr<Caster> makeNaiveCaster(const TerrainMap& map, const RenderOptions& options);
class TerrainPyramid;

// `pyramid`, when given, is shared instead of built (it must have been built from `map` with
// `options.levels`).
std::unique_ptr<Caster> makeFastCaster(const TerrainMap& map, const RenderOptions& options,
                                       std::shared_ptr<const TerrainPyramid> pyramid = nullptr);
std::unique_ptr<Caster> makeSpanCaster(const TerrainMap& map, const RenderOptions& options);
// Fast casters for 1..supersampleMax rays per pixel, one picked per frame by autoSupersample.
std::unique_ptr<Caster> makeAutoSupersampleCaster(const TerrainMap& map,
                                                  const RenderOptions& options);

// A frame of the view's size, pose, time and sequence, pixels to be cast (validates the view).
RenderedFrame newFrame(const TerrainMap& map, const Pose& pose, const Intrinsics& intrinsics,
                       double time, std::uint64_t sequence);

// Throws InputError for a near plane that is negative or not finite (0: none).
void checkNearPlane(double nearM);
// Renders the pixels of `frame` (made by newFrame) with `caster`, its time and kernel in stats.
void renderPixels(const Caster& caster, const Camera& camera, RenderedFrame& frame);

// The frame's nine control points, each cast exactly through its pixel centre.
void castControlPoints(const TerrainMap& map, const Camera& camera, RenderedFrame& frame);

// The reference caster's pixel `i` of `frame` for `ray`: the terrain at its hit t (negative:
// the sky), then, when `objects`, the objects' voxels the ray enters from `tStart` on to it,
// composed over it (their id, and the depth of the first).
inline void shadeReferencePixel(const TerrainMap& map, const RenderOptions& options,
                                const TerrainRay& ray, double t, double tStart, bool objects,
                                RenderedFrame& frame, std::size_t i, ObjectTraceScratch& scratch,
                                ObjectShading& shading) {
    if (t >= 0.0) {
        const glm::dvec3 p = ray.at(t);
        frame.color[i] = terrainColor(map, options.sky, p.x, p.y, t);
        frame.depth[i] = static_cast<float>(t);
    } else {
        frame.color[i] = skyColor(options.sky, ray.dir.z);
        frame.depth[i] = kSkyDepth;
    }
    if (!objects) return;
    traceObjects(options.objects, ray.origin, ray.dir, t >= 0.0 ? t : kSkyDepth, options.sky,
                 scratch, shading, tStart);
    frame.color[i] = composeOver(shading, frame.color[i]);
    frame.objectId[i] = shading.id;
    if (shading.id != 0) frame.depth[i] = static_cast<float>(shading.depth);
}

}  // namespace ig

#include <tbb/task_arena.h>

namespace ig {

// Runs f with at most `threads` workers (0: the library's default).
template <typename F>
void runWithThreads(int threads, F&& f) {
    if (threads <= 0) {
        f();
        return;
    }
    tbb::task_arena arena(threads);
    arena.execute(f);
}

}  // namespace ig
