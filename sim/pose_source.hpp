// Where the aircraft is at any time t: a stick-driven flight or a recorded trajectory.
#pragma once

#include "ig/camera.hpp"
#include "ig/terrain.hpp"
#include "io/stick.hpp"
#include "sim/flight_model.hpp"
#include "sim/mailbox.hpp"
#include "sim/render_view.hpp"

#include <memory>

namespace sim {

// The pipeline asks for poses from two threads: the field loop advances the simulation to each
// field's instant; the renderer asks for the pose it expects when its frame will be ready.
class PoseSource {
  public:
    virtual ~PoseSource() = default;
    // Field loop only, t non-decreasing: advances the simulation to t; the pose there.
    virtual ig::Pose advanceTo(double t) = 0;
    // Renderer only (one thread): the pose expected at t, from the latest state advanceTo()
    // reached. Never blocks advanceTo().
    virtual ig::Pose predict(double t) = 0;
    // Simulation time at which the flight starts.
    virtual double startTime() const = 0;
    // Field loop only: the view (field of view, draw distance) of the field at the last
    // advanceTo(), or before the first the view the run starts with; all 0 (the renderer's
    // geometry) unless a host sets it.
    virtual RenderView view() const { return {}; }
    // Field loop, once, after the first frame is rendered and just before the first field (at
    // its instant t0): a source fed from outside takes what waited meanwhile (a host's
    // messages), so the first field does not pay for the start's backlog. Nothing by default.
    virtual void settle(double t0) { (void)t0; }
};

// Stick converted to the flight model's controls.
Controls controlsFromStick(const io::StickState& stick);

// Flight model driven by a control stick, sampled once per integration step.
class StickFlight final : public PoseSource {
  public:
    StickFlight(std::unique_ptr<io::StickInput> stick, const FlightState& start,
                const FlightLimits& limits = {}, const ig::Ground* floor = nullptr);

    ig::Pose advanceTo(double t) override;
    ig::Pose predict(double t) override;
    double startTime() const override { return startTime_; }

    const FlightModel& model() const { return model_; }
    // Full state at t (after advanceTo(t)), for tests and tools.
    FlightState stateAt(double t) const { return model_.extrapolate(t, controls_); }

  private:
    struct Snapshot {
        FlightState state;
        Controls controls;
    };

    std::unique_ptr<io::StickInput> stick_;
    FlightModel model_;
    double startTime_;
    Controls controls_;         // stick as sampled at model_.state().time
    Mailbox<Snapshot> latest_;  // field loop -> renderer
};

}  // namespace sim
