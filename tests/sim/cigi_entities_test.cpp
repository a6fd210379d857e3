// CIGI entities other than the ownship: placed, attached, dead-reckoned, destroyed, refused, and
// drawn by the scene's renderer where the reference caster puts the same model.
#include "sim/cigi_session.hpp"

#include "base/error.hpp"
#include "ig/caster.hpp"
#include "ig/scene.hpp"
#include "ig/shading.hpp"
#include "ig/vox.hpp"
#include "io/cigi.hpp"
#include "io/udp_socket.hpp"
#include "sim/frame_ring.hpp"
#include "sim/pipeline.hpp"
#include "sim/scene_motion.hpp"
#include "sim/truth.hpp"

#include "common/box_vox.hpp"
#include "common/cigi_host.hpp"

#include <gtest/gtest.h>
#include <glm/geometric.hpp>

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <string>
#include <vector>

namespace {

namespace cigi = io::cigi;

using vig_test::kLoopback;
constexpr double kDeg = std::numbers::pi / 180.0;
constexpr double kPeriod = 1001.0 / 60000.0;

using Host = vig_test::CigiHost;

// A flat map 100 m high (65 x 65 samples, 10 m apart).
ig::TerrainMap flatMap() {
    ig::TerrainMap map(65, 65, 10.0, 10.0, 0.1, 0.0);
    for (int iy = 0; iy < 65; ++iy) {
        for (int ix = 0; ix < 65; ++ix) {
            map.setRaw(ix, iy, 1000);
            map.setColor(ix, iy, ig::Rgb8{90, 140, 60});
        }
    }
    map.updateRange();
    return map;
}

std::string tmpDir() {
    const std::string dir =
        std::string(VIG_TEST_TMP) + "/cigi-entities-" + std::to_string(::getpid());
    std::filesystem::create_directories(dir);
    return dir;
}

// A model 4 x 2 x 3 voxels (so its heading shows), written once per test process.
std::string boxModel() {
    const std::string dir = tmpDir();
    vig_test::writeBoxVox(dir + "/box.vox", 4, 2, 3);
    return dir;
}

sim::CigiOptions optionsFor(const Host& host) {
    sim::CigiOptions o;
    o.bind = {kLoopback, 0};
    o.host = host.socket.localEndpoint();
    o.origin = {47.0, -122.0, 0.0};
    o.startPose.position = {320.0, 100.0, 300.0};
    o.entityTypes = {{10, 0, 4.0}, {11, 0, 2.0}};
    o.reservedIds = {900};
    return o;
}

// A small view to render: 96 x 64 pixels and a margin of 8.
sim::RenderGeometry smallView() {
    sim::RenderGeometry g;
    g.windowWidth = 96;
    g.windowHeight = 64;
    g.margin = 8;
    return g;
}

cigi::EntityControl entityAt(const sim::GeoFrame& geo, std::uint16_t id, std::uint16_t type,
                             glm::dvec3 world, float yawDeg) {
    cigi::EntityControl e;
    e.entityId = id;
    e.entityType = type;
    const glm::dvec3 g = geo.geodeticFromWorld(world);
    e.latOrX = g.x;
    e.lonOrY = g.y;
    e.altOrZ = g.z;
    e.yawDeg = yawDeg;
    return e;
}

cigi::EntityControl attached(std::uint16_t id, std::uint16_t parent, glm::dvec3 offset,
                             float yawDeg = 0.0f) {
    cigi::EntityControl e;
    e.entityId = id;
    e.entityType = 11;
    e.attached = true;
    e.parentId = parent;
    e.latOrX = offset.x;
    e.lonOrY = offset.y;
    e.altOrZ = offset.z;
    e.yawDeg = yawDeg;
    return e;
}

const sim::EntityPose* poseOf(const std::vector<sim::EntityPose>& poses, std::uint16_t id) {
    for (const sim::EntityPose& p : poses)
        if (p.id == id) return &p;
    return nullptr;
}

TEST(CigiEntities, PlacedAttachedDeadReckonedAndDestroyed) {
    const ig::TerrainMap map = flatMap();
    Host host;
    sim::CigiSession session(map, optionsFor(host));
    std::string error;
    ASSERT_EQ(session.open(&error), 0) << error;
    host.ig = session.localEndpoint();
    const sim::GeoFrame& geo = session.geo();

    // Entity 5 heading east at 10 m/s (CIGI world rates: x north, y east); 6 on it, 20 m ahead
    // and 3 m to its right, turned 90 degrees right; 7 on the ownship, 50 m below it.
    cigi::RateControl rate;
    rate.entityId = 5;
    rate.yRate = 10.0f;
    host.send({entityAt(geo, 5, 10, {300.0, 300.0, 100.0}, 90.0f), rate,
               attached(6, 5, {20.0, 3.0, 0.0}, 90.0f), attached(7, 0, {0.0, 0.0, 50.0})});
    session.poll(0.0);
    ASSERT_EQ(session.entities().size(), 3u) << session.stats().firstErrors.front();
    EXPECT_EQ(session.stats().entityControls, 3u);
    EXPECT_EQ(session.stats().entitiesRefused, 0u);

    std::vector<sim::EntityPose> poses;
    for (int n = 1; n <= 30; ++n) {
        const double t = n * kPeriod;
        session.poll(t);
        sim::entityPosesAt(session.entities(), session.ownship(), t, poses);
        ASSERT_EQ(poses.size(), 3u);
        const sim::EntityPose* e5 = poseOf(poses, 5);
        const sim::EntityPose* e6 = poseOf(poses, 6);
        const sim::EntityPose* e7 = poseOf(poses, 7);
        ASSERT_TRUE(e5 && e6 && e7);
        EXPECT_NEAR(e5->pose.position.x, 300.0 + 10.0 * t, 1e-6);
        EXPECT_NEAR(e5->pose.position.y, 300.0, 1e-6);
        EXPECT_NEAR(e5->pose.position.z, 100.0, 1e-6);
        EXPECT_NEAR(e5->pose.yaw, 90.0 * kDeg, 1e-9);
        EXPECT_EQ(e5->model, 0);
        EXPECT_EQ(e5->scale, 4.0);
        // Ahead of an east-facing parent is east, its right is south.
        EXPECT_NEAR(e6->pose.position.x, 320.0 + 10.0 * t, 1e-6);
        EXPECT_NEAR(e6->pose.position.y, 297.0, 1e-6);
        EXPECT_NEAR(e6->pose.position.z, 100.0, 1e-6);
        EXPECT_NEAR(std::remainder(e6->pose.yaw - 180.0 * kDeg, 2.0 * std::numbers::pi), 0.0, 1e-6);
        EXPECT_EQ(e6->scale, 2.0);
        // The ownship holds its start pose (no Entity Control for it): 50 m below it (z down).
        EXPECT_NEAR(e7->pose.position.x, 320.0, 1e-9);
        EXPECT_NEAR(e7->pose.position.y, 100.0, 1e-9);
        EXPECT_NEAR(e7->pose.position.z, 250.0, 1e-9);
    }

    // Inactive: kept, not drawn, and neither is its child; active again, both are back.
    cigi::EntityControl sleep = entityAt(geo, 5, 10, {300.0, 300.0, 100.0}, 90.0f);
    sleep.entityState = cigi::EntityState::Inactive;
    host.send({sleep});
    session.poll(31 * kPeriod);
    sim::entityPosesAt(session.entities(), session.ownship(), 31 * kPeriod, poses);
    EXPECT_EQ(session.entities().size(), 3u);
    ASSERT_EQ(poses.size(), 1u);
    EXPECT_EQ(poses[0].id, 7);
    sleep.entityState = cigi::EntityState::Active;
    host.send({sleep});
    session.poll(32 * kPeriod);
    sim::entityPosesAt(session.entities(), session.ownship(), 32 * kPeriod, poses);
    EXPECT_EQ(poses.size(), 3u);

    // Detach 6: its offset becomes a world position.
    cigi::EntityControl free6 = entityAt(geo, 6, 11, {100.0, 150.0, 120.0}, 45.0f);
    host.send({free6});
    session.poll(33 * kPeriod);
    sim::entityPosesAt(session.entities(), session.ownship(), 34 * kPeriod, poses);
    ASSERT_NE(poseOf(poses, 6), nullptr);
    EXPECT_NEAR(poseOf(poses, 6)->pose.position.x, 100.0, 1e-6);
    EXPECT_NEAR(poseOf(poses, 6)->pose.position.y, 150.0, 1e-6);
    EXPECT_NEAR(poseOf(poses, 6)->pose.yaw, 45.0 * kDeg, 1e-9);

    // Destroying 5 takes an entity attached to it along; 6, detached, stays.
    host.send({attached(8, 5, {0.0, 10.0, 0.0})});
    session.poll(34 * kPeriod);
    EXPECT_EQ(session.entities().size(), 4u);
    cigi::EntityControl destroy;
    destroy.entityId = 5;
    destroy.entityState = cigi::EntityState::Destroyed;
    host.send({destroy});
    session.poll(35 * kPeriod);
    sim::entityPosesAt(session.entities(), session.ownship(), 35 * kPeriod, poses);
    ASSERT_EQ(poses.size(), 2u);
    EXPECT_NE(poseOf(poses, 6), nullptr);
    EXPECT_NE(poseOf(poses, 7), nullptr);
    EXPECT_EQ(session.stats().entitiesDestroyed, 2u);

    // Reset forgets them all.
    host.send({});
    cigi::IgControl reset;
    reset.igMode = cigi::IgMode::Reset;
    const std::vector<cigi::Packet> resetMessage{reset};
    host.sendRaw(cigi::encodeMessage(resetMessage, cigi::ByteOrder::Big));
    session.poll(36 * kPeriod);
    EXPECT_TRUE(session.entities().empty());
}

TEST(CigiEntities, BadEntityPacketsAreRefusedAndReported) {
    const ig::TerrainMap map = flatMap();
    Host host;
    sim::CigiSession session(map, optionsFor(host));
    std::string error;
    ASSERT_EQ(session.open(&error), 0) << error;
    host.ig = session.localEndpoint();
    const sim::GeoFrame& geo = session.geo();
    host.send({entityAt(geo, 5, 10, {300.0, 300.0, 100.0}, 0.0f), attached(6, 5, {5, 0, 0})});
    session.poll(0.0);
    ASSERT_EQ(session.entities().size(), 2u);

    const auto refusedWith = [&](std::vector<cigi::Packet> packets, double t,
                                 const std::string& words) {
        const std::uint64_t before = session.stats().entitiesRefused;
        session.stats().firstErrors.clear();
        host.send(std::move(packets));
        session.poll(t);
        EXPECT_EQ(session.stats().entitiesRefused, before + 1) << words;
        ASSERT_FALSE(session.stats().firstErrors.empty()) << words;
        EXPECT_NE(session.stats().firstErrors.back().find(words), std::string::npos)
            << session.stats().firstErrors.back();
    };
    refusedWith({entityAt(geo, 9, 77, {10, 10, 10}, 0.0f)}, 1 * kPeriod, "type 77 maps to no");
    refusedWith({attached(5, 6, {1, 0, 0})}, 2 * kPeriod, "loop of parents");
    refusedWith({attached(9, 9, {1, 0, 0})}, 3 * kPeriod, "attached to itself");
    refusedWith({attached(9, 44, {1, 0, 0})}, 4 * kPeriod, "parent 44 does not exist");
    refusedWith({entityAt(geo, 900, 10, {10, 10, 10}, 0.0f)}, 5 * kPeriod, "taken by an object");
    cigi::RateControl nobody;
    nobody.entityId = 123;
    refusedWith({nobody}, 6 * kPeriod, "no such entity");
    cigi::RateControl local;
    local.entityId = 6;
    local.localCoordinates = true;
    refusedWith({local}, 7 * kPeriod, "attached entity");
    // The loop refused, 5 is still top-level and 6 still on it.
    ASSERT_EQ(session.entities().size(), 2u);
    EXPECT_FALSE(session.entities()[0].attached);
    EXPECT_EQ(session.entities()[1].parent, 5);

    // NaN and out-of-range positions never reach the session: the codec refuses the datagram.
    const std::uint64_t bad = session.stats().badDatagrams;
    {
        // The encoder refuses to write a NaN: the x offset's bytes (after the 24-byte IG Control,
        // 24 bytes into Entity Control) are overwritten with a big-endian quiet NaN.
        cigi::IgControl control;
        control.igMode = cigi::IgMode::Operate;
        control.hostFrameNumber = ++host.frame;
        const std::vector<cigi::Packet> packets{control, attached(6, 5, {1.0, 0, 0})};
        std::vector<std::uint8_t> bytes = cigi::encodeMessage(packets, cigi::ByteOrder::Big);
        ASSERT_EQ(bytes.size(), 24u + 48u);
        const std::uint8_t nan[8] = {0x7f, 0xf8, 0, 0, 0, 0, 0, 0};
        std::copy(nan, nan + 8, bytes.begin() + 48);
        host.sendRaw(bytes);
    }
    {
        // A latitude of 95 degrees, written over a good one the same way.
        cigi::IgControl control;
        control.igMode = cigi::IgMode::Operate;
        control.hostFrameNumber = ++host.frame;
        const std::vector<cigi::Packet> packets{control, entityAt(geo, 7, 10, {10, 10, 10}, 0.0f)};
        std::vector<std::uint8_t> bytes = cigi::encodeMessage(packets, cigi::ByteOrder::Big);
        const std::uint8_t lat95[8] = {0x40, 0x57, 0xc0, 0, 0, 0, 0, 0};  // 95.0
        std::copy(lat95, lat95 + 8, bytes.begin() + 48);
        host.sendRaw(bytes);
    }
    session.poll(8 * kPeriod);
    EXPECT_EQ(session.stats().badDatagrams, bad + 2);
    EXPECT_EQ(session.entities().size(), 2u);
    EXPECT_EQ(session.entities()[1].motion.pose.position.x, 5.0);

    // More entities than the session keeps: refused, the others unharmed.
    sim::CigiOptions few = optionsFor(host);
    few.maxEntities = 3;
    sim::CigiSession small(map, few);
    ASSERT_EQ(small.open(&error), 0) << error;
    host.ig = small.localEndpoint();
    for (std::uint16_t id = 1; id <= 5; ++id)
        host.send({entityAt(geo, id, 10, {100.0 * id, 100.0, 100.0}, 0.0f)});
    small.poll(0.0);
    EXPECT_EQ(small.entities().size(), 3u);
    EXPECT_EQ(small.stats().entitiesRefused, 2u);
}

TEST(CigiEntities, TypeToModelFlag) {
    const std::vector<std::string> names{"box", "tank"};
    const sim::EntityTypeModel m =
        sim::parseEntityTypeModel("1201=tank:2.5", "--cigi-entity", names);
    EXPECT_EQ(m.type, 1201);
    EXPECT_EQ(m.model, 1);
    EXPECT_EQ(m.scale, 2.5);
    EXPECT_EQ(sim::parseEntityTypeModel("7=box", "--cigi-entity", names).scale, 1.0);
    for (const char* bad : {"tank", "70000=tank", "-1=tank", "1.5=tank", "1=truck", "1=tank:0",
                            "1=tank:nan", "=tank"}) {
        try {
            sim::parseEntityTypeModel(bad, "--cigi-entity", names);
            ADD_FAILURE() << bad << " accepted";
        } catch (const base::InputError& e) {
            EXPECT_NE(std::string(e.what()).find("--cigi-entity"), std::string::npos) << e.what();
        }
    }
}

// The host places an entity of a model; the scene's renderer, asking the pose source at the
// frame's instant, draws it exactly where the reference caster draws the same model placed as a
// static object of a scene file at that pose: the same object-id image, pixel for pixel.
TEST(CigiEntities, DrawnWhereTheReferenceCasterPutsTheModel) {
    ig::TerrainMap map = flatMap();
    const std::string dir = boxModel();
    const ig::Scene hostScene =
        ig::parseScene(R"({"cell_m": 2, "models": {"box": {"vox": "box.vox"}}, "objects": []})",
                       dir + "/host.json", map);
    const sim::SceneMotion hostMotion(hostScene);
    const ig::Scene staticScene = ig::parseScene(
        R"({"cell_m": 2, "models": {"box": {"vox": "box.vox"}},
            "objects": [{"id": 42, "model": "box", "x": 312, "y": 330, "heading": 30,
                         "scale": 4}]})",
        dir + "/static.json", map);

    Host host;
    sim::CigiOptions options = optionsFor(host);
    options.entityTypes = {{10, hostScene.modelIndex("box"), 4.0}};
    sim::CigiPoseSource source(map, options);
    std::string error;
    ASSERT_EQ(source.open(&error), 0) << error;
    host.ig = source.session().localEndpoint();

    // The ownship 200 m south of the box, 60 m up, looking north and a little down.
    cigi::EntityControl own;
    own.entityId = 0;
    const glm::dvec3 eye{312.0, 130.0, 160.0};
    const glm::dvec3 g = source.session().geo().geodeticFromWorld(eye);
    own.latOrX = g.x;
    own.lonOrY = g.y;
    own.altOrZ = g.z;
    own.pitchDeg = -10.0f;
    cigi::EntityControl box = entityAt(source.session().geo(), 42, 10, {312.0, 330.0, 0.0}, 30.0f);
    box.groundClamp = cigi::GroundClamp::NonConformal;
    host.send({own, box});
    const ig::Pose pose = source.advanceTo(0.0);
    EXPECT_NEAR(pose.position.y, 130.0, 1e-6);

    sim::RenderGeometry geometry;
    geometry.windowWidth = 96;
    geometry.windowHeight = 64;
    geometry.hfov = 40.0 * kDeg;
    geometry.margin = 8;
    const sim::FrameRenderer hostDriven = sim::makeSceneRenderer(
        map, geometry, ig::CasterKind::Reference, {}, hostScene, hostMotion,
        [&](double t, std::vector<sim::ExtraObject>& out) { source.objectsAt(t, out); });
    const ig::RenderedFrame a = hostDriven(source.predict(0.0), 0.0, 1);

    ig::RenderOptions withObjects;
    ig::ObjectLayer empty(map, staticScene.cellSize);
    empty.finish();
    withObjects.objects = {staticScene.staticLayer.get(), &empty};
    const auto reference = ig::makeCaster(ig::CasterKind::Reference, map, withObjects);
    const ig::RenderedFrame b =
        ig::renderFrame(*reference, map, pose, sim::renderIntrinsics(geometry, pose), 0.0, 1);
    ASSERT_EQ(a.objectId.size(), b.objectId.size());
    const auto shown = std::count(a.objectId.begin(), a.objectId.end(), std::uint16_t{42});
    EXPECT_GT(shown, 50) << "the box should cover a patch of the frame";
    EXPECT_EQ(a.objectId, b.objectId);
    EXPECT_EQ(a.depth, b.depth);

    // Destroyed: the next frame shows terrain only.
    cigi::EntityControl gone;
    gone.entityId = 42;
    gone.entityState = cigi::EntityState::Destroyed;
    host.send({gone});
    source.advanceTo(kPeriod);
    const ig::RenderedFrame c = hostDriven(source.predict(kPeriod), kPeriod, 2);
    EXPECT_EQ(std::count(c.objectId.begin(), c.objectId.end(), std::uint16_t{42}), 0);
}

