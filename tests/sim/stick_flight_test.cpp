#include "ig/synthetic.hpp"
#include "ig/terrain_io.hpp"
#include "io/stick.hpp"
#include "sim/pose_source.hpp"
#include "sim/scenario.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <memory>
#include <numbers>
#include <sstream>
#include <string>

namespace {

constexpr double kPeriod = 1001.0 / 60000.0;

double angleDiff(double a, double b) {
    return std::remainder(a - b, 2.0 * std::numbers::pi);
}

std::unique_ptr<io::StickInput> script(std::string_view text) {
    std::string error;
    auto stick = io::makeScriptedStick(text, "test.stick", &error);
    EXPECT_TRUE(stick) << error;
    return stick;
}

sim::FlightState levelStart(double heading = 0.5) {
    sim::FlightState s;
    s.position = {1000.0, 1000.0, 1500.0};
    s.heading = heading;
    s.speed = 200.0;
    return s;
}

TEST(StickFlight, PullingUpClimbs) {
    for (double pull : {0.2, 0.5, 1.0}) {
        sim::StickFlight flight(
            script("0 axis pitch " + std::to_string(pull) + "\n0.5 axis pitch 0\n"), levelStart());
        double lastZ = 1500.0;
        for (int n = 1; n <= 180; ++n) {
            const ig::Pose p = flight.advanceTo(n * kPeriod);
            ASSERT_GE(p.position.z, lastZ) << n;  // climbing all the way
            lastZ = p.position.z;
        }
        EXPECT_GT(lastZ, 1500.0 + 50.0 * pull);
        EXPECT_NEAR(flight.model().state().pitch, 0.5 * pull * flight.model().limits().maxPitchRate,
                    0.01);
    }
}

TEST(StickFlight, RightRollTurnsRightLeftRollTurnsLeft) {
    for (double side : {1.0, -1.0}) {
        sim::StickFlight flight(script("0 axis roll " + std::to_string(0.4 * side) +
                                       " ramp 0.1\n0.5 axis roll 0 ramp 0.1\n"),
                                levelStart(2.0));
        double lastHeading = 2.0;
        for (int n = 1; n <= 240; ++n) {
            const ig::Pose p = flight.advanceTo(n * kPeriod);
            ASSERT_GE(side * angleDiff(p.yaw, lastHeading), 0.0) << n;
            lastHeading = p.yaw;
        }
        EXPECT_GT(side * angleDiff(lastHeading, 2.0), 0.08);
        EXPECT_GT(side * flight.advanceTo(240 * kPeriod).roll, 0.3);  // still banked
    }
}

TEST(StickFlight, PoseDoesNotDependOnHowOftenItIsAsked) {
    const std::string text = "0 axis roll 0.3\n0.7 axis pitch 0.4 ramp 0.3\n1.3 axis roll -0.5\n";
    for (double end : {0.5, 1.0, 1.7777, 2.0}) {
        sim::StickFlight often(script(text), levelStart()), once(script(text), levelStart());
        for (double t = 0.0; t < end; t += kPeriod)
            often.advanceTo(t);
        const ig::Pose a = often.advanceTo(end);
        const ig::Pose b = once.advanceTo(end);
        EXPECT_NEAR(a.position.x, b.position.x, 1e-9);
        EXPECT_NEAR(a.position.y, b.position.y, 1e-9);
        EXPECT_NEAR(a.position.z, b.position.z, 1e-9);
        EXPECT_NEAR(a.yaw, b.yaw, 1e-12);
        EXPECT_NEAR(a.roll, b.roll, 1e-12);
    }
}

TEST(StickFlight, PredictionMatchesTheFlightWhileTheStickHolds) {
    sim::StickFlight flight(script("0 axis roll 0.2\n0 axis pitch 0.1\n"), levelStart());
    flight.advanceTo(0.5);
    for (double ahead : {0.0, 0.01, 0.05, 0.1, 0.3}) {
        const ig::Pose predicted = flight.predict(0.5 + ahead);
        sim::StickFlight twin(script("0 axis roll 0.2\n0 axis pitch 0.1\n"), levelStart());
        const ig::Pose actual = twin.advanceTo(0.5 + ahead);
        EXPECT_NEAR(predicted.position.x, actual.position.x, 1e-6) << ahead;
        EXPECT_NEAR(predicted.position.y, actual.position.y, 1e-6) << ahead;
        EXPECT_NEAR(predicted.position.z, actual.position.z, 1e-6) << ahead;
        EXPECT_NEAR(predicted.roll, actual.roll, 1e-9) << ahead;
    }
}

TEST(StickFlight, TerrainFloorHoldsAtEveryField) {
    const ig::TerrainMap map = ig::makeSyntheticTerrain(64, 3, 60.0);
    sim::FlightLimits limits;
    limits.minClearance = 25.0;
    sim::FlightState start = sim::startOverMap(map, limits);
    sim::StickFlight flight(script("0 axis pitch -1\n0 axis throttle -1\n"), start, limits, &map);
    double lowest = 1e9;
    for (int n = 0; n < 600; ++n) {
        const ig::Pose p = flight.advanceTo(n * kPeriod);
        const double clearance = p.position.z - map.surfaceHeight(p.position.x, p.position.y);
        ASSERT_GE(clearance, 25.0 - 1e-6) << "field " << n;
        lowest = std::min(lowest, clearance);
    }
    EXPECT_LT(lowest, 25.0 + 1.0);  // it did reach the floor
}

TEST(Scenario, EmbeddedScriptIsTheShippedFile) {
    std::ifstream in("data/scenarios/default.stick");
    ASSERT_TRUE(in) << "data/scenarios/default.stick";
    std::stringstream text;
    text << in.rdbuf();
    EXPECT_EQ(text.str(), std::string(sim::defaultStickScript()));
    std::string error;
    EXPECT_TRUE(io::makeScriptedStick(sim::defaultStickScript(), "default.stick", &error)) << error;
}

TEST(Scenario, DefaultFlightTurnsClimbsAndRollsAboveTheTerrain) {
    const ig::TerrainMap map = ig::loadPugetSound();
    const sim::Scenario s = sim::defaultScenario();
    std::string error;
    sim::StickFlight flight(io::makeScriptedStick(s.stickScript, "default.stick", &error), s.start,
                            s.limits, &map);
    ig::Pose at1, at42, at66, at10;
    double maxRoll = 0.0, minClearance = 1e9;
    const int fields = static_cast<int>(std::lround(s.duration / kPeriod));
    for (int n = 0; n < fields; ++n) {
        const double t = n * kPeriod;
        const ig::Pose p = flight.advanceTo(t);
        ASSERT_TRUE(p.isFinite());
        minClearance =
            std::min(minClearance, p.position.z - map.surfaceHeight(p.position.x, p.position.y));
        if (t >= 6.8) maxRoll = std::max(maxRoll, std::abs(p.roll));
        if (std::abs(t - 1.0) < kPeriod / 2) at1 = p;
        if (std::abs(t - 4.2) < kPeriod / 2) at42 = p;
        if (std::abs(t - 6.6) < kPeriod / 2) at66 = p;
        at10 = p;
    }
    EXPECT_GT(ig::radToDeg(angleDiff(at42.yaw, at1.yaw)), 15.0);               // a right turn
    EXPECT_LT(std::abs(ig::radToDeg(at42.roll)), 3.0);                         // rolled out
    EXPECT_GT(at66.position.z - at42.position.z, 60.0);                        // a climb
    EXPECT_LT(std::abs(ig::radToDeg(at66.pitch - s.limits.cameraTilt)), 3.0);  // levelled off
    EXPECT_GT(ig::radToDeg(maxRoll), 170.0);                                   // through inverted
    EXPECT_LT(std::abs(ig::radToDeg(at10.roll)), 3.0);                         // and back
    EXPECT_GT(minClearance, 300.0);
}

}  // namespace
