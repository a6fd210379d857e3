#include "sim/trajectory_poses.hpp"

#include "ig/error.hpp"
#include "ig/synthetic.hpp"
#include "io/field_clock.hpp"
#include "io/frame_sink.hpp"
#include "sim/pipeline.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <string>

namespace {

constexpr double kPeriod = 1001.0 / 60000.0;

// A straight 2 s line across a small synthetic map, `height` metres up.
std::string lineCsv(double height) {
    std::string csv = "t,x,y,z,yaw_deg,pitch_deg,roll_deg\n";
    for (int i = 0; i <= 4; ++i) {
        const double t = 0.5 * i;
        csv += std::to_string(t) + "," + std::to_string(600.0 + 100.0 * t) + ",600," +
               std::to_string(height) + ",90,-10," + std::to_string(10.0 * i) + "\n";
    }
    return csv;
}

TEST(TrajectoryPoses, FieldsFollowTheTrajectoryAtTheirInstants) {
    const ig::TerrainMap map = ig::makeSyntheticTerrain(64, 5, 30.0);
    const double top = map.maxHeight() + 200.0;
    sim::TrajectoryPoses poses(sim::Trajectory::parseCsv(lineCsv(top), "line.csv"));
    EXPECT_NO_THROW(sim::checkTrajectoryClearance(poses.trajectory(), map, "line.csv"));

    std::unique_ptr<io::FrameSink> sink = io::makeSink("null", nullptr);
    ASSERT_TRUE(sink);
    std::string error;
    ASSERT_EQ(sink->open({96, 64, io::PixelFormat::Y8}, &error), 0) << error;
    auto clock = io::makeSimulatedClock();
    sim::PipelineOptions options;
    options.clock = sim::ClockMode::Simulated;
    options.duration = 2.0;
    std::vector<double> rolls, times;
    options.onField = [&](const prp::Field& field, const io::FieldBuffer&) {
        times.push_back(field.time);
    };
    sim::RenderGeometry geometry;
    geometry.windowWidth = 96;
    geometry.windowHeight = 64;
    geometry.margin = 8;
    sim::Pipeline pipeline(poses, sim::makeCasterRenderer(map, geometry), *sink, *clock, options);
    const sim::PipelineResult result = pipeline.run();
    ASSERT_TRUE(result.ok()) << result.error;
    ASSERT_EQ(times.size(), static_cast<std::size_t>(std::lround(2.0 / kPeriod)));
    for (std::size_t n = 0; n < times.size(); ++n) {
        EXPECT_NEAR(times[n], n * kPeriod, 1e-9);
        // The pose the field loop used is the trajectory's at that instant.
        const ig::Pose p = poses.advanceTo(times[n]);
        EXPECT_NEAR(p.position.x, 600.0 + 100.0 * times[n], 1e-6);
    }
}

TEST(TrajectoryPoses, TrajectoryIntoTheGroundIsRefusedByName) {
    const ig::TerrainMap map = ig::makeSyntheticTerrain(64, 5, 30.0);
    const sim::Trajectory low =
        sim::Trajectory::parseCsv(lineCsv(map.minHeight() - 50.0), "low.csv");
    try {
        sim::checkTrajectoryClearance(low, map, "low.csv");
        FAIL() << "expected an InputError";
    } catch (const ig::InputError& e) {
        const std::string what = e.what();
        EXPECT_NE(what.find("low.csv"), std::string::npos) << what;
        EXPECT_NE(what.find("terrain"), std::string::npos) << what;
    }
}

TEST(TrajectoryPoses, TrajectoryFarOffTheMapIsRefusedByName) {
    // A 1.9 km map; a trajectory written in UTM eastings and northings.
    const ig::TerrainMap map = ig::makeSyntheticTerrain(64, 5, 30.0);
    const sim::Trajectory utm = sim::Trajectory::parseCsv(
        "t,x,y,z,yaw_deg,pitch_deg,roll_deg\n0,500000,5200000,3000,0,-5,0\n"
        "1,500100,5200000,3000,0,-5,0\n",
        "utm.csv");
    try {
        sim::checkTrajectoryClearance(utm, map, "utm.csv");
        FAIL() << "expected an InputError";
    } catch (const ig::InputError& e) {
        const std::string what = e.what();
        EXPECT_NE(what.find("utm.csv"), std::string::npos) << what;
        EXPECT_NE(what.find("off the map"), std::string::npos) << what;
    }
    // Approaching from just outside the map is fine.
    const sim::Trajectory approach = sim::Trajectory::parseCsv(
        "t,x,y,z,yaw_deg,pitch_deg,roll_deg\n0,-1500,900,3000,90,-5,0\n"
        "1,-1400,900,3000,90,-5,0\n",
        "approach.csv");
    EXPECT_NO_THROW(sim::checkTrajectoryClearance(approach, map, "approach.csv"));
}

}  // namespace
