// Trajectories: timed poses from CSV, interpolated smoothly to any time.
#pragma once

#include "ig/camera.hpp"

#include <string>
#include <string_view>
#include <vector>

namespace sim {

struct TrajectorySample {
    double t = 0.0;
    ig::Pose pose;  // angles unwrapped along the trajectory (shortest arc between rows)
};

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

}  // namespace sim
