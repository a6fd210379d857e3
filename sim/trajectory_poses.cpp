#include "sim/trajectory_poses.hpp"

#include "ig/error.hpp"

#include <algorithm>
#include <cstdio>

namespace sim {

bool nearMap(const ig::TerrainMap& map, double x, double y) {
    const double far = std::max(map.extentX(), map.extentY());
    return x > -far && y > -far && x < map.extentX() + far && y < map.extentY() + far;
}

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
    bool near = false;
    for (const TrajectorySample& s : trajectory.samples())
        near = near || nearMap(map, s.pose.position.x, s.pose.position.y);
    if (!near) {
        const glm::dvec3 p = trajectory.samples().front().pose.position;
        char buf[320];
        std::snprintf(buf, sizeof buf,
                      "every position lies far off the map (the first at %.1f, %.1f; the map "
                      "spans x 0..%.1f, y 0..%.1f m): positions are metres east and north of the "
                      "map's south-west sample",
                      p.x, p.y, map.extentX(), map.extentY());
        throw ig::InputError(name + ": " + buf);
    }
    for (const TrajectorySample& s : trajectory.samples())
        check(s.t);
    for (double t = trajectory.startTime(); t < trajectory.endTime(); t += step)
        check(t);
}

}  // namespace sim