// A View Control may put the view on another of the host's entities: the eye then rides that
// entity, dead-reckoned to each field (and to the renderer's predictions); one naming an entity
// the host has not created is refused; when the entity is destroyed the view is back on the
// ownship.
TEST(CigiView, ViewOnAnotherEntityRidesIt) {
    const ig::TerrainMap map = flatMap();
    Host host;
    const sim::CigiOptions options = optionsFor(host);
    sim::CigiPoseSource source(map, options);
    std::string error;
    ASSERT_EQ(source.open(&error), 0) << error;
    host.ig = source.session().localEndpoint();
    const sim::GeoFrame& geo = source.session().geo();
    cigi::EntityControl e5 = entityAt(geo, 5, 10, {300.0, 300.0, 250.0}, 30.0f);
    e5.pitchDeg = 5.0f;
    cigi::RateControl rate;
    rate.entityId = 5;
    rate.yRate = 8.0f;  // CIGI world rates: y east
    cigi::ViewControl vc;
    vc.viewId = static_cast<std::uint16_t>(options.viewId);
    vc.entityId = 5;
    vc.xEnable = vc.zEnable = vc.pitchEnable = true;
    vc.x = 2.0f;
    vc.z = -3.0f;  // z down: 3 m up
    vc.pitchDeg = -20.0f;
    host.send({e5, rate, vc});
    const ig::Pose first = source.advanceTo(0.0);
    EXPECT_EQ(source.session().viewEntity(), 5);
    const sim::ViewOffset view{{2.0, 0.0, -3.0}, 0.0, -20.0 * kDeg, 0.0};
    const auto entityAtT = [&](double t) {
        ig::Pose p;
        EXPECT_TRUE(sim::entityPoseAt(source.session().entities(), source.session().ownship(), 5, t,
                                      map, p));
        return p;
    };
    const auto near = [](const ig::Pose& a, const ig::Pose& b) {
        return glm::length(a.position - b.position) < 1e-9 && std::abs(a.yaw - b.yaw) < 1e-12 &&
               std::abs(a.pitch - b.pitch) < 1e-12 && std::abs(a.roll - b.roll) < 1e-12;
    };
    EXPECT_TRUE(near(first, sim::eyePose(entityAtT(0.0), view)));
    EXPECT_NEAR(first.position.z, 250.0 + 3.0 * std::cos(5.0 * kDeg) + 2.0 * std::sin(5.0 * kDeg),
                1e-6);  // 3 m up and 2 m ahead in the axes of an entity pitched 5 degrees up
    // Half a second on: 4 m further east, on the field thread and in the renderer's prediction.
    const double t = 30 * kPeriod;
    const ig::Pose later = source.advanceTo(t);
    EXPECT_NEAR(later.position.x - first.position.x, 8.0 * t, 1e-6);
    EXPECT_NEAR(later.position.y, first.position.y, 1e-6);
    EXPECT_TRUE(near(later, sim::eyePose(entityAtT(t), view)));
    EXPECT_TRUE(near(source.predict(t), later));
    EXPECT_NEAR(source.predict(t + 0.25).position.x - later.position.x, 2.0, 1e-6);

    // An entity the host has not created: refused, the view stays on entity 5.
    vc.entityId = 77;
    host.send({vc});
    const ig::Pose kept = source.advanceTo(t + kPeriod);
    EXPECT_TRUE(near(kept, sim::eyePose(entityAtT(t + kPeriod), view)));
    bool named = false;
    for (const std::string& e : source.session().stats().firstErrors)
        named = named || e.find("names entity 77") != std::string::npos;
    EXPECT_TRUE(named);
    // Destroyed: back on the ownship.
    cigi::EntityControl gone;
    gone.entityId = 5;
    gone.entityState = cigi::EntityState::Destroyed;
    host.send({gone});
    const ig::Pose own = source.advanceTo(t + 2 * kPeriod);
    EXPECT_TRUE(near(own, sim::eyePose(source.session().ownship().at(t + 2 * kPeriod), view)));
    EXPECT_TRUE(near(source.predict(t + 2 * kPeriod), own));
}

