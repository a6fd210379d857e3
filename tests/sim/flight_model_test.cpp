#include "sim/flight_model.hpp"

#include <gtest/gtest.h>
#include <glm/geometric.hpp>

#include <cmath>
#include <numbers>
#include <random>

namespace {

using sim::Controls;
using sim::FlightLimits;
using sim::FlightModel;
using sim::FlightState;

constexpr double kPi = std::numbers::pi;

double angleDiff(double a, double b) {
    return std::remainder(a - b, 2.0 * kPi);
}

FlightState startAt(double heading, double altitude = 1000.0, double speed = 200.0) {
    FlightState s;
    s.position = {5000.0, 5000.0, altitude};
    s.heading = heading;
    s.speed = speed;
    return s;
}

void fly(FlightModel& model, const Controls& c, double seconds) {
    const int steps = static_cast<int>(std::lround(seconds / FlightModel::kStep));
    for (int i = 0; i < steps; ++i)
        model.step(c);
}

// A ridge rising to 900 m across the middle of a 64 x 64 map at 100 m spacing.
ig::TerrainMap ridgeMap() {
    ig::TerrainMap map(64, 64, 100.0, 100.0, 1.0, 0.0);
    for (int iy = 0; iy < 64; ++iy) {
        for (int ix = 0; ix < 64; ++ix) {
            const double d = std::abs(iy - 32) / 8.0;
            map.setRaw(ix, iy, static_cast<std::uint16_t>(900.0 * std::exp(-d * d)));
        }
    }
    map.updateRange();
    return map;
}

TEST(FlightModel, CentredStickFliesStraightAlongHeading) {
    for (double headingDeg : {0.0, 45.0, 90.0, 180.0, -120.0}) {
        const double h = ig::degToRad(headingDeg);
        FlightModel model(startAt(h));
        const glm::dvec3 p0 = model.state().position;
        fly(model, {}, 2.0);
        const glm::dvec3 d = model.state().position - p0;
        EXPECT_NEAR(d.x, 400.0 * std::sin(h), 1e-6) << headingDeg;
        EXPECT_NEAR(d.y, 400.0 * std::cos(h), 1e-6) << headingDeg;
        EXPECT_NEAR(d.z, 0.0, 1e-9);
        EXPECT_NEAR(angleDiff(model.state().heading, h), 0.0, 1e-12);
        EXPECT_NEAR(model.state().time, 2.0, 1e-9);
    }
}

TEST(FlightModel, PullUpClimbsAndPushDownDescends) {
    for (double stick : {0.25, 0.5, 1.0}) {
        FlightModel up(startAt(0.3)), down(startAt(0.3));
        fly(up, {stick, 0, 0, 0}, 1.0);
        fly(down, {-stick, 0, 0, 0}, 1.0);
        EXPECT_GT(up.state().pitch, 0.0);
        EXPECT_LT(down.state().pitch, 0.0);
        EXPECT_NEAR(up.state().pitch, stick * up.limits().maxPitchRate, 1e-9);
        fly(up, {}, 1.0);
        fly(down, {}, 1.0);
        EXPECT_GT(up.state().position.z, 1000.0 + 10.0);
        EXPECT_LT(down.state().position.z, 1000.0 - 10.0);
        EXPECT_GT(up.pose(up.state()).pitch, 0.0);
    }
}

TEST(FlightModel, RightRollTurnsRightLeftRollTurnsLeft) {
    for (double speed : {80.0, 200.0, 320.0}) {
        for (double side : {1.0, -1.0}) {
            FlightLimits limits;
            limits.cruiseSpeed = speed;  // constant speed
            FlightModel model(startAt(1.0, 1000.0, speed), limits);
            fly(model, {0, side * 0.5, 0, 0}, 0.5);  // bank ~36 deg
            EXPECT_GT(side * model.state().roll, 0.3);
            const double bankedHeading = model.state().heading;
            fly(model, {}, 3.0);
            const double turned = angleDiff(model.state().heading, bankedHeading);
            EXPECT_GT(side * turned, 0.05) << "speed " << speed << " side " << side;
            // Coordinated: g tan(bank) / v.
            const double expected = 9.80665 * std::tan(model.state().roll) / speed * 3.0;
            EXPECT_NEAR(turned, expected, 1e-3 + 0.01 * std::abs(expected));
            EXPECT_GT(side * model.pose(model.state()).roll, 0.0);
        }
    }
}

TEST(FlightModel, FullAileronRollComesBackLevel) {
    FlightModel model(startAt(0.0));
    const double seconds = 2.0 * kPi / model.limits().maxRollRate;
    fly(model, {0, 1, 0, 0}, seconds);
    EXPECT_NEAR(angleDiff(model.state().roll, 0.0), 0.0, 0.01);
    // The roll passes through inverted, so the net turn stays small.
    EXPECT_LT(std::abs(model.state().heading), 0.1);
}

TEST(FlightModel, LimitsHoldUnderRandomStick) {
    std::mt19937 rng(7);
    std::uniform_real_distribution<double> u(-1.5, 1.5);
    FlightModel model(startAt(0.0, 5000.0));
    const FlightLimits& l = model.limits();
    for (int i = 0; i < 200; ++i) {
        fly(model, {u(rng), u(rng), u(rng), u(rng)}, 0.1);
        const FlightState& s = model.state();
        ASSERT_LE(std::abs(s.pitch), l.maxPitch + 1e-12);
        ASSERT_GE(s.speed, l.minSpeed);
        ASSERT_LE(s.speed, l.maxSpeed);
        ASSERT_GT(s.roll, -kPi - 1e-12);
        ASSERT_LE(s.roll, kPi + 1e-12);
        ASSERT_TRUE(model.pose(s).isFinite());
    }
}

TEST(FlightModel, ThrottleSetsSpeedWithinLimits) {
    for (double throttle : {-1.0, -0.5, 0.0, 0.5, 1.0}) {
        FlightModel model(startAt(0.0));
        fly(model, {0, 0, 0, throttle}, 20.0);
        const FlightLimits& l = model.limits();
        const double want = throttle >= 0 ? l.cruiseSpeed + throttle * (l.maxSpeed - l.cruiseSpeed)
                                          : l.cruiseSpeed + throttle * (l.cruiseSpeed - l.minSpeed);
        EXPECT_NEAR(model.state().speed, want, 1e-9) << throttle;
    }
}

TEST(FlightModel, TerrainFloorHolds) {
    const ig::TerrainMap map = ridgeMap();
    FlightLimits limits;
    limits.minClearance = 50.0;
    FlightState s;
    s.position = {3000.0, 500.0, 300.0};  // heading north, straight at the ridge
    s.speed = 150.0;
    FlightModel model(s, limits, &map);
    double maxZ = 0.0;
    for (int i = 0; i < 30 * 600; ++i) {
        model.step({-1.0, 0.0, 0.0, 0.0});  // full nose-down the whole way
        const FlightState& st = model.state();
        const double floor = map.surfaceHeight(st.position.x, st.position.y) + 50.0;
        ASSERT_GE(st.position.z, floor - 1e-9) << "step " << i;
        maxZ = std::max(maxZ, st.position.z);
        // Partial steps obey the floor too.
        const FlightState mid =
            model.extrapolate(st.time + 0.4 * FlightModel::kStep, {-1, 0, 0, 0});
        ASSERT_GE(mid.position.z, map.surfaceHeight(mid.position.x, mid.position.y) + 50.0 - 1e-9);
    }
    EXPECT_GT(maxZ, 900.0);  // it went over the ridge rather than through it
}

TEST(FlightModel, StartBelowFloorIsLifted) {
    const ig::TerrainMap map = ridgeMap();
    FlightState s;
    s.position = {3000.0, 3200.0, 0.0};
    FlightModel model(s, {}, &map);
    EXPECT_NEAR(model.state().position.z, map.surfaceHeight(3000.0, 3200.0) + 40.0, 1e-9);
}

TEST(FlightModel, ExtrapolationIsContinuousWithSteps) {
    FlightModel model(startAt(0.2));
    const Controls c{0.3, 0.4, 0.1, 0.5};
    fly(model, c, 0.5);
    // A pose between grid points lies between the grid states; a full step matches step().
    const FlightState a = model.state();
    const FlightState half = model.extrapolate(a.time + 0.5 * FlightModel::kStep, c);
    const FlightState full = model.extrapolate(a.time + FlightModel::kStep, c);
    model.step(c);
    const FlightState& b = model.state();
    EXPECT_NEAR(glm::length(full.position - b.position), 0.0, 1e-9);
    EXPECT_NEAR(full.heading, b.heading, 1e-12);
    EXPECT_NEAR(half.position.y, 0.5 * (a.position.y + b.position.y), 1e-3);
    EXPECT_GT(half.time, a.time);
    EXPECT_LT(half.time, b.time);
    EXPECT_DOUBLE_EQ(model.gridTimeAtOrBefore(b.time + 0.3 * FlightModel::kStep), b.time);
}

}  // namespace
