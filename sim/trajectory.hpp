// Trajectories: timed poses from CSV, interpolated smoothly to any time.
#pragma once

#include "ig/camera.hpp"
#include "ig/terrain.hpp"

#include <string>
#include <string_view>
#include <vector>

namespace sim {

struct TrajectorySample {
    double t = 0.0;
    ig::Pose pose;  // angles unwrapped along the trajectory (shortest arc between rows)
};

// Trajectory times lie within +-kMaxTrajectoryTime seconds (about 32 years): beyond it a double
// no longer resolves a field period to better than a microsecond.
inline constexpr double kMaxTrajectoryTime = 1e9;

// CSV whose header names the columns t, x, y, z, yaw_deg, pitch_deg, roll_deg in any order (names
// compared without case or spaces; other columns are ignored, e.g. speed or a phase label);
// times strictly increasing; metres and degrees (yaw clockwise from north, pitch up, roll right
// wing down). Blank lines and lines starting with '#' are skipped.
class Trajectory {
  public:
    // Throws ig::InputError naming the file (and line) and the problem.
    static Trajectory loadCsv(const std::string& path);
    static Trajectory parseCsv(std::string_view text, const std::string& name);
    static Trajectory fromSamples(std::vector<TrajectorySample> samples, const std::string& name);

    // Cubic Hermite (Catmull-Rom tangents, non-uniform times) through positions and unwrapped
    // angles; each angle takes the shortest arc between rows. Clamps outside the time range.
    ig::Pose poseAt(double t) const;
    double startTime() const { return samples_.front().t; }
    double endTime() const { return samples_.back().t; }
    const std::vector<TrajectorySample>& samples() const { return samples_; }

  private:
    std::vector<TrajectorySample> samples_;
};

// A trajectory laid over another map: its horizontal path scaled about its centre by `scale`
// (1 when it fits in 60 % of the map's smaller side, less when it would not) and moved to the
// map's centre; its heights taken as heights above `ground`, the highest terrain under and
// beside the path (heights below 0 keep their distance to the lowest one); times and angles
// unchanged, so a shape flown over one map can be flown over any.
struct FittedTrajectory {
    Trajectory trajectory;
    double scale = 1.0;
    double ground = 0.0;
};
FittedTrajectory fitTrajectoryToMap(const Trajectory& trajectory, const ig::TerrainMap& map);

}  // namespace sim
