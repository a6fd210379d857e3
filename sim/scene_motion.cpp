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
    return out;
}

ig::ObjectLayer SceneMotion::stamp(double t) const {
    const std::vector<ig::Placement> where = placementsAt(t);
    return scene_->stampMoving(where);
}

}  // namespace sim
