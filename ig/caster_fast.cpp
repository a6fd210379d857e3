// Fast caster (Cohen-Or sec. 2.1): the image is cast column by column, bottom to top, each ray
// starting where the ray below it hit (vertical ray coherence), with the discrete grid march.
//
// With pitch, a column's rays are not in one vertical plane: their ground tracks fan out in
// azimuth, so the ray below may have passed beside a feature this ray meets. Coherence is used
// only where it is provably safe: where this ray's climb over the ray below outruns the most the
// terrain can rise across the gap between their tracks (the map's maximum slope bounds it).
// Elsewhere (near the nadir, where tracks fan widely or turn behind the camera, or on very steep
// maps) the ray is marched from where it enters the map. See docs/design/ray_casting.md.
#include "ig/caster_impl.hpp"
#include "ig/grid_march.hpp"
#include "ig/shading.hpp"

#include <tbb/combinable.h>
#include <tbb/parallel_for.h>
#include <glm/geometric.hpp>

#include <cmath>
#include <stdexcept>

namespace ig {
namespace {

struct ColumnCounters {
    std::uint64_t steps = 0;
    std::uint64_t restarts = 0;
};

class FastCaster final : public Caster {
  public:
    FastCaster(const TerrainMap& map, const RenderOptions& options)
        : map_(map), options_(options) {}
    CasterKind kind() const override { return CasterKind::Fast; }

    void render(const Camera& camera, RenderedFrame& frame) const override {
        if (camera.pose().roll != 0.0) {
            throw std::invalid_argument(
                "fast caster renders roll = 0 (the PRP applies roll); use naive or reference");
        }
        const int w = camera.intrinsics().width;
        tbb::combinable<ColumnCounters> counters;
        runWithThreads(options_.threads, [&] {
            // The image is a pool of columns; idle workers take the next one.
            tbb::parallel_for(0, w, [&](int x) {
                ColumnCounters& c = counters.local();
                renderColumn(camera, x, frame, c);
            });
        });
        const ColumnCounters total = counters.combine([](ColumnCounters a, ColumnCounters b) {
            return ColumnCounters{a.steps + b.steps, a.restarts + b.restarts};
        });
        frame.stats.steps = total.steps;
        frame.stats.restarts = total.restarts;
        frame.stats.rays = static_cast<std::uint64_t>(w) * camera.intrinsics().height;
    }

  private:
    void renderColumn(const Camera& camera, int x, RenderedFrame& frame,
                      ColumnCounters& counters) const {
        const int w = camera.intrinsics().width, h = camera.intrinsics().height;
        // Ray direction of row y: base + (y + 0.5) * down (unnormalised, linear in y).
        const CameraBasis& b = camera.basis();
        const double focal = camera.intrinsics().focal;
        const glm::dvec3 base = focal * b.forward + (x + 0.5 - camera.intrinsics().cx()) * b.right +
                                camera.intrinsics().cy() * b.up;
        const glm::dvec3 down = -b.up;
        const glm::dvec3 eye = camera.pose().position;
        const double maxSlope = map_.maxSlope();

        bool havePrev = false;
        double prevDist = 0.0;   // horizontal distance of the ray below's hit (or exit)
        double prevSlope = 0.0;  // its rise per horizontal metre
        glm::dvec2 prevTrack{0.0};
        std::uint64_t steps = 0, restarts = 0;
        for (int y = h - 1; y >= 0; --y) {
            const TerrainRay ray(map_, eye, base + (y + 0.5) * down);
            const std::size_t idx = static_cast<std::size_t>(y) * w + x;
            const double horiz = std::sqrt(ray.dir.x * ray.dir.x + ray.dir.y * ray.dir.y);
            const glm::dvec2 track =
                horiz > 1e-12 ? glm::dvec2{ray.dir.x, ray.dir.y} / horiz : glm::dvec2{0.0};
            const double slope = horiz > 1e-12 ? ray.dir.z / horiz : 0.0;
            double t0, t1, t = -1.0;
            if (clipToMapBox(map_, ray, t0, t1)) {
                double tStart = t0;
                if (havePrev && horiz > 1e-9) {
                    // At horizontal distance D this ray is (slope - prevSlope) * D above the ray
                    // below, and its track is at most |track - prevTrack| * D to the side, where
                    // the terrain is at most maxSlope times that higher. So it cannot meet the
                    // terrain before the ray below did when the rise beats the possible climb.
                    const double rise = slope - prevSlope;
                    const double lateral = glm::length(track - prevTrack);
                    if (glm::dot(track, prevTrack) > 0.0 && rise >= maxSlope * lateral) {
                        tStart = std::max(t0, prevDist / horiz);
                    } else {
                        ++restarts;
                    }
                }
                t = marchRay(map_, ray, tStart, t1, steps);
                prevDist = (t >= 0.0 ? t : t1) * horiz;
            } else {
                prevDist = 0.0;
            }
            havePrev = horiz > 1e-9;
            prevTrack = track;
            prevSlope = slope;
            if (t >= 0.0) {
                const glm::dvec3 p = ray.at(t);
                frame.color[idx] = terrainColor(map_, options_.sky, p.x, p.y, t);
                frame.depth[idx] = static_cast<float>(t);
            } else {
                frame.color[idx] = skyColor(options_.sky, ray.dir.z);
                frame.depth[idx] = kSkyDepth;
            }
        }
        counters.steps += steps;
        counters.restarts += restarts;
    }

    const TerrainMap& map_;
    RenderOptions options_;
};

}  // namespace

std::unique_ptr<Caster> makeFastCaster(const TerrainMap& map, const RenderOptions& options) {
    return std::make_unique<FastCaster>(map, options);
}

}  // namespace ig
