#include "sim/flight_model.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

namespace sim {

namespace {

constexpr double kGravity = 9.80665;

double wrapAngle(double a) {
    a = std::remainder(a, 2.0 * std::numbers::pi);  // [-pi, pi]
    return a <= -std::numbers::pi ? a + 2.0 * std::numbers::pi : a;
}

Controls clamped(const Controls& c) {
    auto unit = [](double v) { return std::isfinite(v) ? std::clamp(v, -1.0, 1.0) : 0.0; };
    return {unit(c.pitch), unit(c.roll), unit(c.yaw), unit(c.throttle)};
}

}  // namespace

FlightModel::FlightModel(const FlightState& start, const FlightLimits& limits,
                         const ig::Ground* floor)
    : limits_(limits), floor_(floor), startTime_(start.time), state_(start) {
    state_.roll = wrapAngle(state_.roll);
    state_.heading = wrapAngle(state_.heading);
    state_.pitch = std::clamp(state_.pitch, -limits_.maxPitch, limits_.maxPitch);
    state_.position.z = std::max(
        state_.position.z, floorAltitude(floor_, limits_, state_.position.x, state_.position.y));
}

double FlightModel::floorAltitude(const ig::Ground* floor, const FlightLimits& limits, double x,
                                  double y) {
    const double ground =
        floor == nullptr ? std::numeric_limits<double>::quiet_NaN() : floor->groundHeight(x, y);
    if (!std::isfinite(ground)) return -std::numeric_limits<double>::infinity();
    return ground + limits.minClearance;
}

double FlightModel::gridTimeAtOrBefore(double t) const {
    const double k = std::floor((t - startTime_) / kStep + 1e-9);
    return startTime_ + std::max(k, 0.0) * kStep;
}

void FlightModel::step(const Controls& controls) {
    state_ = integrate(state_, controls, kStep, limits_, floor_);
    ++steps_;
    state_.time = startTime_ + static_cast<double>(steps_) * kStep;
}

FlightState FlightModel::extrapolate(double t, const Controls& controls) const {
    FlightState s = state_;
    // Whole steps first, on the same grid the model itself uses, then the remainder.
    while (t - s.time >= kStep * (1.0 - 1e-9))
        s = integrate(s, controls, kStep, limits_, floor_);
    if (t > s.time) s = integrate(s, controls, t - s.time, limits_, floor_);
    s.time = std::max(t, state_.time);
    return s;
}

ig::Pose FlightModel::pose(const FlightState& s) const {
    ig::Pose p;
    p.position = s.position;
    p.yaw = s.heading;
    p.pitch = s.pitch + limits_.cameraTilt;
    p.roll = s.roll;
    return p;
}

FlightState FlightModel::integrate(const FlightState& s, const Controls& raw, double dt,
                                   const FlightLimits& limits, const ig::Ground* floor) {
    const Controls c = clamped(raw);
    FlightState n = s;
    n.time = s.time + dt;

    // Speed follows the throttle's setting at a limited acceleration.
    const double target =
        c.throttle >= 0.0
            ? limits.cruiseSpeed + c.throttle * (limits.maxSpeed - limits.cruiseSpeed)
            : limits.cruiseSpeed + c.throttle * (limits.cruiseSpeed - limits.minSpeed);
    const double dv =
        std::clamp(target - s.speed, -limits.acceleration * dt, limits.acceleration * dt);
    n.speed = std::clamp(s.speed + dv, limits.minSpeed, limits.maxSpeed);

    // Stick rates. Bank is free (aileron rolls are allowed); the flight path is limited.
    n.roll = wrapAngle(s.roll + c.roll * limits.maxRollRate * dt);
    n.pitch =
        std::clamp(s.pitch + c.pitch * limits.maxPitchRate * dt, -limits.maxPitch, limits.maxPitch);

    // Coordinated turn: g tan(bank) / v up to 60 degrees of bank; beyond, 2 sin(bank) continues
    // it smoothly and falls to zero inverted, so a full roll gives only a small net turn.
    const double bankFactor = std::sin(n.roll) / std::max(std::cos(n.roll), 0.5);
    const double turnRate = kGravity / std::max(n.speed, 1.0) * bankFactor;
    n.heading = wrapAngle(s.heading + (turnRate + c.yaw * limits.maxYawRate) * dt);

    const double cp = std::cos(n.pitch);
    const glm::dvec3 dir{std::sin(n.heading) * cp, std::cos(n.heading) * cp, std::sin(n.pitch)};
    n.position = s.position + dir * (n.speed * dt);

    // Terrain floor: never below surface + clearance; a descent there levels off.
    const double lowest = floorAltitude(floor, limits, n.position.x, n.position.y);
    if (n.position.z < lowest) {
        n.position.z = lowest;
        n.pitch = std::max(n.pitch, 0.0);
    }
    return n;
}

}  // namespace sim
