#include "ig/pose_sweep.hpp"

#include <cmath>

namespace ig {

std::vector<Pose> sweepPoses(const TerrainMap& map, int count) {
    std::vector<Pose> poses;
    poses.reserve(count);
    const double golden = 0.6180339887498949;
    for (int i = 0; i < count; ++i) {
        const double a = static_cast<double>(i) / (count - 1);  // 0..1 in order
        const double b = std::fmod(i * golden, 1.0);            // well spread, another order
        const double c = std::fmod(i * golden * golden + 0.3, 1.0);
        Pose p;
        p.position.x = map.extentX() * (0.2 + 0.6 * b);
        p.position.y = map.extentY() * (0.2 + 0.6 * c);
        const double agl = 5.0 * std::pow(4000.0, std::fmod(i * 0.37, 1.0));  // 5 m .. 20 km
        p.position.z = map.surfaceHeight(p.position.x, p.position.y) + agl;
        p.yaw = degToRad(360.0 * std::fmod(i * 7.0 / count + 0.5 * a, 1.0));
        p.pitch = degToRad(10.0 - 95.0 * c);
        p.roll = 0.0;
        poses.push_back(p);
    }
    return poses;
}

}  // namespace ig