// A line of sight meets the scene's objects and the host's entities (each by its exact model)
// before the terrain: the range to the face it meets, the object's id as the entity id, the
// voxel's colour and the face's normal; past an object (minimum range) it goes on to the ground.
TEST(CigiLineOfSight, MeetsObjectsAndEntitiesBeforeTheTerrain) {
    ig::TerrainMap map = flatMap();  // the ground 100 m up
    const std::string dir = boxModel();
    std::ofstream(dir + "/east.csv") << "t,x,y,z,yaw_deg,pitch_deg,roll_deg\n"
                                        "0,200,200,0,0,0,0\n"
                                        "10,300,200,0,0,0,0\n";
    // Boxes of 4 x 2 x 3 voxels of 4 m, heading north: 16 m east-west, 8 m north-south, 12 m
    // tall. The static one spans x 312..328, y 326..334; the moving one x 242..258, y 196..204
    // at t = 5 s.
    const ig::Scene scene = ig::parseScene(
        R"({"cell_m": 2, "models": {"box": {"vox": "box.vox"}},
            "objects": [{"id": 42, "model": "box", "x": 320, "y": 330, "heading": 0, "scale": 4},
                        {"id": 43, "model": "box", "trajectory": "east.csv", "scale": 4}]})",
        dir + "/lines.json", map);
    const sim::SceneMotion motion(scene);
    const sim::TruthScene objects(scene, motion, map);
    Host host;
    sim::CigiOptions options = optionsFor(host);
    options.entityTypes = {{10, scene.modelIndex("box"), 4.0}};
    options.objects = &objects;
    sim::CigiSession session(map, options);
    std::string error;
    ASSERT_EQ(session.open(&error), 0) << error;
    host.ig = session.localEndpoint();
    const sim::GeoFrame& geo = session.geo();
    // Entity 5, the same box on the ground spanning x 442..458, y 446..454.
    cigi::EntityControl e5 = entityAt(geo, 5, 10, {450.0, 450.0, 0.0}, 0.0f);
    e5.groundClamp = cigi::GroundClamp::NonConformal;
    host.send({e5});
    const double t = 5.0;
    session.poll(t);
    ASSERT_EQ(session.entities().size(), 1u);

    const auto segment = [&](glm::dvec3 from, glm::dvec3 to) {
        cigi::LosSegmentRequest q;
        q.extended = true;
        const glm::dvec3 a = geo.geodeticFromWorld(from), b = geo.geodeticFromWorld(to);
        q.sourceLatOrX = a.x;
        q.sourceLonOrY = a.y;
        q.sourceAltOrZ = a.z;
        q.destinationLatOrX = b.x;
        q.destinationLonOrY = b.y;
        q.destinationAltOrZ = b.z;
        return std::get<cigi::LosExtendedResponse>(session.answer(q, 0, t));
    };
    const ig::Rgba8 color = scene.models[0]->color(0, 0, 0);
    struct Case {
        glm::dvec3 from, to;
        std::uint16_t id;
        double range, azimuthDeg;
    };
    const Case cases[] = {
        {{250.0, 330.0, 106.0}, {400.0, 330.0, 106.0}, 42, 62.0, 270.0},  // east to the static box
        {{320.0, 250.0, 111.0}, {320.0, 400.0, 111.0}, 42, 76.0, 180.0},  // north to it
        {{250.0, 100.0, 104.0}, {250.0, 300.0, 104.0}, 43, 96.0, 180.0},  // the moving box at t
        {{450.0, 400.0, 104.0}, {450.0, 500.0, 104.0}, 5, 46.0, 180.0},   // the host's entity
        {{520.0, 450.0, 110.0}, {400.0, 450.0, 110.0}, 5, 62.0, 90.0},    // it from the east
    };
    for (const Case& c : cases) {
        const cigi::LosExtendedResponse r = segment(c.from, c.to);
        ASSERT_TRUE(r.valid && r.rangeValid) << c.id;
        EXPECT_FALSE(r.visible) << c.id;
        EXPECT_TRUE(r.entityIdValid) << c.id;
        EXPECT_EQ(r.entityId, c.id);
        EXPECT_NEAR(r.rangeM, c.range, 1e-6) << c.id;
        EXPECT_NEAR(r.normalAzimuthDeg, c.azimuthDeg, 1e-3) << c.id;
        EXPECT_NEAR(r.normalElevationDeg, 0.0, 1e-3) << c.id;
        EXPECT_EQ(r.red, color.r);
        EXPECT_EQ(r.green, color.g);
        EXPECT_EQ(r.blue, color.b);
        EXPECT_EQ(r.alpha, color.a);
        const glm::dvec3 hit = geo.worldFromGeodetic(r.latOrX, r.lonOrY, r.altOrZ);
        EXPECT_NEAR(glm::length(hit - (c.from + c.range * glm::normalize(c.to - c.from))), 0.0,
                    1e-6);
    }
    // From above: the top face, elevation 90.
    const cigi::LosExtendedResponse top = segment({320.0, 330.0, 150.0}, {320.0, 330.0, 50.0});
    EXPECT_EQ(top.entityId, 42);
    EXPECT_NEAR(top.rangeM, 38.0, 1e-6);
    EXPECT_NEAR(top.normalElevationDeg, 90.0, 1e-3);
    // A line that passes beside the box meets the ground beyond it, as the terrain alone.
    const cigi::LosExtendedResponse beside = segment({250.0, 340.0, 106.0}, {400.0, 340.0, 90.0});
    EXPECT_TRUE(beside.valid);
    EXPECT_FALSE(beside.entityIdValid);
    const ig::RayHit ground = ig::intersectTerrain(map, {250.0, 340.0, 106.0}, {150.0, 0.0, -16.0});
    EXPECT_NEAR(beside.rangeM, ground.distance, 1e-6);
    // A minimum range past the box: the same line goes on through it to the ground.
    cigi::LosVectorRequest v;
    v.extended = true;
    v.azimuthDeg = 90.0f;
    v.elevationDeg = -2.0f;
    v.minRangeM = 80.0f;
    v.maxRangeM = 1000.0f;
    const glm::dvec3 g = geo.geodeticFromWorld({250.0, 330.0, 106.0});
    v.sourceLatOrX = g.x;
    v.sourceLonOrY = g.y;
    v.sourceAltOrZ = g.z;
    const auto past = std::get<cigi::LosExtendedResponse>(session.answer(v, 0, t));
    EXPECT_TRUE(past.valid);
    EXPECT_FALSE(past.entityIdValid);
    EXPECT_NEAR(past.rangeM, 6.0 / std::sin(2.0 * kDeg), 1e-3);
    v.minRangeM = 0.0f;
    const auto met = std::get<cigi::LosExtendedResponse>(session.answer(v, 0, t));
    EXPECT_EQ(met.entityId, 42);
    // A line from entity 5, 6 m above its base in its own axes, to the static box: it does not
    // meet its own model, and meets the box's north face.
    cigi::LosSegmentRequest fromEntity;
    fromEntity.extended = true;
    fromEntity.sourceEntityCoordinates = true;
    fromEntity.entityId = 5;
    fromEntity.sourceAltOrZ = -6.0;  // z down
    const glm::dvec3 gb = geo.geodeticFromWorld({320.0, 330.0, 106.0});
    fromEntity.destinationLatOrX = gb.x;
    fromEntity.destinationLonOrY = gb.y;
    fromEntity.destinationAltOrZ = gb.z;
    const auto seen = std::get<cigi::LosExtendedResponse>(session.answer(fromEntity, 0, t));
    EXPECT_TRUE(seen.valid);
    EXPECT_EQ(seen.entityId, 42);
    EXPECT_NEAR(seen.rangeM, (450.0 - 334.0) / 120.0 * std::hypot(130.0, 120.0), 1e-6);
    EXPECT_NEAR(seen.normalAzimuthDeg, 0.0, 1e-3);
    // Height above the terrain of a point 10 m ahead of entity 5 and 6 m up; an unknown
    // entity's offsets answer invalid.
    cigi::HatHotRequest hat;
    hat.type = cigi::HatHotType::Hat;
    hat.entityCoordinates = true;
    hat.entityId = 5;
    hat.latOrX = 10.0;
    hat.altOrZ = -6.0;
    const auto above = std::get<cigi::HatHotResponse>(session.answer(hat, 0, t));
    EXPECT_TRUE(above.valid);
    EXPECT_NEAR(above.heightM, 6.0, 1e-6);
    hat.entityId = 77;
    EXPECT_FALSE(std::get<cigi::HatHotResponse>(session.answer(hat, 0, t)).valid);

    // Without the objects the session sees the terrain alone.
    options.objects = nullptr;
    sim::CigiSession bare(map, options);
    const auto alone = std::get<cigi::LosExtendedResponse>(bare.answer(v, 0, t));
    EXPECT_FALSE(alone.entityIdValid);
    EXPECT_NEAR(alone.rangeM, past.rangeM, 1e-6);
}

