// Kinematic flight model: stick controls -> aircraft state -> camera pose at any time t.
#pragma once

#include "ig/camera.hpp"
#include "ig/terrain.hpp"

namespace sim {

// Stick deflections, each in [-1, 1] (values outside are clamped).
//   pitch: +1 full back (nose up); roll: +1 full right; yaw: +1 full right rudder;
//   throttle: 0 cruise, +1 maximum speed, -1 minimum speed.
struct Controls {
    double pitch = 0.0;
    double roll = 0.0;
    double yaw = 0.0;
    double throttle = 0.0;
};

// Rates and limits of the model. Angles in radians, speeds in m/s.
struct FlightLimits {
    double maxPitchRate = 0.5;  // flight-path rate at full stick (~29 deg/s)
    double maxRollRate = 2.5;   // bank rate at full stick (~143 deg/s)
    double maxYawRate = 0.15;   // rudder heading rate at full pedal (~9 deg/s)
    double maxPitch = 1.2;      // |flight-path angle| limit (~69 deg)
    double minSpeed = 60.0;
    double cruiseSpeed = 200.0;
    double maxSpeed = 340.0;
    double acceleration = 20.0;  // m/s^2 toward the throttle's speed
    double minClearance = 40.0;  // metres kept above the terrain surface
    double cameraTilt = 0.0;     // camera pitch relative to the flight path (negative: down)
};

// Aircraft state. heading: clockwise from north (+y); pitch: flight-path angle, up positive;
// roll: bank, right wing down positive, kept in (-pi, pi].
struct FlightState {
    double time = 0.0;
    glm::dvec3 position{0.0};
    double heading = 0.0;
    double pitch = 0.0;
    double roll = 0.0;
    double speed = 200.0;
};

// Integrates the state on a fixed time grid (kStep), so the flight does not depend on when or
// how often it is asked for a pose; a pose between grid points is a partial step from the
// last grid state. With a ground (a terrain map, or the ground of a paged one), the aircraft
// never goes below ground + minClearance.
class FlightModel {
  public:
    static constexpr double kStep = 1.0 / 600.0;  // seconds: 10 steps per NTSC field

    explicit FlightModel(const FlightState& start, const FlightLimits& limits = {},
                         const ig::Ground* floor = nullptr);

    // Time of the grid step at or before t (never before the start).
    double gridTimeAtOrBefore(double t) const;
    // Advances to the next grid point with `controls` held over the step.
    void step(const Controls& controls);
    // Grid state reached so far.
    const FlightState& state() const { return state_; }
    // State at time t >= state().time with `controls` held from state().time on; the model
    // itself does not change.
    FlightState extrapolate(double t, const Controls& controls) const;
    // Camera pose of a state: heading, flight-path pitch + cameraTilt, bank.
    ig::Pose pose(const FlightState& state) const;

    const FlightLimits& limits() const { return limits_; }
    const ig::Ground* floor() const { return floor_; }

    // One integration step of dt seconds (pure function; dt may be shorter than kStep).
    static FlightState integrate(const FlightState& state, const Controls& controls, double dt,
                                 const FlightLimits& limits, const ig::Ground* floor);
    // Lowest altitude the aircraft may have at (x, y): surface + minClearance.
    static double floorAltitude(const ig::Ground* floor, const FlightLimits& limits, double x,
                                double y);

  private:
    FlightLimits limits_;
    const ig::Ground* floor_;
    double startTime_;
    std::uint64_t steps_ = 0;
    FlightState state_;
};

}  // namespace sim
