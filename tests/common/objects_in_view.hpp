// The shipped voxel models and a view populated with them: the objects tests' shared scene.
#pragma once

#include "ig/camera.hpp"
#include "ig/caster.hpp"
#include "ig/sticks.hpp"
#include "ig/vox.hpp"

#include <glm/geometric.hpp>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

namespace vig_test {

// The shipped models: opaque textured (conifer), semi-transparent (broadleaf), glass and a
// doorway of cavities (house), thin floating runs (mast).
inline const std::vector<ig::ObjectModel>& shippedModels() {
    static const std::vector<ig::ObjectModel> models = [] {
        std::vector<ig::ObjectModel> m;
        for (const char* name : {"conifer", "broadleaf", "house", "mast"}) {
            const std::string path = std::string(VIG_DATA_DIR) + "/models/" + name + ".vox";
            m.push_back(ig::objectModelFromVox(ig::readVox(path), 0, path));
        }
        return m;
    }();
    return models;
}

// Objects where a view looks: one on the ground under each pixel of a 6 x 5 grid whose centre
// ray meets the terrain, about 30 pixels tall at the distance of the nearest such hit, headings
// varied. Null when the view sees no ground. `nearest`, when given, gets that distance.
inline std::unique_ptr<ig::ObjectLayer> objectsInView(const ig::TerrainMap& map,
                                                      const ig::Pose& pose,
                                                      const ig::Intrinsics& in,
                                                      double* nearestOut = nullptr) {
    const ig::Camera camera(pose, in);
    std::vector<glm::dvec3> at;
    double nearest = INFINITY;
    for (int j = 0; j < 5; ++j) {
        for (int i = 0; i < 6; ++i) {
            const glm::dvec3 d = glm::normalize(
                camera.rayDirection((i + 0.5) * in.width / 6.0, (j + 0.7) * in.height / 5.0));
            const ig::RayHit hit = ig::intersectTerrain(map, pose.position, d);
            if (!hit.hit) continue;
            at.push_back(hit.point);
            nearest = std::min(nearest, hit.distance);
        }
    }
    if (nearestOut != nullptr) *nearestOut = nearest;
    if (at.empty()) return nullptr;
    const double tall = nearest * 30.0 / in.focal;  // metres
    const double scale = std::clamp(tall / 32.0, 0.01, 1000.0);
    auto layer = std::make_unique<ig::ObjectLayer>(map, std::max(scale, map.spacingX() / 4000.0));
    for (std::size_t i = 0; i < at.size(); ++i) {
        const ig::ObjectModel& m = shippedModels()[i % 4];
        layer->place(m, ig::Placement{static_cast<std::uint16_t>(1 + i), at[i].x, at[i].y,
                                      map.surfaceHeight(at[i].x, at[i].y),
                                      0.7 * static_cast<double>(i), scale});
    }
    layer->finish();
    return layer;
}

}  // namespace vig_test
