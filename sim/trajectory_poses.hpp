// Poses from a recorded trajectory for the pipeline, and a terrain-clearance check for it.
#pragma once

#include "ig/terrain.hpp"
#include "sim/pose_source.hpp"
#include "sim/trajectory.hpp"

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

// Whether (x, y) lies within the map's own size of the map; positions further off are taken
// for a mistake of coordinates (UTM or degrees instead of metres from the map's south-west
// sample).
bool nearMap(const ig::TerrainMap& map, double x, double y);

// Throws ig::InputError naming `name` when the trajectory passes within
// `clearance` metres of the terrain surface (checked every `step` seconds and
// at every sample), or when every sample lies further from the map than the
// map's own size (positions in another frame, such as UTM or degrees, instead
// of metres from the map's south-west sample).
void checkTrajectoryClearance(const Trajectory& trajectory, const ig::TerrainMap& map,
                              const std::string& name, double clearance = 1.0, double step = 0.05);

}  // namespace sim