// A View Definition's far plane is the draw distance: taken before the run, refused when it
// changes during it; the renderer draws what lies beyond it as sky and leaves the rest alone.
TEST(CigiView, FarPlaneIsTheDrawDistance) {
    ig::TerrainMap map = flatMap();
    Host host;
    sim::CigiSession session(map, optionsFor(host));
    std::string error;
    ASSERT_EQ(session.open(&error), 0) << error;
    host.ig = session.localEndpoint();
    EXPECT_TRUE(std::isinf(session.viewFar()));
    cigi::ViewDefinition vd;
    vd.farEnable = true;
    vd.farM = 300.0f;
    host.send({vd});
    session.poll(0.0);
    EXPECT_EQ(session.viewFar(), 300.0);
    EXPECT_EQ(session.stats().viewDefinitions, 1u);
    session.freezeFar(300.0);
    vd.farM = 500.0f;
    host.send({vd});
    vd.nearEnable = true;
    vd.nearM = 400.0f;
    vd.farM = 300.0f;
    host.send({vd});  // far before near
    session.poll(kPeriod);
    // Another far plane during the run is the draw distance of the renders asked from then on;
    // one before the near plane is refused.
    EXPECT_EQ(session.viewFar(), 500.0);
    EXPECT_EQ(session.fieldFar(), 500.0);
    EXPECT_EQ(session.stats().farPlaneChanges, 1u);
    EXPECT_EQ(session.stats().viewDefinitionsNotApplied, 1u);
    ASSERT_EQ(session.stats().firstErrors.size(), 1u);
    EXPECT_NE(session.stats().firstErrors[0].find("beyond the near plane"), std::string::npos);

    // Rendered with and without it: pixels nearer than the far plane identical, the others sky
    // along their own ray; control points beyond it become directions.
    sim::RenderGeometry geometry = smallView();
    ig::Pose pose;
    pose.position = {320.0, 20.0, 130.0};
    pose.pitch = -4.0 * kDeg;
    ig::RenderOptions options;
    const ig::RenderedFrame all =
        sim::makeCasterRenderer(map, geometry, ig::CasterKind::Reference, options)(pose, 0.0, 1);
    geometry.farM = 300.0;
    const ig::RenderedFrame near =
        sim::makeCasterRenderer(map, geometry, ig::CasterKind::Reference, options)(pose, 0.0, 1);
    ASSERT_EQ(all.depth.size(), near.depth.size());
    const ig::Camera camera(all.pose, all.intrinsics);
    std::size_t kept = 0, clipped = 0;
    for (int y = 0; y < all.intrinsics.height; ++y) {
        for (int x = 0; x < all.intrinsics.width; ++x) {
            const std::size_t i = static_cast<std::size_t>(y) * all.intrinsics.width + x;
            if (all.depth[i] <= 300.0f) {
                ++kept;
                ASSERT_EQ(near.depth[i], all.depth[i]);
                ASSERT_EQ(near.color[i], all.color[i]);
            } else {
                clipped += all.depth[i] != ig::kSkyDepth;
                ASSERT_EQ(near.depth[i], ig::kSkyDepth);
                const glm::dvec3 d = glm::normalize(camera.rayDirection(x + 0.5, y + 0.5));
                ASSERT_EQ(near.color[i], ig::skyColor(options.sky, d.z)) << x << "," << y;
            }
        }
    }
    EXPECT_GT(kept, 500u);
    EXPECT_GT(clipped, 500u);
    int directions = 0;
    for (int k = 0; k < ig::kControlPointCount; ++k) {
        const ig::ControlPoint& a = all.controlPoints[k];
        const ig::ControlPoint& b = near.controlPoints[k];
        const glm::dvec3 d = glm::dvec3(a.world) - pose.position;
        if (a.world.w == 1.0 && glm::length(d) > 300.0) {
            ++directions;
            EXPECT_EQ(b.world.w, 0.0);
            EXPECT_NEAR(glm::length(glm::dvec3(b.world) - glm::normalize(d)), 0.0, 1e-12);
        } else {
            EXPECT_EQ(b.world, a.world);
        }
    }
    EXPECT_GT(directions, 0);
}

