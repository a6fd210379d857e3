#include "ig/camera.hpp"

#include <glm/geometric.hpp>

#include <cmath>
#include <numbers>

namespace ig {

bool Pose::isFinite() const {
    return std::isfinite(position.x) && std::isfinite(position.y) && std::isfinite(position.z) &&
           std::isfinite(yaw) && std::isfinite(pitch) && std::isfinite(roll);
}

Intrinsics Intrinsics::fromFov(int windowWidth, int windowHeight, double hfov, int margin) {
    Intrinsics in;
    in.width = windowWidth + 2 * margin;
    in.height = windowHeight + 2 * margin;
    in.margin = margin;
    in.focal = 0.5 * windowWidth / std::tan(0.5 * hfov);
    return in;
}

double Intrinsics::windowHfov() const {
    return 2.0 * std::atan(0.5 * windowWidth() / focal);
}

CameraBasis CameraBasis::fromPose(const Pose& pose) {
    // Heading h (clockwise from north) and its right-hand horizontal, then pitch about right,
    // then roll about forward (right wing down positive: right gains a -z component).
    const double sy = std::sin(pose.yaw), cy = std::cos(pose.yaw);
    const double sp = std::sin(pose.pitch), cp = std::cos(pose.pitch);
    const double sr = std::sin(pose.roll), cr = std::cos(pose.roll);
    const glm::dvec3 heading{sy, cy, 0.0};
    const glm::dvec3 right0{cy, -sy, 0.0};
    const glm::dvec3 zUp{0.0, 0.0, 1.0};
    CameraBasis b;
    b.forward = cp * heading + sp * zUp;
    const glm::dvec3 up0 = -sp * heading + cp * zUp;
    b.right = cr * right0 - sr * up0;
    b.up = sr * right0 + cr * up0;
    return b;
}

Camera::Camera(const Pose& pose, const Intrinsics& intrinsics)
    : pose_(pose), intr_(intrinsics), basis_(CameraBasis::fromPose(pose)) {}

glm::dvec3 Camera::rayDirection(double x, double y) const {
    return intr_.focal * basis_.forward + (x - intr_.cx()) * basis_.right -
           (y - intr_.cy()) * basis_.up;
}

std::optional<glm::dvec2> Camera::project(const glm::dvec3& p, double w) const {
    const glm::dvec3 d = p - w * pose_.position;
    const double zf = glm::dot(d, basis_.forward);
    const double scale = w != 0.0 ? std::max(1.0, glm::length(d)) : glm::length(d);
    if (!(zf > 1e-9 * scale)) return std::nullopt;
    const double xr = glm::dot(d, basis_.right);
    const double yu = glm::dot(d, basis_.up);
    return glm::dvec2{intr_.cx() + intr_.focal * xr / zf, intr_.cy() - intr_.focal * yu / zf};
}

double Camera::forwardDepth(const glm::dvec3& p) const {
    return glm::dot(p - pose_.position, basis_.forward);
}

double degToRad(double deg) {
    return deg * (std::numbers::pi / 180.0);
}
double radToDeg(double rad) {
    return rad * (180.0 / std::numbers::pi);
}

}  // namespace ig
