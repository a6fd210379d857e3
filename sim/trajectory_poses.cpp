#include "sim/trajectory_poses.hpp"

#include "ig/error.hpp"

#include <cstdio>

namespace sim {

void checkTrajectoryClearance(const Trajectory& trajectory, const ig::TerrainMap& map,
                              const std::string& name, double clearance, double step) {
    auto check = [&](double t) {
        const ig::Pose p = trajectory.poseAt(t);
        const double ground = map.surfaceHeight(p.position.x, p.position.y);
        if (p.position.z < ground + clearance) {
            char buf[256];
            std::snprintf(buf, sizeof buf,
                          "at t = %.3f s the camera (%.1f, %.1f, %.1f) is %.1f m above the "
                          "terrain surface (needs at least %.1f m)",
                          t, p.position.x, p.position.y, p.position.z, p.position.z - ground,
                          clearance);
            throw ig::InputError(name + ": " + buf);
        }
    };
    for (const TrajectorySample& s : trajectory.samples())
        check(s.t);
    for (double t = trajectory.startTime(); t < trajectory.endTime(); t += step)
        check(t);
}

}  // namespace sim
