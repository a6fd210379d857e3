#include "ig/near_clip.hpp"

#include "ig/caster_impl.hpp"
#include "ig/object_trace.hpp"
#include "ig/shading.hpp"
#include "ig/surface_hit.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <glm/geometric.hpp>

#include <cmath>
#include <limits>

namespace ig {

double nearPlaneRange(const Camera& camera, const glm::dvec3& dir, double nearM) {
    const double c = glm::dot(dir, camera.basis().forward);
    return c > 0.0 ? nearM / c : std::numeric_limits<double>::infinity();
}

void clipNearer(const TerrainMap& map, const RenderOptions& options, const Camera& camera,
                RenderedFrame& frame) {
    const double nearM = frame.nearM;
    if (!(nearM > 0.0)) return;
    const Intrinsics& in = camera.intrinsics();
    const int w = in.width, h = in.height;
    // A point of range d along the ray through pixel offset (dx, dy) from the centre lies
    // d f / sqrt(f^2 + dx^2 + dy^2) ahead.
    const NearerThanPlane nearer(in, nearM);
    const bool ids = !options.objects.empty() && frame.objectId.size() == frame.depth.size();
    runWithThreads(options.threads, [&] {
        tbb::parallel_for(tbb::blocked_range<int>(0, h), [&](const tbb::blocked_range<int>& rows) {
            ObjectTraceScratch scratch;
            ObjectShading shading;
            for (int y = rows.begin(); y < rows.end(); ++y) {
                for (int x = 0; x < w; ++x) {
                    const std::size_t i = static_cast<std::size_t>(y) * w + x;
                    if (!nearer(frame.depth[i], x, y)) continue;
                    // The reference caster's pixel, from the plane on.
                    const TerrainRay ray(map, camera.pose().position,
                                         camera.rayDirection(x + 0.5, y + 0.5));
                    const double tNear = nearPlaneRange(camera, ray.dir, nearM);
                    const double t =
                        entryBeyond(map, ray, tNear, std::numeric_limits<double>::infinity());
                    shadeReferencePixel(map, options, ray, t, tNear, ids, frame, i, scratch,
                                        shading);
                }
            }
        });
    });
}

}  // namespace ig
