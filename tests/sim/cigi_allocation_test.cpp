// Once warmed up, a CIGI session's field (receive, decode, apply, answer, send) allocates
// nothing: every allocation in this test binary goes through the counting operator new
// (tests/common/counting_new.cpp).
#include <gtest/gtest.h>

#include "common/box_vox.hpp"
#include "common/counting_new.hpp"

#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <new>
#include <string>
#include <vector>

#include "ig/scene.hpp"
#include "ig/synthetic.hpp"
#include "ig/vox.hpp"
#include "io/cigi.hpp"
#include "io/udp_socket.hpp"
#include "sim/cigi_session.hpp"
#include "sim/truth.hpp"

namespace {

namespace cigi = io::cigi;

// A host's fields against a session, warmed for 10 fields then counted for 100; `objects`: the
// scene whose objects lines of sight meet (null: the terrain alone).
void expectWarmFieldsAllocateNothing(const ig::TerrainMap& map, const sim::TruthScene* objects) {
    io::UdpSocket host;
    ASSERT_EQ(host.open({0x7f000001, 0}), 0);
    sim::CigiOptions options;
    options.bind = {0x7f000001, 0};
    options.host = host.localEndpoint();
    options.origin = {47.0, -122.0, 0.0};
    options.startPose.position = {100.0, 100.0, map.maxHeight() + 100.0};
    options.entityTypes = {{10, 0, 2.0, 4, 2, 3}};
    options.objects = objects;
    sim::CigiPoseSource source(map, options);
    std::string error;
    ASSERT_EQ(source.open(&error), 0) << error;
    const io::UdpEndpoint ig = source.session().localEndpoint();
    const sim::GeoFrame& geo = source.session().geo();

    // What the host sends every field: ownship, rates, a HAT/HOT and a LOS question, an entity
    // and a sensor tracking it. (A refused
    // datagram does allocate: the codec words its refusal as it finds it, and the session asks
    // for the wording of the first four only, so the rest cost a few small strings each.)
    const glm::dvec3 g = geo.geodeticFromWorld({900.0, 800.0, map.maxHeight() + 50.0});
    cigi::IgControl control;
    cigi::EntityControl e;
    e.latOrX = g.x;
    e.lonOrY = g.y;
    e.altOrZ = g.z;
    cigi::RateControl r;
    r.xRate = 50.0f;
    cigi::HatHotRequest hat;
    hat.type = cigi::HatHotType::Extended;
    hat.latOrX = g.x;
    hat.lonOrY = g.y;
    cigi::LosVectorRequest los;
    los.extended = true;
    los.elevationDeg = -45.0f;
    los.maxRangeM = 5000.0f;
    los.sourceLatOrX = g.x;
    los.sourceLonOrY = g.y;
    los.sourceAltOrZ = g.z;
    // An entity ahead, tracked by an extended sensor.
    cigi::EntityControl other = e;
    other.entityId = 5;
    other.entityType = 10;
    const glm::dvec3 g5 = geo.geodeticFromWorld({900.0, 1200.0, map.maxHeight()});
    other.latOrX = g5.x;
    other.lonOrY = g5.y;
    other.altOrZ = g5.z;
    cigi::SensorControl sensor;
    sensor.sensorOn = true;
    sensor.trackMode = cigi::SensorTrackMode::Target;
    sensor.extendedResponse = true;
    cigi::ComponentControl target;
    target.componentClass = cigi::kComponentClassSensor;
    target.data[0] = 5;
    // A line of sight from the ownship to the entity, past the scene's box when there is one.
    cigi::LosSegmentRequest toEntity;
    toEntity.extended = true;
    toEntity.sourceLatOrX = g.x;
    toEntity.sourceLonOrY = g.y;
    toEntity.sourceAltOrZ = g.z;
    toEntity.destinationLatOrX = g5.x;
    toEntity.destinationLonOrY = g5.y;
    toEntity.destinationAltOrZ = g5.z;
    const std::vector<cigi::Packet> packets{control, e,      r,      hat,     los,
                                            other,   sensor, target, toEntity};
    const std::vector<std::uint8_t> good = cigi::encodeMessage(packets, cigi::ByteOrder::Big);
    const std::vector<std::uint8_t> bad(good.begin(), good.begin() + 30);
    std::vector<std::uint8_t> answers(65536);

    bool sendBad = false;
    auto field = [&](int n) {
        ASSERT_EQ(host.sendTo(good, ig), 0);
        if (sendBad) {
            ASSERT_EQ(host.sendTo(bad, ig), 0);
        }
        source.advanceTo(n * 1001.0 / 60000.0);
        (void)source.predict(n * 1001.0 / 60000.0 + 0.05);
        while (host.receive(answers) > 0) {
        }
    };
    for (int n = 0; n < 10; ++n)
        field(n);
    const std::size_t before = gAllocations.load();
    for (int n = 10; n < 110; ++n)
        field(n);
    EXPECT_EQ(gAllocations.load() - before, 0u);
    const sim::CigiStats& stats = source.session().stats();
    EXPECT_EQ(stats.entityUpdates, 110u);
    EXPECT_EQ(stats.answers, 330u);
    // The line meets the scene's box when there is a scene, else nothing but the terrain.
    const auto line = std::get<cigi::LosExtendedResponse>(
        source.session().answer(toEntity, 0, 110 * 1001.0 / 60000.0));
    EXPECT_EQ(line.entityIdValid, objects != nullptr);
    if (objects) {
        EXPECT_EQ(line.entityId, 900);
    }
    EXPECT_EQ(stats.badDatagrams, 0u);
    EXPECT_EQ(stats.sensorResponses, 110u);

    // Refused datagrams are counted whatever they cost.
    sendBad = true;
    for (int n = 110; n < 120; ++n)
        field(n);
    EXPECT_EQ(stats.badDatagrams, 10u);
}

TEST(CigiSessionAllocation, AFieldAllocatesNothingOnceWarm) {
    const ig::TerrainMap map = ig::makeSyntheticTerrain(64, 5, 30.0);
    expectWarmFieldsAllocateNothing(map, nullptr);
}

// The same with the objects of a scene, which lines of sight meet: a box standing in the line
// from the ownship to the entity, and one driving.
TEST(CigiSessionAllocation, LinesOfSightMeetingObjectsAllocateNothingOnceWarm) {
    const ig::TerrainMap map = ig::makeSyntheticTerrain(64, 5, 30.0);
    const std::string dir = std::string(VIG_TEST_TMP) + "/cigi-alloc-" + std::to_string(::getpid());
    std::filesystem::create_directories(dir);
    vig_test::writeBoxVox(dir + "/box.vox", 4, 2, 3);
    std::ofstream(dir + "/drive.csv") << "t,x,y,z,yaw_deg,pitch_deg,roll_deg\n"
                                         "0,600,600,0,0,0,0\n"
                                         "10,700,600,0,0,0,0\n";
    // The line runs from (900, 800, top + 50) to (900, 1200, top): at y = 1000 it is 25 m above
    // the top, inside a box standing there from 20 m above the top, 12 m tall.
    const double top = map.maxHeight();
    const ig::Scene scene = ig::parseScene(
        R"({"cell_m": 2, "models": {"box": {"vox": "box.vox"}},
            "objects": [{"id": 900, "model": "box", "x": 900, "y": 1000, "z": )" +
            std::to_string(top + 20.0) + R"(, "heading": 0, "scale": 4},
                        {"id": 901, "model": "box", "trajectory": "drive.csv", "scale": 4}]})",
        dir + "/scene.json", map);
    const sim::SceneMotion motion(scene);
    const sim::TruthScene objects(scene, motion, map);
    expectWarmFieldsAllocateNothing(map, &objects);
}

}  // namespace
