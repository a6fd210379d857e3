#include "sim/pose_source.hpp"

#include <algorithm>

namespace sim {

Controls controlsFromStick(const io::StickState& stick) {
    return {stick.pitch, stick.roll, stick.yaw, stick.throttle};
}

StickFlight::StickFlight(std::unique_ptr<io::StickInput> stick, const FlightState& start,
                         const FlightLimits& limits, const ig::Ground* floor)
    : stick_(std::move(stick)), model_(start, limits, floor), startTime_(start.time) {
    controls_ = controlsFromStick(stick_->sample(0.0));
    latest_.back() = {model_.state(), controls_};
    latest_.publish();
}

ig::Pose StickFlight::advanceTo(double t) {
    // The stick is sampled at the start of every grid step (time since the flight began).
    const double grid = model_.gridTimeAtOrBefore(t);
    bool moved = false;
    while (model_.state().time < grid - 1e-12) {
        model_.step(controls_);
        controls_ = controlsFromStick(stick_->sample(model_.state().time - startTime_));
        moved = true;
    }
    if (moved) {
        latest_.back() = {model_.state(), controls_};
        latest_.publish();
    }
    return model_.pose(model_.extrapolate(t, controls_));
}

ig::Pose StickFlight::predict(double t) {
    latest_.fetch();
    const Snapshot& s = latest_.front();
    // The renderer works from a copy of the model's latest grid state, stick held from there.
    FlightModel ahead(s.state, model_.limits(), model_.floor());
    return ahead.pose(ahead.extrapolate(std::max(t, s.state.time), s.controls));
}

}  // namespace sim
