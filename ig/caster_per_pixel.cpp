// The per-pixel casters. Reference: every pixel's ray intersected exactly with the bilinear
// surface, cell by cell (slow, obviously correct; for tests and evaluation). Naive: every pixel's
// ray marched independently from the eye, one grid line per step, no coherence (the baseline).
#include "ig/caster_impl.hpp"
#include "ig/grid_march.hpp"
#include "ig/near_clip.hpp"
#include "ig/object_trace.hpp"
#include "ig/shading.hpp"
#include "ig/surface_hit.hpp"

#include <tbb/blocked_range.h>
#include <tbb/combinable.h>
#include <tbb/parallel_for.h>
#include <glm/geometric.hpp>

namespace ig {
namespace {

// Renders image row y, every pixel independently with `trace(ray, t0, t1, steps)`; honours
// any roll.
template <typename Trace>
void renderRow(const TerrainMap& map, const RenderOptions& options, const Camera& camera,
               RenderedFrame& frame, int y, std::uint64_t& steps, Trace trace) {
    const int w = camera.intrinsics().width;
    const bool objects = !options.objects.empty() && !frame.objectId.empty();
    ObjectTraceScratch scratch;
    ObjectShading shading;
    for (int x = 0; x < w; ++x) {
        const TerrainRay ray(map, camera.pose().position, camera.rayDirection(x + 0.5, y + 0.5));
        const std::size_t idx = static_cast<std::size_t>(y) * w + x;
        double t0, t1, t = -1.0;
        if (clipToMapBox(map, ray, t0, t1)) t = trace(ray, t0, t1, steps);
        shadeReferencePixel(map, options, ray, t, 0.0, objects, frame, idx, scratch, shading);
    }
}

// Every row of the frame, rows taken by the workers of the caster's thread count.
template <typename Trace>
void renderPerPixel(const TerrainMap& map, const RenderOptions& options, const Camera& camera,
                    RenderedFrame& frame, Trace trace) {
    const int w = camera.intrinsics().width, h = camera.intrinsics().height;
    if (!options.objects.empty()) frame.objectId.assign(static_cast<std::size_t>(w) * h, 0);
    tbb::combinable<std::uint64_t> steps([] { return std::uint64_t{0}; });
    runWithThreads(options.threads, [&] {
        tbb::parallel_for(tbb::blocked_range<int>(0, h), [&](const tbb::blocked_range<int>& rows) {
            std::uint64_t localSteps = 0;
            for (int y = rows.begin(); y < rows.end(); ++y) {
                renderRow(map, options, camera, frame, y, localSteps, trace);
            }
            steps.local() += localSteps;
        });
    });
    frame.stats.steps = steps.combine(std::plus<>());
    frame.stats.rays = static_cast<std::uint64_t>(w) * h;
}

class ReferenceCaster final : public Caster {
  public:
    ReferenceCaster(const TerrainMap& map, const RenderOptions& options)
        : map_(map), options_(options) {}
    CasterKind kind() const override { return CasterKind::Reference; }
    void render(const Camera& camera, RenderedFrame& frame) const override {
        renderPerPixel(map_, options_, camera, frame, trace());
        finishFrame(camera, frame);
    }
    void finishFrame(const Camera& camera, RenderedFrame& frame) const override {
        finishPasses(map_, options_, LevelBands{}, camera, frame);
    }
    int workUnits(const Camera& camera) const override { return camera.intrinsics().height; }
    void renderUnit(const Camera& camera, RenderedFrame& frame, int unit,
                    UnitCounters& counters) const override {
        renderRow(map_, options_, camera, frame, unit, counters.steps, trace());
    }

  private:
    struct Trace {
        const TerrainMap* map;
        double operator()(const TerrainRay& ray, double t0, double t1, std::uint64_t& steps) const {
            return exactHitInRange(*map, ray, t0, t1, &steps);
        }
    };
    Trace trace() const { return Trace{&map_}; }

    const TerrainMap& map_;
    RenderOptions options_;
};

class NaiveCaster final : public Caster {
  public:
    NaiveCaster(const TerrainMap& map, const RenderOptions& options)
        : map_(map), options_(options) {}
    CasterKind kind() const override { return CasterKind::Naive; }
    void render(const Camera& camera, RenderedFrame& frame) const override {
        renderPerPixel(map_, options_, camera, frame, trace());
        finishFrame(camera, frame);
    }
    void finishFrame(const Camera& camera, RenderedFrame& frame) const override {
        finishPasses(map_, options_, LevelBands{}, camera, frame);
    }
    int workUnits(const Camera& camera) const override { return camera.intrinsics().height; }
    void renderUnit(const Camera& camera, RenderedFrame& frame, int unit,
                    UnitCounters& counters) const override {
        renderRow(map_, options_, camera, frame, unit, counters.steps, trace());
    }

  private:
    struct Trace {
        const TerrainMap* map;
        double operator()(const TerrainRay& ray, double t0, double t1, std::uint64_t& steps) const {
            return marchRay(*map, ray, t0, t1, steps);
        }
    };
    Trace trace() const { return Trace{&map_}; }

    const TerrainMap& map_;
    RenderOptions options_;
};

}  // namespace

std::unique_ptr<Caster> makeNaiveCaster(const TerrainMap& map, const RenderOptions& options) {
    return std::make_unique<NaiveCaster>(map, options);
}

std::unique_ptr<Caster> makeReferenceCaster(const TerrainMap& map, const RenderOptions& options) {
    return std::make_unique<ReferenceCaster>(map, options);
}

}  // namespace ig
