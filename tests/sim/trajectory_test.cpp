#include "sim/trajectory.hpp"

#include "ig/error.hpp"
#include "ig/synthetic.hpp"
#include "ig/terrain_io.hpp"
#include "prp/evaluation.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <numbers>
#include <string>

namespace sim {
namespace {

constexpr double kPi = std::numbers::pi;

TEST(Trajectory, InterpolatesThroughItsRows) {
    const Trajectory tr = Trajectory::parseCsv(
        "# comment\n"
        "t,x,y,z,yaw_deg,pitch_deg,roll_deg\n"
        "0, 0, 0, 100, 0, -10, 0\n"
        "1, 100, 0, 110, 10, -12, 5\n"
        "\n"
        "2.5, 200, 50, 120, 30, -8, -5\n",
        "test");
    ASSERT_EQ(tr.samples().size(), 3u);
    EXPECT_EQ(tr.startTime(), 0.0);
    EXPECT_EQ(tr.endTime(), 2.5);
    for (const auto& s : tr.samples()) {
        const ig::Pose p = tr.poseAt(s.t);
        EXPECT_NEAR(p.position.x, s.pose.position.x, 1e-9);
        EXPECT_NEAR(p.position.z, s.pose.position.z, 1e-9);
        EXPECT_NEAR(p.yaw, s.pose.yaw, 1e-12);
        EXPECT_NEAR(p.roll, s.pose.roll, 1e-12);
    }
    EXPECT_NEAR(tr.samples()[1].pose.yaw, 10 * kPi / 180, 1e-12);
    // Clamped outside.
    EXPECT_EQ(tr.poseAt(-5).position.x, 0.0);
    EXPECT_EQ(tr.poseAt(9).position.y, 50.0);
    // Continuous: small steps give small changes.
    for (double t = 0; t < 2.5; t += 0.01) {
        const ig::Pose a = tr.poseAt(t), b = tr.poseAt(t + 0.001);
        EXPECT_LT(std::abs(a.position.x - b.position.x), 0.5);
        EXPECT_LT(std::abs(a.yaw - b.yaw), 0.01);
    }
}

TEST(Trajectory, StraightUniformFlightIsExact) {
    // Catmull-Rom reproduces linear motion exactly.
    const Trajectory tr = Trajectory::parseCsv(
        "t,x,y,z,yaw_deg,pitch_deg,roll_deg\n0,0,0,500,0,0,0\n1,150,0,500,0,0,0\n"
        "2,300,0,500,0,0,0\n3,450,0,500,0,0,0\n",
        "line");
    for (double t = 0; t <= 3; t += 0.1)
        EXPECT_NEAR(tr.poseAt(t).position.x, 150 * t, 1e-9);
}

TEST(Trajectory, AnglesTakeTheShortestArc) {
    const Trajectory tr = Trajectory::parseCsv(
        "t,x,y,z,yaw_deg,pitch_deg,roll_deg\n0,0,0,0,350,0,-170\n1,0,0,0,10,0,170\n", "wrap");
    const ig::Pose mid = tr.poseAt(0.5);
    // Through north (0 / 360 deg), not back through south; roll through 180.
    EXPECT_NEAR(std::remainder(mid.yaw, 2 * kPi), 0.0, 1e-9);
    EXPECT_NEAR(std::abs(std::remainder(mid.roll, 2 * kPi)), kPi, 1e-9);
    for (double t = 0; t <= 1; t += 0.05) {
        const double yawDeg = std::remainder(tr.poseAt(t).yaw, 2 * kPi) * 180 / kPi;
        EXPECT_LE(std::abs(yawDeg), 10.0 + 1e-9);
    }
}

TEST(Trajectory, ColumnsInAnyOrderAndExtraColumnsIgnored) {
    const Trajectory a = Trajectory::parseCsv(
        "t,x,y,z,yaw_deg,pitch_deg,roll_deg\n0,1,2,3,10,-5,2\n2,5,6,7,20,-3,1\n", "plain");
    // Reordered, upper case, with spaces, CRLF and two columns the product does not use.
    const Trajectory b = Trajectory::parseCsv(
        "Roll_deg, phase, T, z, y, x, pitch_deg, speed_mps, yaw_deg\r\n"
        "2, climb, 0, 3, 2, 1, -5, 80.5, 10\r\n"
        "1, cruise, 2, 7, 6, 5, -3, n/a, 20\r\n",
        "reordered");
    for (double t : {0.0, 0.7, 1.3, 2.0}) {
        const ig::Pose pa = a.poseAt(t), pb = b.poseAt(t);
        EXPECT_EQ(pa.position, pb.position) << t;
        EXPECT_EQ(pa.yaw, pb.yaw) << t;
        EXPECT_EQ(pa.pitch, pb.pitch) << t;
        EXPECT_EQ(pa.roll, pb.roll) << t;
    }
    EXPECT_EQ(b.poseAt(0.0).position, (glm::dvec3{1, 2, 3}));
}

TEST(Trajectory, BadFilesNameTheLine) {
    const std::string h = "t,x,y,z,yaw_deg,pitch_deg,roll_deg\n";
    struct Case {
        std::string text, expect;
    };
    const Case cases[] = {
        {"t,x,y,z,yaw,pitch,roll\n0,0,0,0,0,0,0\n", "bad.csv:1: no column 'yaw_deg'"},
        {"t,x,y,z,yaw_deg,pitch_deg,roll_deg,x\n", "bad.csv:1: column 'x' appears twice"},
        {h + "0,0,0,0,0,0\n", "bad.csv:2: expected 7 columns"},
        {h + "0,0,0,0,0,0,0,0\n", "bad.csv:2: expected 7 columns as in the header, found 8"},
        {h + "0,0,0,0,0,0,0\n1,0,abc,0,0,0,0\n", "bad.csv:3: column 3 (y)"},
        {h + "0,0,0,0,0,0,0\n0,1,0,0,0,0,0\n", "bad.csv:3: time"},
        {h + "0,0,0,0,0,0,0\n1,nan,0,0,0,0,0\n", "bad.csv:3: column 2"},
        {h + "0,0,0,0,0,0,0\n1,0,0,inf,0,0,0\n", "bad.csv:3: column 4"},
        {h + "0,0,,0,0,0,0\n", "bad.csv:2: column 3"},
        {h + "1e16,0,0,0,0,0,0\n", "bad.csv:2: time 1e+16 s is out of range"},
        {h + "-2e9,0,0,0,0,0,0\n", "bad.csv:2: time -2000000000 s is out of range"},
        {h, "no trajectory rows"},
        {"", "no header"},
    };
    for (const Case& c : cases) {
        try {
            Trajectory::parseCsv(c.text, "bad.csv");
            ADD_FAILURE() << "accepted: " << c.text;
        } catch (const ig::InputError& e) {
            EXPECT_NE(std::string(e.what()).find(c.expect), std::string::npos)
                << e.what() << " / wanted " << c.expect;
        }
    }
    EXPECT_THROW(Trajectory::loadCsv("no/such/file.csv"), ig::InputError);
    // The limit itself is accepted.
    EXPECT_NO_THROW(Trajectory::parseCsv(h + "1e9,0,0,0,0,0,0\n", "edge.csv"));
    std::vector<sim::TrajectorySample> far(1);
    far[0].t = 3e9;
    EXPECT_THROW(Trajectory::fromSamples(far, "far"), ig::InputError);
}

// A 10 MB bad line (or raw binary) is quoted, escaped and cut, not echoed whole.
TEST(Trajectory, LongOrBinaryBadInputIsQuotedBriefly) {
    const std::string h = "t,x,y,z,yaw_deg,pitch_deg,roll_deg\n";
    std::string binary(4096, '\0');
    for (std::size_t k = 0; k < binary.size(); ++k)
        binary[k] = static_cast<char>(k * 131 + 7);
    const std::string cases[] = {
        std::string(10 << 20, 'x') + "\n",                        // header
        h + "0,0," + std::string(10 << 20, '7') + "z,0,0,0,0\n",  // a field
        binary,                                                   // no header, binary
        h + "1," + binary + ",0,0,0,0,0\n",
    };
    for (const std::string& text : cases) {
        try {
            Trajectory::parseCsv(text, "big.csv");
            ADD_FAILURE() << "accepted";
        } catch (const ig::InputError& e) {
            const std::string msg = e.what();
            // Binary bytes are escaped (\xNN): at most 200 of them shown, so about 800 characters.
            EXPECT_LE(msg.size(), 1024u) << msg.substr(0, 400);
            EXPECT_EQ(msg.rfind("big.csv:", 0), 0u) << msg.substr(0, 400);
            EXPECT_TRUE(std::all_of(msg.begin(), msg.end(), [](unsigned char c) {
                return c >= 0x20 && c < 0x7f;
            })) << msg.substr(0, 400);
        }
    }
    // The quoted part of a 10 MB line: at most about 200 bytes of it, and its length.
    try {
        Trajectory::parseCsv(cases[0], "big.csv");
    } catch (const ig::InputError& e) {
        const std::string msg = e.what();
        const std::size_t quote = msg.find("found '");
        ASSERT_NE(quote, std::string::npos) << msg;
        EXPECT_LE(msg.size() - quote, 260u) << msg;
        EXPECT_LE(msg.size(), 450u) << msg;
        EXPECT_NE(msg.find("(10485760 bytes)"), std::string::npos) << msg;
    }
}

TEST(Trajectory, ShippedTrajectoriesLoad) {
    int count = 0;
    for (const auto& entry : std::filesystem::directory_iterator("data/trajectories")) {
        if (entry.path().extension() != ".csv") continue;
        const Trajectory tr = Trajectory::loadCsv(entry.path().string());
        EXPECT_GT(tr.endTime() - tr.startTime(), 1.0) << entry.path();
        ++count;
    }
    EXPECT_GE(count, 5);
}

TEST(WarpEvalPugetSound, PolynomialBeatsHoldAtEveryHorizonOnEachTrajectory) {
    const ig::TerrainMap map = ig::loadPugetSound();
    const auto fast = ig::makeCaster(ig::CasterKind::Fast, map);
    const auto reference = ig::makeCaster(ig::CasterKind::Reference, map);
    prp::EvalConfig config;
    config.width = 240;
    config.height = 180;
    config.margin = 24;
    config.baseFrames = 2;
    config.timingRepeats = 1;
    config.models = {prp::WarpModel::Poly, prp::WarpModel::Hold};
    int checked = 0;
    for (const auto& entry : std::filesystem::directory_iterator("data/trajectories")) {
        if (entry.path().extension() != ".csv") continue;
        const Trajectory tr = Trajectory::loadCsv(entry.path().string());
        const prp::EvalResult r = prp::evaluateWarps(
            map, *fast, *reference, [&](double t) { return tr.poseAt(t); }, tr.startTime(),
            tr.endTime(), config);
        const std::size_t n = config.horizons.size();
        ASSERT_EQ(r.cells.size(), 2 * n);
        for (std::size_t i = 0; i < n; ++i) {
            const prp::EvalCell& poly = r.cells[i];
            const prp::EvalCell& hold = r.cells[n + i];
            EXPECT_LT(poly.maePct, hold.maePct) << entry.path() << " k=" << poly.horizon;
            EXPECT_GT(poly.psnrDb, hold.psnrDb) << entry.path() << " k=" << poly.horizon;
        }
        ++checked;
    }
    EXPECT_GE(checked, 5);
}

}  // namespace
}  // namespace sim