// A View Definition's near plane: taken before the run and during it (for the renders asked
// from then on), refused when not short of the far plane; the renderer draws nothing nearer
// than it and leaves what lies beyond alone.
TEST(CigiView, NearPlaneClipsWhatIsNearer) {
    ig::TerrainMap map = flatMap();
    Host host;
    sim::CigiSession session(map, optionsFor(host));
    std::string error;
    ASSERT_EQ(session.open(&error), 0) << error;
    host.ig = session.localEndpoint();
    EXPECT_EQ(session.viewNear(), 0.0);
    EXPECT_EQ(session.fieldNear(), -1.0);  // the renderer's own before the run
    cigi::ViewDefinition vd;
    vd.nearEnable = true;
    vd.nearM = 40.0f;
    host.send({vd});
    session.poll(0.0);
    EXPECT_EQ(session.viewNear(), 40.0);
    EXPECT_EQ(session.stats().viewDefinitions, 1u);
    session.freezeNear(40.0);
    EXPECT_EQ(session.fieldNear(), 40.0);
    vd.nearM = 25.0f;
    host.send({vd});
    vd.farEnable = true;
    vd.farM = 20.0f;
    host.send({vd});  // near beyond far (a negative one the codec refuses)
    session.poll(kPeriod);
    EXPECT_EQ(session.viewNear(), 25.0);
    EXPECT_EQ(session.fieldNear(), 25.0);
    EXPECT_EQ(session.stats().nearPlaneChanges, 1u);
    EXPECT_EQ(session.stats().viewDefinitionsNotApplied, 1u);
    ASSERT_GE(session.stats().firstErrors.size(), 1u);
    EXPECT_NE(session.stats().firstErrors[0].find("near plane"), std::string::npos)
        << session.stats().firstErrors[0];
    // The view the field loop passes on, and the renderer process's request, carry it.
    sim::FrameRing ring(64);
    sim::RenderView view;
    view.nearM = session.fieldNear();
    ring.postRequest(ig::Pose{}, 1.5, 7, {}, view);
    EXPECT_EQ(ring.latestRequest().view.nearM, 25.0);

    // Rendered with and without it, low over the ground looking down: pixels beyond the plane
    // identical, none nearer than it; the ground cut open shows the sky along each ray.
    sim::RenderGeometry geometry = smallView();
    ig::Pose pose;
    pose.position = {320.0, 320.0, 110.0};
    pose.pitch = -30.0 * kDeg;
    ig::RenderOptions renderOptions;
    const ig::RenderedFrame all =
        sim::makeCasterRenderer(map, geometry, ig::CasterKind::Fast, renderOptions)(pose, 0.0, 1);
    geometry.nearM = 25.0;
    const ig::RenderedFrame cut =
        sim::makeCasterRenderer(map, geometry, ig::CasterKind::Fast, renderOptions)(pose, 0.0, 1);
    EXPECT_EQ(cut.nearM, 25.0);
    sim::RenderView none;
    none.nearM = 0.0;
    EXPECT_EQ(sim::viewed(geometry, none).nearM, 0.0);  // a host's 0 takes it away
    EXPECT_EQ(sim::viewed(geometry, {}).nearM, 25.0);   // no view: the geometry's own
    const ig::Camera camera(all.pose, all.intrinsics);
    std::size_t kept = 0, clipped = 0;
    for (int y = 0; y < all.intrinsics.height; ++y) {
        for (int x = 0; x < all.intrinsics.width; ++x) {
            const std::size_t i = static_cast<std::size_t>(y) * all.intrinsics.width + x;
            const glm::dvec3 d = glm::normalize(camera.rayDirection(x + 0.5, y + 0.5));
            const double ahead = all.depth[i] * glm::dot(d, camera.basis().forward);
            if (ahead > 25.0 * (1.0 + 1e-6)) {
                ++kept;
                ASSERT_EQ(cut.depth[i], all.depth[i]);
                ASSERT_EQ(cut.color[i], all.color[i]);
            } else if (ahead < 25.0 * (1.0 - 1e-6)) {
                ++clipped;
                ASSERT_EQ(cut.depth[i], ig::kSkyDepth) << x << "," << y;  // flat ground
                ASSERT_EQ(cut.color[i], ig::skyColor(renderOptions.sky, d.z)) << x << "," << y;
            }
        }
    }
    EXPECT_GT(kept, 500u);
    EXPECT_GT(clipped, 500u);
}

}  // namespace

