// Flight scenarios: the built-in default flight over Puget Sound and starts for any terrain.
#pragma once

#include "ig/terrain.hpp"
#include "sim/flight_model.hpp"

#include <string>
#include <string_view>

namespace sim {

struct Scenario {
    std::string name;
    std::string stickScript;  // io scripted-stick text (makeScriptedStick)
    FlightState start;
    FlightLimits limits;
    double duration = 10.0;  // seconds
};

// The default stick script, identical to data/scenarios/default.stick (embedded so programs
// run from any folder).
std::string_view defaultStickScript();

// About 10 s over the shipped Puget Sound map (world metres of ig::loadPugetSound()): a right
// turn, a climb and an aileron roll, starting some 20 km south-west of Mount Rainier.
Scenario defaultScenario();

// A start for any map: over the south-west part heading north-east, well above the terrain
// there, at cruise speed.
FlightState startOverMap(const ig::TerrainMap& map, const FlightLimits& limits = {});

}  // namespace sim