namespace sim {
namespace {

// Every shipped trajectory laid over a small rough map and a large flat one: inside the map,
// above its ground, the same shape (scaled), times and angles unchanged.
TEST(FitTrajectoryToMap, ShippedShapesFitAnyMap) {
    ig::TerrainMap flat(400, 300, 100.0, 100.0, 1.0, 250.0);  // 40 x 30 km at 250 m
    flat.updateRange();
    const ig::TerrainMap small = ig::makeSyntheticTerrain(256, 5, 5.0);  // 1.3 km, rough
    for (const auto& entry : std::filesystem::directory_iterator("data/trajectories")) {
        if (entry.path().extension() != ".csv") continue;
        const Trajectory tr = Trajectory::loadCsv(entry.path().string());
        for (const ig::TerrainMap* map : {static_cast<const ig::TerrainMap*>(&flat), &small}) {
            SCOPED_TRACE(entry.path().string() + " over " + std::to_string(map->width()));
            const sim::FittedTrajectory f = sim::fitTrajectoryToMap(tr, *map);
            ASSERT_GT(f.scale, 0.0);
            EXPECT_LE(f.scale, 1.0);
            if (map == &flat) {
                EXPECT_EQ(f.scale, 1.0);
                EXPECT_NEAR(f.ground, 250.0, 1e-9);
            }
            const auto& a = tr.samples();
            const auto& b = f.trajectory.samples();
            ASSERT_EQ(a.size(), b.size());
            for (std::size_t i = 0; i < a.size(); ++i) {
                EXPECT_EQ(a[i].t, b[i].t);
                EXPECT_NEAR(a[i].pose.yaw, b[i].pose.yaw, 1e-12);
                EXPECT_NEAR(a[i].pose.pitch, b[i].pose.pitch, 1e-12);
                EXPECT_NEAR(a[i].pose.roll, b[i].pose.roll, 1e-12);
                if (i > 0) {  // the horizontal shape is scaled, not bent
                    const glm::dvec2 da{a[i].pose.position.x - a[0].pose.position.x,
                                        a[i].pose.position.y - a[0].pose.position.y};
                    const glm::dvec2 db{b[i].pose.position.x - b[0].pose.position.x,
                                        b[i].pose.position.y - b[0].pose.position.y};
                    EXPECT_NEAR(db.x, f.scale * da.x, 1e-6);
                    EXPECT_NEAR(db.y, f.scale * da.y, 1e-6);
                    EXPECT_NEAR(b[i].pose.position.z - b[0].pose.position.z,
                                f.scale * (a[i].pose.position.z - a[0].pose.position.z), 1e-6);
                }
            }
            // Inside the map and above its ground all along, by the path's own lowest height.
            const double t0 = f.trajectory.startTime(), t1 = f.trajectory.endTime();
            double lowest = 1e300;
            for (const auto& s : a)
                lowest = std::min(lowest, s.pose.position.z);
            for (int k = 0; k <= 200; ++k) {
                const glm::dvec3 p = f.trajectory.poseAt(t0 + (t1 - t0) * k / 200).position;
                EXPECT_GT(p.x, 0.0);
                EXPECT_LT(p.x, map->extentX());
                EXPECT_GT(p.y, 0.0);
                EXPECT_LT(p.y, map->extentY());
                EXPECT_GE(p.z - map->surfaceHeight(p.x, p.y), f.scale * lowest - 1e-6);
            }
        }
    }
}

}  // namespace
}  // namespace sim
