// The fast caster with vertical rays per pixel chosen per frame from the view's pitch.
#include "ig/appearance.hpp"
#include "ig/caster_impl.hpp"
#include "ig/error.hpp"
#include "ig/pyramid.hpp"

#include <memory>
#include <string>
#include <vector>

namespace ig {

namespace {

// One fast caster per ray count, all on one pyramid (it does not depend on the ray count); a
// frame goes to the one its pose asks for. The
// choice is a function of the camera alone, so every work unit of a frame agrees on it.
class AutoSupersampleCaster final : public Caster {
  public:
    AutoSupersampleCaster(const TerrainMap& map, const RenderOptions& options) {
        if (options.supersampleMax < 1 || options.supersampleMax > 8) {
            throw InputError("supersample auto: at most " + std::to_string(options.supersampleMax) +
                             " rays per pixel; expected 1..8");
        }
        if (options.levels < kLevelsAuto) {  // as the fast caster, before the pyramid is built
            throw InputError("levels " + std::to_string(options.levels) +
                             ": expected auto or a count >= 0");
        }
        const auto pyramid = options.pyramid
                                 ? options.pyramid
                                 : std::make_shared<const TerrainPyramid>(map, options.levels);
        for (int n = 1; n <= options.supersampleMax; ++n) {
            RenderOptions o = options;
            o.supersample = n;
            casters_.push_back(makeFastCaster(map, o, pyramid));
        }
    }
    CasterKind kind() const override { return CasterKind::Fast; }
    std::string_view kernelName() const override { return casters_.front()->kernelName(); }

    void render(const Camera& camera, RenderedFrame& frame) const override {
        pick(camera).render(camera, frame);
    }
    void finishFrame(const Camera& camera, RenderedFrame& frame) const override {
        pick(camera).finishFrame(camera, frame);
    }
    int workUnits(const Camera& camera) const override { return pick(camera).workUnits(camera); }
    void renderUnit(const Camera& camera, RenderedFrame& frame, int unit,
                    UnitCounters& counters) const override {
        pick(camera).renderUnit(camera, frame, unit, counters);
    }
    std::pair<int, int> unitColumns(const Camera& camera, int unit) const override {
        return pick(camera).unitColumns(camera, unit);
    }

  private:
    const Caster& pick(const Camera& camera) const {
        const int n =
            autoSupersample(camera.pose(), camera.intrinsics(), static_cast<int>(casters_.size()));
        return *casters_[static_cast<std::size_t>(n - 1)];
    }

    std::vector<std::unique_ptr<Caster>> casters_;
};

}  // namespace

std::unique_ptr<Caster> makeAutoSupersampleCaster(const TerrainMap& map,
                                                  const RenderOptions& options) {
    return std::make_unique<AutoSupersampleCaster>(map, options);
}

}  // namespace ig
