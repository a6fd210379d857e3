#include "sim/scenario.hpp"

#include "ig/cli.hpp"

#include <algorithm>
#include <cmath>

namespace sim {

namespace {

// Keep identical to data/scenarios/default.stick (a test compares them).
constexpr std::string_view kDefaultStickScript =
    R"(# Default flythrough: about 10 s over the shipped Puget Sound terrain, starting some 20 km
# south-west of Mount Rainier and heading toward it: a right turn, a climb, an aileron roll.
# Format: TIME axis pitch|roll|yaw|throttle VALUE [ramp SECONDS] | TIME button trigger down|up
# (seconds since the start; full roll stick = 143 deg/s of bank, full pitch = 29 deg/s).

# Right turn: bank to about 60 degrees with a little rudder, hold it, roll back to level.
1.0 axis roll 0.6 ramp 0.2
1.0 axis yaw 0.5 ramp 0.5
1.7 axis roll 0 ramp 0.2
3.2 axis roll -0.6 ramp 0.2
3.2 axis yaw 0 ramp 0.5
3.9 axis roll 0 ramp 0.2

# Climb: pull up to about 18 degrees, hold it, push back to level flight.
4.2 axis pitch 0.8 ramp 0.2
5.0 axis pitch 0 ramp 0.2
5.6 axis pitch -0.8 ramp 0.2
6.4 axis pitch 0 ramp 0.2

# A full aileron roll to the right with a touch of throttle.
6.8 axis throttle 0.3 ramp 1.0
6.8 axis roll 1 ramp 0.2
9.313 axis roll 0 ramp 0.2
)";

}  // namespace

std::string_view defaultStickScript() {
    return kDefaultStickScript;
}

Scenario defaultScenario() {
    Scenario s;
    s.name = "default";
    s.stickScript = std::string(kDefaultStickScript);
    // Mount Rainier's summit is at about (128480, 79200) m on the shipped map (sample 803, 495
    // south-first, 4380 m). Start 22 km from it on a heading of 40 degrees, at 2600 m.
    const double heading = ig::degToRad(40.0);
    const double distance = 22000.0;
    s.start.position = {128480.0 - distance * std::sin(heading),
                        79200.0 - distance * std::cos(heading), 2600.0};
    s.start.heading = heading;
    s.limits.cruiseSpeed = 160.0;
    s.start.speed = s.limits.cruiseSpeed;
    s.limits.cameraTilt = ig::degToRad(-8.0);
    s.duration = 10.0;
    return s;
}

FlightState startOverMap(const ig::TerrainMap& map, const FlightLimits& limits) {
    // Where ig-render looks from on a map it has no view for.
    const ig::Pose view = ig::defaultViewPose(map);
    FlightState s;
    s.position = view.position;
    s.heading = view.yaw;
    s.speed = limits.cruiseSpeed;
    return s;
}

}  // namespace sim
