#include "sim/trajectory_poses.hpp"

#include "ig/error.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>

namespace sim {

void checkTrajectoryClearance(const Trajectory& trajectory, const ig::TerrainMap& map,
                              const std::string& name, double clearance, double step,
                              double duration, const std::function<double(double, double)>& at) {
    auto check = [&](double t) {
        const ig::Pose p = trajectory.poseAt(t);
        const double ground =
            at ? at(p.position.x, p.position.y) : map.surfaceHeight(p.position.x, p.position.y);
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
        near = near || ig::nearMap(map, s.pose.position.x, s.pose.position.y);
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
    // Only the span the run flies, at no more than kMaxChecks times: a span or time the file
    // makes huge (t = 1e16, where t + step == t) bounds nothing.
    const double start = trajectory.startTime();
    const double end = std::min(trajectory.endTime(), start + std::max(duration, 0.0));
    constexpr double kMaxChecks = 1e6;
    const double span = end - start;
    const double every = std::max(step, span / kMaxChecks);
    for (const TrajectorySample& s : trajectory.samples()) {
        if (s.t <= end) check(s.t);
    }
    if (!(span > 0.0) || !(every > 0.0)) return;
    const auto count = static_cast<std::uint64_t>(std::min(std::ceil(span / every), kMaxChecks));
    for (std::uint64_t i = 0; i < count; ++i)
        check(start + span * (static_cast<double>(i) / static_cast<double>(count)));
    check(end);
}

}  // namespace sim
