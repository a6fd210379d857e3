// Poses from a recorded trajectory for the pipeline, and a terrain-clearance check for it.
#pragma once

#include "ig/terrain.hpp"
#include "sim/pose_source.hpp"
#include "sim/trajectory.hpp"

#include <functional>
#include <limits>
#include <string>

namespace sim {

// Poses straight from a trajectory (the future is known, so prediction is
// exact).
class TrajectoryPoses final : public PoseSource {
  public:
    explicit TrajectoryPoses(Trajectory trajectory) : trajectory_(std::move(trajectory)) {}

    ig::Pose advanceTo(double t) override { return trajectory_.poseAt(t); }
    ig::Pose predict(double t) override { return trajectory_.poseAt(t); }
    double startTime() const override { return trajectory_.startTime(); }
    const Trajectory& trajectory() const { return trajectory_; }

  private:
    Trajectory trajectory_;
};

// Throws ig::InputError naming `name` when the trajectory passes within
// `clearance` metres of the terrain surface (checked every `step` seconds, at
// most a million times, and at every sample, over the `duration` seconds from
// its start that a run flies), or when every sample lies further from the map
// than the map's own size (positions in another frame, such as UTM or degrees,
// instead of metres from the map's south-west sample).
// `ground`, when given, answers the terrain's surface height at (x, y) instead of the map (a
// map paged from a database, whose tiles it places first).
void checkTrajectoryClearance(const Trajectory& trajectory, const ig::TerrainMap& map,
                              const std::string& name, double clearance = 1.0, double step = 0.05,
                              double duration = std::numeric_limits<double>::infinity(),
                              const std::function<double(double, double)>& ground = {});

}  // namespace sim
