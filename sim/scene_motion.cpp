#include "sim/scene_motion.hpp"

#include "ig/error.hpp"

#include <algorithm>

namespace sim {

SceneMotion::SceneMotion(const ig::Scene& scene) : scene_(&scene) {
    for (const ig::MovingObject& m : scene.moving) {
        try {
            trajectories_.push_back(Trajectory::loadCsv(m.trajectory));
        } catch (const ig::InputError& e) {
            throw ig::InputError(scene.path + ": " + m.entry + ".trajectory: " + e.what());
        }
    }
}

double SceneMotion::startTime() const {
    double t = trajectories_.empty() ? 0.0 : trajectories_.front().startTime();
    for (const Trajectory& tr : trajectories_)
        t = std::min(t, tr.startTime());
    return t;
}

std::vector<ig::Placement> SceneMotion::placementsAt(double t) const {
    std::vector<ig::Placement> out;
    out.reserve(trajectories_.size());
    placementsAt(t, out);
    return out;
}

void SceneMotion::placementsAt(double t, std::vector<ig::Placement>& out) const {
    out.clear();
    for (std::size_t i = 0; i < trajectories_.size(); ++i) {
        const ig::Pose pose = trajectories_[i].poseAt(t);
        ig::Placement p;
        p.id = scene_->moving[i].id;
        p.x = pose.position.x;
        p.y = pose.position.y;
        p.heading = pose.yaw;
        p.scale = scene_->moving[i].scale;
        out.push_back(p);
    }
}

ig::ObjectLayer SceneMotion::stamp(double t, const ig::Ground* ground) const {
    const std::vector<ig::Placement> where = placementsAt(t);
    return scene_->stampMoving(where, ground);
}

ig::ObjectLayer SceneMotion::stamp(double t, std::span<const ExtraObject> extra,
                                   const ig::Ground* ground) const {
    if (extra.empty()) return stamp(t, ground);
    // The scene's moving objects as stampMoving places them, then the extra ones.
    const std::vector<ig::Placement> where = placementsAt(t);
    const ig::TerrainMap& map = scene_->staticLayer->map();
    const ig::Ground& under = ground ? *ground : map;
    ig::ObjectLayer layer(map, scene_->cellSize);
    const auto onMap = [&](const ig::Placement& p) {
        return p.x >= 0.0 && p.y >= 0.0 && p.x <= map.extentX() && p.y <= map.extentY();
    };
    for (std::size_t i = 0; i < where.size(); ++i) {
        const ig::MovingObject& m = scene_->moving[i];
        ig::Placement p = where[i];
        if (!onMap(p)) continue;
        p.z = m.z ? *m.z : under.groundHeight(p.x, p.y);
        layer.place(*scene_->models[static_cast<std::size_t>(m.model)], p);
    }
    for (const ExtraObject& o : extra) {
        ig::Placement p = o.placement;
        if (!onMap(p) || o.model < 0 ||
            static_cast<std::size_t>(o.model) >= scene_->models.size()) {
            continue;
        }
        if (o.onGround) p.z = under.groundHeight(p.x, p.y);
        layer.place(*scene_->models[static_cast<std::size_t>(o.model)], p);
    }
    layer.finish();
    return layer;
}

}  // namespace sim