namespace {

// The flat map with a ridge 200 m high across it at y = 320 m.
ig::TerrainMap ridgeMap() {
    ig::TerrainMap map = flatMap();
    for (int ix = 0; ix < 65; ++ix)
        map.setRaw(ix, 32, 3000);
    map.updateRange();
    return map;
}

// The sensor responses of one Start of Frame datagram.
std::vector<cigi::Packet> sensorPackets(Host& host) {
    std::vector<cigi::Packet> out;
    for (const cigi::Message& m : host.receiveAll()) {
        for (const cigi::Packet& p : m.packets) {
            if (std::holds_alternative<cigi::SensorResponse>(p) ||
                std::holds_alternative<cigi::SensorExtendedResponse>(p)) {
                out.push_back(p);
            }
        }
    }
    return out;
}

cigi::ComponentControl sensorTarget(std::uint8_t sensor, std::uint32_t entity) {
    cigi::ComponentControl c;
    c.componentClass = cigi::kComponentClassSensor;
    c.instanceId = sensor;
    c.componentId = 0;
    c.data[0] = entity;
    return c;
}

TEST(CigiSensors, TrackedEntityIsWhereTheFieldsCameraProjectsIt) {
    const ig::TerrainMap map = ridgeMap();
    Host host;
    sim::CigiOptions options = optionsFor(host);
    options.windowWidth = 720;
    options.windowHeight = 486;
    options.entityTypes[0].sizeX = 4;  // type 10: the box model at scale 4 (16 x 8 x 12 m)
    options.entityTypes[0].sizeY = 2;
    options.entityTypes[0].sizeZ = 3;
    sim::CigiSession session(map, options);
    std::string error;
    ASSERT_EQ(session.open(&error), 0) << error;
    host.ig = session.localEndpoint();
    const double hfov = 60.0 * kDeg;
    session.freezeFieldOfView(hfov);
    const sim::GeoFrame& geo = session.geo();

    // The ownship 50 m above the plain, looking north at the ridge; entity 5 on the plain in
    // front of it, 6 behind it, both clamped to the ground; sensor 2 tracks 5 (extended
    // answers), sensor 3 tracks 6 (short answers).
    cigi::EntityControl own = entityAt(geo, 0, 0, {320.0, 100.0, 150.0}, 0.0f);
    own.pitchDeg = -5.0f;
    cigi::EntityControl e5 = entityAt(geo, 5, 10, {347.0, 250.0, 100.0}, 0.0f);
    cigi::EntityControl e6 = entityAt(geo, 6, 10, {320.0, 500.0, 100.0}, 0.0f);
    cigi::SensorControl s2;
    s2.viewId = 0;
    s2.sensorId = 2;
    s2.sensorOn = true;
    s2.trackMode = cigi::SensorTrackMode::Target;
    s2.extendedResponse = true;
    cigi::SensorControl s3 = s2;
    s3.sensorId = 3;
    s3.extendedResponse = false;
    cigi::RateControl rate;  // entity 5 drives east at 5 m/s
    rate.entityId = 5;
    rate.yRate = 5.0f;
    host.send({own, e5, e6, rate, s2, s3, sensorTarget(2, 5), sensorTarget(3, 6)});
    session.poll(0.0);
    ASSERT_EQ(session.stats().sensorTargets, 2u)
        << (session.stats().firstErrors.empty() ? "" : session.stats().firstErrors.front());
    (void)host.receiveAll();

    ig::ObjectModel model432;
    model432.grid = ig::VoxModel(4, 2, 3);
    for (int n = 1; n <= 10; ++n) {
        const double t = n * kPeriod;
        session.poll(t);
        const std::vector<cigi::Packet> got = sensorPackets(host);
        ASSERT_EQ(got.size(), 2u);
        const auto* x = std::get_if<cigi::SensorExtendedResponse>(&got[0]);
        const auto* s = std::get_if<cigi::SensorResponse>(&got[1]);
        ASSERT_TRUE(x && s);
        // Entity 5: tracked, the middle of its box where the field's camera projects it (an
        // independent path: the pixel from ig::Camera, turned back into angles from the axis),
        // the gate the pixels its box's corners project to.
        const ig::Pose eye = session.ownship().at(t);
        const glm::dvec3 base5{347.0 + 5.0 * t, 250.0, 100.0};
        const glm::dvec3 p5 = base5 + glm::dvec3(0.0, 0.0, 6.0);
        const ig::Camera camera(eye, ig::Intrinsics::fromFov(720, 486, hfov));
        double x0 = 1e9, x1 = -1e9, y0 = 1e9, y1 = -1e9;
        for (int c = 0; c < 8; ++c) {
            const auto q =
                camera.project(base5 + glm::dvec3((c & 1) ? 8.0 : -8.0, (c & 2) ? 4.0 : -4.0,
                                                  (c & 4) ? 12.0 : 0.0));
            ASSERT_TRUE(q.has_value());
            x0 = std::min(x0, q->x);
            x1 = std::max(x1, q->x);
            y0 = std::min(y0, q->y);
            y1 = std::max(y1, q->y);
        }
        EXPECT_EQ(x->gateXSize, std::lround(x1 - x0));
        EXPECT_EQ(x->gateYSize, std::lround(y1 - y0));
        EXPECT_GT(x->gateXSize, 10);
        const auto px = camera.project(p5);
        ASSERT_TRUE(px.has_value());
        const double f = camera.intrinsics().focal;
        const double dx = px->x - camera.intrinsics().cx(), dy = camera.intrinsics().cy() - px->y;
        EXPECT_EQ(x->status, cigi::SensorStatus::Tracking);
        EXPECT_TRUE(x->entityIdValid);
        EXPECT_EQ(x->entityId, 5);
        EXPECT_EQ(x->sensorId, 2);
        EXPECT_EQ(x->frameCounter, session.igFrame() - 1);
        EXPECT_NEAR(x->gateXDeg, std::atan(dx / f) / kDeg, 1e-4);
        EXPECT_NEAR(x->gateYDeg, std::atan(dy / std::hypot(f, dx)) / kDeg, 1e-4);
        EXPECT_GT(x->gateXDeg, 0.5f);  // right of the axis, below it
        EXPECT_LT(x->gateYDeg, -5.0f);
        // The same point as the truth's: the middle of the box whose corners the truth writer
        // projects (sim::objectCorners, the centre its range_m measures to).
        sim::TruthObject truth;
        truth.model = &model432;
        truth.x = base5.x;
        truth.y = base5.y;
        truth.z = base5.z;
        truth.scale = 4.0;
        truth.hi[0] = 4;
        truth.hi[1] = 2;
        truth.hi[2] = 3;
        glm::dvec3 centre{0.0};
        for (const glm::dvec3& q : sim::objectCorners(truth))
            centre += 0.125 * q;
        EXPECT_NEAR(glm::length(centre - p5), 0.0, 1e-9);
        const glm::dvec3 g = geo.geodeticFromWorld(p5);
        EXPECT_NEAR(x->latDeg, g.x, 1e-9);
        EXPECT_NEAR(x->lonDeg, g.y, 1e-9);
        EXPECT_NEAR(x->altM, g.z, 1e-6);
        // Entity 6: in front of the eye and inside the window, but behind the ridge: lost.
        EXPECT_EQ(s->sensorId, 3);
        EXPECT_EQ(s->status, cigi::SensorStatus::Breaklock);
        const sim::SensorSight sight =
            sim::sightOf(map, eye, {320.0, 500.0, 100.0}, 720, 486, hfov);
        EXPECT_TRUE(sight.inFront && sight.inWindow && !sight.unoccluded);
    }

    // An unknown entity is refused and reported; the sensor keeps its target.
    host.send({sensorTarget(2, 77)});
    session.poll(11 * kPeriod);
    EXPECT_EQ(session.stats().sensorTargetsRefused, 1u);
    ASSERT_FALSE(session.stats().firstErrors.empty());
    EXPECT_NE(session.stats().firstErrors.back().find(
                  "Component Control for sensor 2: entity 77 is not an entity the host has placed"),
              std::string::npos)
        << session.stats().firstErrors.back();
    std::vector<cigi::Packet> got = sensorPackets(host);
    ASSERT_EQ(got.size(), 2u);
    EXPECT_EQ(std::get<cigi::SensorExtendedResponse>(got[0]).entityId, 5);

    // Destroyed, the target is lost; a sensor switched off answers no more.
    cigi::EntityControl destroy;
    destroy.entityId = 5;
    destroy.entityState = cigi::EntityState::Destroyed;
    s3.sensorOn = false;
    host.send({destroy, s3});
    session.poll(12 * kPeriod);
    got = sensorPackets(host);
    ASSERT_EQ(got.size(), 1u);
    EXPECT_EQ(std::get<cigi::SensorExtendedResponse>(got[0]).status, cigi::SensorStatus::Breaklock);

    // Sensor Control for another view is not this image generator's.
    s2.viewId = 1;
    const std::uint64_t ignored = session.stats().ignoredPackets;
    host.send({s2});
    session.poll(13 * kPeriod);
    EXPECT_EQ(session.stats().ignoredPackets, ignored + 1);
}

TEST(CigiSensors, SightOfPointsBehindAndOutsideTheWindow) {
    const ig::TerrainMap map = flatMap();
    ig::Pose eye;
    eye.position = {320.0, 320.0, 200.0};
    const double hfov = 60.0 * kDeg;
    // Behind the eye (looking north): not in front.
    sim::SensorSight s = sim::sightOf(map, eye, {320.0, 200.0, 150.0}, 720, 486, hfov);
    EXPECT_FALSE(s.inFront);
    EXPECT_FALSE(s.seen());
    // 40 degrees right of the axis with a 60-degree field: outside the window.
    s = sim::sightOf(map, eye, {320.0 + 100.0 * std::tan(40.0 * kDeg), 420.0, 200.0}, 720, 486,
                     hfov);
    EXPECT_TRUE(s.inFront);
    EXPECT_FALSE(s.inWindow);
    EXPECT_NEAR(s.gateXDeg, 40.0, 1e-9);
    EXPECT_NEAR(s.gateYDeg, 0.0, 1e-9);
    // 29 degrees right: inside; straight down the axis: the origin.
    s = sim::sightOf(map, eye, {320.0 + 100.0 * std::tan(29.0 * kDeg), 420.0, 200.0}, 720, 486,
                     hfov);
    EXPECT_TRUE(s.seen());
    s = sim::sightOf(map, eye, {320.0, 520.0, 200.0}, 720, 486, hfov);
    EXPECT_NEAR(s.gateXDeg, 0.0, 1e-12);
    EXPECT_NEAR(s.rangeM, 200.0, 1e-9);
}

}  // namespace
