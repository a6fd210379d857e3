#include "sim/cigi_session.hpp"

#include "base/error.hpp"
#include "ig/camera.hpp"
#include "ig/caster.hpp"
#include "ig/synthetic.hpp"
#include "io/cigi.hpp"
#include "io/field_clock.hpp"
#include "io/udp_socket.hpp"
#include "sim/pipeline.hpp"
#include "sim/trajectory.hpp"
#include "sim/trajectory_poses.hpp"

#include "common/cigi_host.hpp"

#include <gtest/gtest.h>
#include <glm/geometric.hpp>
#include <glm/gtc/matrix_transform.hpp>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <functional>
#include <limits>
#include <numbers>
#include <string>
#include <variant>
#include <vector>

namespace {

namespace cigi = io::cigi;

using vig_test::kLoopback;
constexpr double kDeg = std::numbers::pi / 180.0;
constexpr double kPeriod = 1001.0 / 60000.0;

using Host = vig_test::CigiHost;

// A 3.8 km square of synthetic terrain placed at 47 N, 122 W.
struct World {
    ig::TerrainMap map = ig::makeSyntheticTerrain(128, 11, 30.0);
    Host host;

    sim::CigiOptions options() {
        sim::CigiOptions o;
        o.bind = {kLoopback, 0};
        o.host = host.socket.localEndpoint();
        o.origin = {47.0, -122.0, 10.0};
        o.startPose.position = {500.0, 500.0, map.maxHeight() + 200.0};
        return o;
    }
};

// A measured figure as a test property ("2.3e-10").
std::string figure(double v) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "%.3g", v);
    return buf;
}

template <class T>
std::vector<T> packetsOf(const std::vector<cigi::Message>& messages) {
    std::vector<T> out;
    for (const cigi::Message& m : messages) {
        for (const cigi::Packet& p : m.packets) {
            if (const T* x = std::get_if<T>(&p)) out.push_back(*x);
        }
    }
    return out;
}

TEST(GeoFrame, LocalTangentPlaneAboutTheOrigin) {
    const sim::GeoFrame geo({47.0, -122.0, 10.0});
    // WGS 84 at 47 degrees: 111,170.8 m per degree of latitude, 76,055.3 per degree of longitude
    // (the series 111132.92 - 559.82 cos 2φ + 1.175 cos 4φ and 111412.84 cos φ - 93.5 cos 3φ).
    EXPECT_NEAR(geo.metresPerDegreeLat(), 111170.8, 1.0);
    EXPECT_NEAR(geo.metresPerDegreeLon(), 76055.3, 1.0);
    const glm::dvec3 o = geo.worldFromGeodetic(47.0, -122.0, 10.0);
    EXPECT_EQ(o, glm::dvec3(0.0));
    // North is +y, east is +x, up is +z.
    const glm::dvec3 ne = geo.worldFromGeodetic(47.01, -121.99, 110.0);
    EXPECT_NEAR(ne.x, 0.01 * geo.metresPerDegreeLon(), 1e-6);
    EXPECT_NEAR(ne.y, 0.01 * geo.metresPerDegreeLat(), 1e-6);
    EXPECT_DOUBLE_EQ(ne.z, 100.0);
    // Round trips within a nanometre over 100 km.
    for (double x = -1e5; x <= 1e5; x += 12345.6) {
        const glm::dvec3 w{x, -0.7 * x + 3.0, 1234.5};
        const glm::dvec3 g = geo.geodeticFromWorld(w);
        const glm::dvec3 back = geo.worldFromGeodetic(g.x, g.y, g.z);
        EXPECT_NEAR(back.x, w.x, 1e-6);
        EXPECT_NEAR(back.y, w.y, 1e-6);
        EXPECT_NEAR(back.z, w.z, 1e-9);
    }
    // Across the antimeridian longitudes wrap.
    const sim::GeoFrame pacific({0.0, 179.99, 0.0});
    EXPECT_NEAR(pacific.worldFromGeodetic(0.0, -179.99, 0.0).x, 0.02 * pacific.metresPerDegreeLon(),
                1e-6);
}

TEST(GeoFrame, OriginFlagIsParsedOrRefusedByName) {
    const sim::GeoOrigin o = sim::parseGeoOrigin("47.5,-122.25,100", "--cigi-origin");
    EXPECT_EQ(o.latDeg, 47.5);
    EXPECT_EQ(o.lonDeg, -122.25);
    EXPECT_EQ(o.altM, 100.0);
    EXPECT_EQ(sim::parseGeoOrigin("1,2", "--cigi-origin").altM, 0.0);
    for (const char* bad : {"", "47", "47,", "a,b", "47,-122,0,1", "91,0", "86,0", "0,181", "nan,0",
                            "0,inf", "0,0,1e9"}) {
        try {
            sim::parseGeoOrigin(bad, "--cigi-origin");
            ADD_FAILURE() << "accepted '" << bad << "'";
        } catch (const base::InputError& e) {
            EXPECT_NE(std::string(e.what()).find("--cigi-origin"), std::string::npos) << e.what();
        }
    }
}

// Records what the field loop got; before each field the host sends what `script` says.
class ScriptedHost final : public sim::PoseSource {
  public:
    ScriptedHost(sim::CigiPoseSource& inner, std::function<void(std::uint64_t, double)> script)
        : inner_(inner), script_(std::move(script)) {}
    ig::Pose advanceTo(double t) override {
        script_(fields_++, t);
        poses.push_back(inner_.advanceTo(t));
        times.push_back(t);
        return poses.back();
    }
    ig::Pose predict(double t) override { return inner_.predict(t); }
    double startTime() const override { return inner_.startTime(); }
    sim::RenderView view() const override { return inner_.view(); }
    std::vector<ig::Pose> poses;
    std::vector<double> times;

  private:
    sim::CigiPoseSource& inner_;
    std::function<void(std::uint64_t, double)> script_;
    std::uint64_t fields_ = 0;
};

class NullSink final : public io::FrameSink {
  public:
    int open(const io::VideoFormat& format, std::string*) override {
        format_ = format;
        return 0;
    }
    int writeField(const io::FieldBuffer&) override {
        ++fields;
        return 0;
    }
    int close(std::string*) override { return 0; }
    const io::VideoFormat& format() const override { return format_; }
    int fields = 0;

  private:
    io::VideoFormat format_;
};

// A simulated-clock run of `seconds` into `sink` (opened here at 128 x 96 UYVY), renders
// modelled at `renderHz`.
sim::PipelineResult runSimulated(World& world, sim::PoseSource& poses, io::FrameSink& sink,
                                 double seconds, double renderHz) {
    std::string error;
    sink.open({128, 96, io::PixelFormat::Uyvy}, &error);
    sim::RenderGeometry geometry;
    geometry.windowWidth = 128;
    geometry.windowHeight = 96;
    geometry.margin = 8;
    sim::PipelineOptions options;
    options.clock = sim::ClockMode::Simulated;
    options.duration = seconds;
    options.simulatedRenderHz = renderHz;
    auto clock = io::makeSimulatedClock();
    sim::Pipeline pipeline(poses, sim::makeCasterRenderer(world.map, geometry), sink, *clock,
                           options);
    return pipeline.run();
}

sim::PipelineResult runPipeline(World& world, sim::PoseSource& poses, double seconds) {
    NullSink sink;
    sim::PipelineResult result = runSimulated(world, poses, sink, seconds, 6.0);
    EXPECT_EQ(sink.fields, static_cast<int>(result.stats.fields));
    return result;
}

// A host at 20 Hz (every third field) flies a straight climbing line at constant rates: between
// its messages every field's pose is the line's, dead-reckoned to the field's own instant.
TEST(CigiSession, DeadReckonedPosesFollowTheHostsLineEveryField) {
    World world;
    sim::CigiPoseSource source(world.map, world.options());
    std::string error;
    ASSERT_EQ(source.open(&error), 0) << error;
    world.host.ig = source.session().localEndpoint();
    const sim::GeoFrame& geo = source.session().geo();

    const glm::dvec3 p0{1000.0, 1200.0, world.map.maxHeight() + 300.0};
    const glm::dvec3 v{30.0, 40.0, 0.5};                   // east, north, up (m/s)
    const double yaw0 = 36.0, yawRate = 2.0, pitch = 1.5;  // degrees, degrees per second
    auto truth = [&](double t) {
        ig::Pose p;
        p.position = p0 + v * t;
        p.yaw = (yaw0 + yawRate * t) * kDeg;
        p.pitch = pitch * kDeg;
        return p;
    };
    std::vector<std::uint32_t> hostFrameAtField;
    ScriptedHost host(source, [&](std::uint64_t n, double t) {
        if (n % 3 == 0) {
            const ig::Pose p = truth(t);
            const glm::dvec3 g = geo.geodeticFromWorld(p.position);
            cigi::EntityControl e;
            e.latOrX = g.x;
            e.lonOrY = g.y;
            e.altOrZ = g.z;
            e.yawDeg = static_cast<float>(yaw0 + yawRate * t);
            e.pitchDeg = static_cast<float>(pitch);
            std::vector<cigi::Packet> packets{e};
            if (n == 0) {
                cigi::RateControl r;
                r.xRate = static_cast<float>(v.y);   // north
                r.yRate = static_cast<float>(v.x);   // east
                r.zRate = static_cast<float>(-v.z);  // down
                r.yawRateDeg = static_cast<float>(yawRate);
                packets.push_back(r);
            }
            world.host.send(packets);
        }
        hostFrameAtField.push_back(world.host.frame);
    });
    const sim::PipelineResult result = runPipeline(world, host, 2.0);
    ASSERT_TRUE(result.ok()) << result.error;
    ASSERT_EQ(host.poses.size(), 120u);

    double worstPosition = 0.0, worstYaw = 0.0, worstPitch = 0.0;
    for (std::size_t n = 0; n < host.poses.size(); ++n) {
        const ig::Pose want = truth(host.times[n]);
        const ig::Pose& got = host.poses[n];
        worstPosition = std::max(worstPosition, glm::length(got.position - want.position));
        worstYaw = std::max(worstYaw, std::abs(got.yaw - want.yaw));
        worstPitch = std::max(worstPitch, std::abs(got.pitch - want.pitch));
        EXPECT_EQ(got.roll, 0.0);
    }
    // Positions travel as doubles; angles as floats of degrees (1e-6 rad is 6e-5 degrees).
    EXPECT_LT(worstPosition, 1e-6);
    EXPECT_LT(worstYaw, 1e-6);
    EXPECT_LT(worstPitch, 1e-6);
    RecordProperty("worst_position_m", figure(worstPosition));

    const sim::CigiStats& stats = source.session().stats();
    EXPECT_EQ(stats.entityUpdates, 40u);
    EXPECT_EQ(stats.rateUpdates, 1u);
    EXPECT_EQ(stats.badDatagrams, 0u);
    EXPECT_EQ(stats.clampedPoses, 0u);

    // A Start of Frame every field, counters and timestamps going up with it.
    const std::vector<cigi::StartOfFrame> sofs =
        packetsOf<cigi::StartOfFrame>(world.host.receiveAll());
    ASSERT_EQ(sofs.size(), 120u);
    EXPECT_EQ(stats.framesSent, 120u);
    for (std::size_t n = 0; n < sofs.size(); ++n) {
        EXPECT_EQ(sofs[n].igFrameNumber, n);
        EXPECT_EQ(sofs[n].igMode, cigi::IgMode::Operate);
        EXPECT_EQ(sofs[n].lastHostFrameNumber, hostFrameAtField[n]);
        EXPECT_TRUE(sofs[n].timestampValid);
        EXPECT_EQ(sofs[n].timestamp, static_cast<std::uint32_t>(std::llround(n * kPeriod * 1e5)));
    }
}

TEST(CigiSession, HoldsTheStartPoseUntilTheFirstEntityControlAndAfterAReset) {
    World world;
    sim::CigiOptions options = world.options();
    sim::CigiPoseSource source(world.map, options);
    std::string error;
    ASSERT_EQ(source.open(&error), 0) << error;
    world.host.ig = source.session().localEndpoint();
    EXPECT_EQ(source.advanceTo(0.0).position, options.startPose.position);
    EXPECT_EQ(source.predict(1.0).position, options.startPose.position);
    EXPECT_EQ(source.session().igMode(), cigi::IgMode::Reset);
    // No host: the wait ends at its limit, a Start of Frame sent every field period meanwhile.
    const auto before = std::chrono::steady_clock::now();
    EXPECT_FALSE(source.waitForHost(0.05));
    EXPECT_LT(std::chrono::steady_clock::now() - before, std::chrono::seconds(1));
    EXPECT_GE(packetsOf<cigi::StartOfFrame>(world.host.receiveAll()).size(), 2u);
    source.advanceTo(0.0);

    cigi::EntityControl e;
    const glm::dvec3 g =
        source.session().geo().geodeticFromWorld({2000.0, 2100.0, world.map.maxHeight() + 50});
    e.latOrX = g.x;
    e.lonOrY = g.y;
    e.altOrZ = g.z;
    cigi::RateControl r;
    r.xRate = 10.0f;
    world.host.send({e, r});
    ig::Pose p = source.advanceTo(0.1);
    EXPECT_NEAR(p.position.x, 2000.0, 1e-6);
    EXPECT_NEAR(source.predict(0.6).position.y, 2105.0, 1e-6);  // 10 m/s north for 0.5 s

    // A host writing little-endian is understood as well.
    cigi::IgControl control;
    control.hostFrameNumber = ++world.host.frame;
    cigi::EntityControl moved = e;
    const glm::dvec3 g2 =
        source.session().geo().geodeticFromWorld({2500.0, 2100.0, world.map.maxHeight() + 50});
    moved.latOrX = g2.x;
    moved.lonOrY = g2.y;
    const std::vector<cigi::Packet> little{control, moved};
    world.host.sendRaw(cigi::encodeMessage(little, cigi::ByteOrder::Little));
    EXPECT_NEAR(source.advanceTo(0.15).position.x, 2500.0, 1e-6);
    world.host.send({e, r});
    source.advanceTo(0.15);

    // Another entity of a type mapped to no model: refused and counted, the ownship untouched.
    cigi::EntityControl other = e;
    other.entityId = 3;
    other.latOrX += 0.01;
    world.host.send({other});
    const double xBefore = source.advanceTo(0.2).position.x;
    EXPECT_EQ(source.session().stats().entitiesRefused, 1u);
    EXPECT_EQ(source.session().stats().ignoredPackets, 0u);
    EXPECT_TRUE(source.session().entities().empty());
    EXPECT_EQ(source.predict(0.2).position.x, xBefore);

    // Reset: back to the start pose, still; Entity Control is ignored until Operate.
    world.host.send({e}, cigi::IgMode::Reset);
    p = source.advanceTo(0.3);
    EXPECT_EQ(p.position, options.startPose.position);
    EXPECT_EQ(source.predict(5.0).position, options.startPose.position);
    EXPECT_EQ(source.session().stats().resets, 1u);
    EXPECT_EQ(source.session().igMode(), cigi::IgMode::Reset);
    const auto sofs = packetsOf<cigi::StartOfFrame>(world.host.receiveAll());
    ASSERT_EQ(sofs.size(), 6u);
    EXPECT_EQ(sofs[0].igMode, cigi::IgMode::Reset);
    EXPECT_EQ(sofs[1].igMode, cigi::IgMode::Operate);
    EXPECT_EQ(sofs[5].igMode, cigi::IgMode::Reset);
}

// Rates in the entity's own axes (x forward, y right, z down) turn with its attitude.
TEST(CigiSession, LocalRatesFollowTheEntitysAxes) {
    World world;
    sim::CigiPoseSource source(world.map, world.options());
    std::string error;
    ASSERT_EQ(source.open(&error), 0) << error;
    world.host.ig = source.session().localEndpoint();
    const glm::dvec3 p0{1000.0, 1000.0, world.map.maxHeight() + 500.0};
    const glm::dvec3 g = source.session().geo().geodeticFromWorld(p0);
    cigi::EntityControl e;
    e.latOrX = g.x;
    e.lonOrY = g.y;
    e.altOrZ = g.z;
    e.yawDeg = 90.0f;  // heading east
    cigi::RateControl r;
    r.localCoordinates = true;
    r.xRate = 10.0f;  // forward: east
    r.yRate = 3.0f;   // right: south
    r.zRate = 2.0f;   // down
    r.yawRateDeg = 5.0f;
    world.host.send({e, r});
    source.advanceTo(0.0);
    const ig::Pose p = source.advanceTo(1.0);
    EXPECT_NEAR(p.position.x - p0.x, 10.0, 1e-6);
    EXPECT_NEAR(p.position.y - p0.y, -3.0, 1e-6);
    EXPECT_NEAR(p.position.z - p0.z, -2.0, 1e-6);
    EXPECT_NEAR(p.yaw, 95.0 * kDeg, 1e-9);

    // Pitched up 30 degrees, forward climbs; a new Entity Control turns the same rates with it.
    e.pitchDeg = 30.0f;
    world.host.send({e});
    source.advanceTo(1.0);
    const ig::Pose q = source.advanceTo(2.0);
    const double c = std::cos(30.0 * kDeg), s = std::sin(30.0 * kDeg);
    EXPECT_NEAR(q.position.x - p0.x, 10.0 * c + 2.0 * s, 1e-5);
    EXPECT_NEAR(q.position.y - p0.y, -3.0, 1e-5);
    EXPECT_NEAR(q.position.z - p0.z, 10.0 * s - 2.0 * c, 1e-5);
}

TEST(CigiSession, OwnshipUnderTheTerrainIsLiftedAboveIt) {
    World world;
    sim::CigiPoseSource source(world.map, world.options(), 2.0);
    std::string error;
    ASSERT_EQ(source.open(&error), 0) << error;
    world.host.ig = source.session().localEndpoint();
    cigi::EntityControl e;
    const glm::dvec3 g = source.session().geo().geodeticFromWorld({1500.0, 1700.0, -500.0});
    e.latOrX = g.x;
    e.lonOrY = g.y;
    e.altOrZ = g.z;
    world.host.send({e});
    const ig::Pose p = source.advanceTo(0.0);
    EXPECT_NEAR(p.position.x, 1500.0, 1e-6);
    EXPECT_EQ(p.position.z, world.map.surfaceHeight(p.position.x, p.position.y) + 2.0);
    EXPECT_EQ(source.session().stats().clampedPoses, 1u);
}

// HAT/HOT and line-of-sight answers against the terrain's exact surface.
TEST(CigiSession, AnswersHeightAndLineOfSightFromTheTerrainExactly) {
    World world;
    sim::CigiSession session(world.map, world.options());
    std::string error;
    ASSERT_EQ(session.open(&error), 0) << error;
    world.host.ig = session.localEndpoint();
    const sim::GeoFrame& geo = session.geo();
    const double alt0 = world.options().origin.altM;
    session.poll(0.0);
    world.host.receiveAll();

    // HAT, HOT and extended at a grid of points between samples, and two off the map.
    std::vector<cigi::Packet> requests;
    std::vector<glm::dvec3> points;
    std::uint16_t id = 0;
    for (double x = 17.3; x < world.map.extentX(); x += 431.7) {
        for (double y = 11.9; y < world.map.extentY(); y += 517.3) {
            const glm::dvec3 g = geo.geodeticFromWorld({x, y, 2500.0});
            for (cigi::HatHotType type :
                 {cigi::HatHotType::Hat, cigi::HatHotType::Hot, cigi::HatHotType::Extended}) {
                cigi::HatHotRequest q;
                q.requestId = id++;
                q.type = type;
                q.latOrX = g.x;
                q.lonOrY = g.y;
                q.altOrZ = g.z;
                requests.push_back(q);
                points.push_back(geo.worldFromGeodetic(g.x, g.y, g.z));
            }
        }
    }
    const std::uint16_t firstOff = id;
    for (const glm::dvec3 w :
         {glm::dvec3{-50.0, 100.0, 0.0}, glm::dvec3{100.0, world.map.extentY() + 1.0, 0.0}}) {
        const glm::dvec3 g = geo.geodeticFromWorld(w);
        cigi::HatHotRequest q;
        q.requestId = id++;
        q.type = cigi::HatHotType::Extended;
        q.latOrX = g.x;
        q.lonOrY = g.y;
        requests.push_back(q);
    }
    world.host.send(requests);
    // Answers go out with the next field's Start of Frame, at most 64 a field.
    std::vector<cigi::Message> messages;
    for (int field = 1; field <= 4; ++field) {
        session.poll(field * kPeriod);
        auto some = world.host.receiveAll();
        ASSERT_EQ(some.size(), 1u);
        EXPECT_EQ(some[0].packets.size(), field < 4 ? 65u : requests.size() - 3 * 64 + 1);
        messages.insert(messages.end(), some.begin(), some.end());
    }
    const auto basic = packetsOf<cigi::HatHotResponse>(messages);
    const auto extended = packetsOf<cigi::HatHotExtendedResponse>(messages);
    ASSERT_EQ(basic.size() + extended.size(), requests.size());
    double worstHeight = 0.0, worstNormal = 0.0;
    for (const cigi::HatHotResponse& a : basic) {
        ASSERT_LT(a.requestId, firstOff);
        EXPECT_TRUE(a.valid);
        EXPECT_EQ(a.hostFrameLsn, world.host.frame & 15u);
        const glm::dvec3& w = points[a.requestId];
        const double hot = world.map.surfaceHeight(w.x, w.y) + alt0;
        const double want = a.isHot ? hot : (w.z + alt0) - hot;
        worstHeight = std::max(worstHeight, std::abs(a.heightM - want));
    }
    for (const cigi::HatHotExtendedResponse& a : extended) {
        if (a.requestId >= firstOff) {
            EXPECT_FALSE(a.valid) << "off the map";
            continue;
        }
        EXPECT_TRUE(a.valid);
        const glm::dvec3& w = points[a.requestId];
        const double hot = world.map.surfaceHeight(w.x, w.y) + alt0;
        worstHeight = std::max(worstHeight, std::abs(a.hotM - hot));
        worstHeight = std::max(worstHeight, std::abs(a.hatM - ((w.z + alt0) - hot)));
        // The normal against central differences of the surface (inside one cell).
        const double h = 1e-4;
        const double gx =
            (world.map.surfaceHeight(w.x + h, w.y) - world.map.surfaceHeight(w.x - h, w.y)) /
            (2 * h);
        const double gy =
            (world.map.surfaceHeight(w.x, w.y + h) - world.map.surfaceHeight(w.x, w.y - h)) /
            (2 * h);
        const glm::dvec3 want = glm::normalize(glm::dvec3(-gx, -gy, 1.0));
        const double az = a.normalAzimuthDeg * kDeg, el = a.normalElevationDeg * kDeg;
        const glm::dvec3 got{std::sin(az) * std::cos(el), std::cos(az) * std::cos(el),
                             std::sin(el)};
        worstNormal = std::max(worstNormal, std::acos(std::min(1.0, glm::dot(got, want))));
    }
    EXPECT_LT(worstHeight, 1e-9);
    EXPECT_LT(worstNormal, 1e-5);  // radians: the normal travels as float degrees
    RecordProperty("worst_height_m", figure(worstHeight));

    // Line of sight: segments and vectors against ig::intersectTerrain.
    requests.clear();
    struct Expect {
        bool valid;
        double range;
        glm::dvec3 point;
    };
    std::vector<Expect> expects;
    id = 0;
    for (double x = 200.0; x < world.map.extentX() - 200.0; x += 611.0) {
        const glm::dvec3 src{x, 300.0, world.map.maxHeight() + 100.0};
        const glm::dvec3 gs = geo.geodeticFromWorld(src);
        const glm::dvec3 s = geo.worldFromGeodetic(gs.x, gs.y, gs.z);
        // A segment down through the terrain, and one that stays above it.
        for (const double dz : {-3000.0, 50.0}) {
            const glm::dvec3 gd = geo.geodeticFromWorld(src + glm::dvec3{150.0, 2500.0, dz});
            const glm::dvec3 d = geo.worldFromGeodetic(gd.x, gd.y, gd.z);
            cigi::LosSegmentRequest q;
            q.requestId = id++;
            q.extended = dz < 0.0;
            q.sourceLatOrX = gs.x;
            q.sourceLonOrY = gs.y;
            q.sourceAltOrZ = gs.z;
            q.destinationLatOrX = gd.x;
            q.destinationLonOrY = gd.y;
            q.destinationAltOrZ = gd.z;
            requests.push_back(q);
            const ig::RayHit hit = ig::intersectTerrain(world.map, s, d - s);
            const bool within = hit.hit && hit.distance <= glm::length(d - s);
            expects.push_back({within, hit.distance, hit.point});
        }
        // A vector 30 degrees down toward the north-east, then the same with too short a range.
        for (const float maxRange : {20000.0f, 10.0f}) {
            cigi::LosVectorRequest q;
            q.requestId = id++;
            q.extended = maxRange > 100.0f;
            q.azimuthDeg = 45.0f;
            q.elevationDeg = -30.0f;
            q.maxRangeM = maxRange;
            q.sourceLatOrX = gs.x;
            q.sourceLonOrY = gs.y;
            q.sourceAltOrZ = gs.z;
            requests.push_back(q);
            const double az = 45.0 * kDeg, el = -30.0 * kDeg;
            const ig::RayHit hit = ig::intersectTerrain(
                world.map, s,
                {std::sin(az) * std::cos(el), std::cos(az) * std::cos(el), std::sin(el)});
            expects.push_back({hit.hit && hit.distance <= maxRange, hit.distance, hit.point});
        }
    }
    world.host.send(requests);
    session.poll(5 * kPeriod);
    const auto losMessages = world.host.receiveAll();
    std::vector<std::pair<std::uint16_t, double>> ranges;
    double worstRange = 0.0, worstPoint = 0.0;
    int valid = 0, invalid = 0;
    for (const cigi::LosResponse& a : packetsOf<cigi::LosResponse>(losMessages)) {
        const Expect& e = expects.at(a.requestId);
        EXPECT_EQ(a.valid, e.valid) << a.requestId;
        (a.valid ? valid : invalid)++;
        if (a.valid) worstRange = std::max(worstRange, std::abs(a.rangeM - e.range));
    }
    for (const cigi::LosExtendedResponse& a : packetsOf<cigi::LosExtendedResponse>(losMessages)) {
        const Expect& e = expects.at(a.requestId);
        EXPECT_EQ(a.valid, e.valid) << a.requestId;
        (a.valid ? valid : invalid)++;
        if (!a.valid) continue;
        worstRange = std::max(worstRange, std::abs(a.rangeM - e.range));
        const glm::dvec3 w = geo.worldFromGeodetic(a.latOrX, a.lonOrY, a.altOrZ);
        worstPoint = std::max(worstPoint, glm::length(w - e.point));
    }
    EXPECT_EQ(static_cast<std::size_t>(valid + invalid), requests.size());
    EXPECT_GE(valid, 3);
    EXPECT_GE(invalid, 12);
    EXPECT_LT(worstRange, 1e-6);
    EXPECT_LT(worstPoint, 1e-6);
    RecordProperty("worst_los_range_m", figure(worstRange));
}

// Entity coordinates: offsets from the ownship in its axes (x forward, y right, z down).
TEST(CigiSession, AnswersInTheOwnshipsCoordinates) {
    World world;
    sim::CigiPoseSource source(world.map, world.options());
    std::string error;
    ASSERT_EQ(source.open(&error), 0) << error;
    world.host.ig = source.session().localEndpoint();
    const glm::dvec3 p0{1000.0, 1500.0, world.map.maxHeight() + 400.0};
    const glm::dvec3 g = source.session().geo().geodeticFromWorld(p0);
    cigi::EntityControl e;
    e.latOrX = g.x;
    e.lonOrY = g.y;
    e.altOrZ = g.z;
    e.yawDeg = 90.0f;  // east
    cigi::RateControl r;
    r.yRate = 60.0f;  // east, 60 m/s: answers are for the field's dead-reckoned ownship
    world.host.send({e, r});
    source.advanceTo(0.0);

    std::vector<cigi::Packet> requests;
    for (std::uint16_t id = 0; id < 3; ++id) {
        cigi::HatHotRequest q;
        q.requestId = id;
        q.type = cigi::HatHotType::Hat;
        q.entityCoordinates = true;
        q.latOrX = id == 1 ? 200.0 : 0.0;  // 200 m ahead
        q.entityId = id == 2 ? 7 : 0;      // an entity this image generator does not know
        requests.push_back(q);
    }
    cigi::LosVectorRequest down;  // straight down from the ownship
    down.requestId = 3;
    down.sourceEntityCoordinates = true;
    down.elevationDeg = -90.0f;
    down.maxRangeM = 10000.0f;
    requests.push_back(down);
    world.host.send(requests);
    const double t = 0.5;
    source.advanceTo(t);
    const auto messages = world.host.receiveAll();
    const auto hats = packetsOf<cigi::HatHotResponse>(messages);
    ASSERT_EQ(hats.size(), 3u);
    const glm::dvec3 at{p0.x + 60.0 * t, p0.y, p0.z};
    EXPECT_TRUE(hats[0].valid);
    EXPECT_NEAR(hats[0].heightM, at.z - world.map.surfaceHeight(at.x, at.y), 1e-6);
    EXPECT_TRUE(hats[1].valid);
    EXPECT_NEAR(hats[1].heightM, at.z - world.map.surfaceHeight(at.x + 200.0, at.y), 1e-6);
    EXPECT_FALSE(hats[2].valid);
    const auto los = packetsOf<cigi::LosResponse>(messages);
    ASSERT_EQ(los.size(), 1u);
    EXPECT_TRUE(los[0].valid);
    EXPECT_NEAR(los[0].rangeM, at.z - world.map.surfaceHeight(at.x, at.y), 1e-6);
}

// A request with an update period is answered every that many fields, at each field's pose,
// until a request with the same id and period 0 (answered once) ends it.
TEST(CigiSession, RepeatingRequestsFollowTheOwnshipUntilCancelled) {
    World world;
    sim::CigiPoseSource source(world.map, world.options());
    std::string error;
    ASSERT_EQ(source.open(&error), 0) << error;
    world.host.ig = source.session().localEndpoint();
    const glm::dvec3 p0{800.0, 900.0, world.map.maxHeight() + 300.0};
    const glm::dvec3 g = source.session().geo().geodeticFromWorld(p0);
    cigi::EntityControl e;
    e.latOrX = g.x;
    e.lonOrY = g.y;
    e.altOrZ = g.z;
    cigi::RateControl r;
    r.xRate = 90.0f;  // north
    cigi::HatHotRequest q;
    q.requestId = 42;
    q.type = cigi::HatHotType::Hot;
    q.entityCoordinates = true;
    q.updatePeriod = 2;
    world.host.send({e, r, q});
    std::vector<int> answeredAt;
    for (int n = 0; n < 10; ++n) {
        if (n == 7) {
            q.updatePeriod = 0;
            world.host.send({q});
        }
        const double t = n * kPeriod;
        source.advanceTo(t);
        for (const cigi::HatHotResponse& a :
             packetsOf<cigi::HatHotResponse>(world.host.receiveAll())) {
            EXPECT_EQ(a.requestId, 42);
            EXPECT_TRUE(a.valid);
            EXPECT_NEAR(
                a.heightM,
                world.map.surfaceHeight(p0.x, p0.y + 90.0 * t) + world.options().origin.altM, 1e-6);
            answeredAt.push_back(n);
        }
    }
    EXPECT_EQ(answeredAt, (std::vector<int>{0, 2, 4, 6, 7}));
}

// Bad traffic: refused datagrams are counted and the first few reported; fields go on.
TEST(CigiSession, BadTrafficNeverStopsTheFields) {
    World world;
    sim::CigiPoseSource source(world.map, world.options());
    std::string error;
    ASSERT_EQ(source.open(&error), 0) << error;
    world.host.ig = source.session().localEndpoint();
    const glm::dvec3 g =
        source.session().geo().geodeticFromWorld({1000.0, 1000.0, world.map.maxHeight() + 10});
    cigi::EntityControl e;
    e.latOrX = g.x;
    e.lonOrY = g.y;
    e.altOrZ = g.z;
    const std::vector<std::uint8_t> good = world.host.encode({e});
    ASSERT_EQ(good.size(), 72u);

    std::uint64_t bad = 0;
    // Every truncation (but the one that leaves IG Control alone, a good message).
    for (std::size_t n = 1; n < good.size(); ++n) {
        world.host.sendRaw({good.begin(), good.begin() + static_cast<std::ptrdiff_t>(n)});
        if (n != cigi::IgControl::kSize) ++bad;
    }
    // A wrong size, a NaN latitude (big-endian double at offset 24 of the Entity Control).
    std::vector<std::uint8_t> b = good;
    b[25] = 40;
    world.host.sendRaw(b);
    b = good;
    std::fill(b.begin() + 48, b.begin() + 56, 0);
    b[48] = 0x7f;
    b[49] = 0xf8;
    world.host.sendRaw(b);
    bad += 2;
    // An unknown (user-defined) packet is skipped, the rest applied.
    b = good;
    b.insert(b.end(), {201, 8, 1, 2, 3, 4, 5, 6});
    world.host.sendRaw(b);
    source.advanceTo(0.0);
    const sim::CigiStats& stats = source.session().stats();
    EXPECT_EQ(stats.badDatagrams, bad);
    EXPECT_EQ(stats.skippedPackets, 1u);
    EXPECT_EQ(stats.entityUpdates, 1u);
    ASSERT_EQ(stats.firstErrors.size(), sim::CigiStats::kReportedErrors);
    EXPECT_NE(stats.firstErrors[0].find("CIGI message from the host"), std::string::npos)
        << stats.firstErrors[0];

    // A flood of 10,000 datagrams: first as one burst (the kernel keeps what fits its buffer),
    // then 200 before each of 50 fields (every one delivered). Each field drains the socket:
    // the first field after the burst takes all the kernel kept, and every field is answered at
    // once with its Start of Frame.
    std::vector<std::uint8_t> junk(good.begin(), good.begin() + 30);
    for (int i = 0; i < 10000; ++i) {
        junk[29] = static_cast<std::uint8_t>(i);
        (void)world.host.socket.sendTo(junk, world.host.ig);
    }
    const auto start = std::chrono::steady_clock::now();
    double worstField = 0.0;
    int fields = 0;
    auto field = [&] {
        const auto before = std::chrono::steady_clock::now();
        source.advanceTo(kPeriod * (++fields));
        worstField = std::max(
            worstField,
            std::chrono::duration<double>(std::chrono::steady_clock::now() - before).count());
        world.host.receiveAll();
    };
    field();
    const std::uint64_t burst = stats.badDatagrams - bad;
    EXPECT_GT(burst, 100u);
    while (fields < 100)
        field();
    EXPECT_EQ(stats.badDatagrams - bad, burst) << "the first field drained the socket";
    for (int k = 0; k < 50; ++k) {
        for (int i = 0; i < 200; ++i)
            ASSERT_EQ(world.host.socket.sendTo(junk, world.host.ig), 0);
        field();
    }
    EXPECT_EQ(stats.badDatagrams, bad + burst + 10000);
    // What the kernel could not keep of the burst is counted, not lost without trace.
    EXPECT_EQ(stats.droppedByKernel + burst, 10000u);
    EXPECT_EQ(stats.cappedPolls, 0u);
    world.host.sendRaw(world.host.encode({e}));
    source.advanceTo(kPeriod * (fields + 1));
    EXPECT_EQ(stats.entityUpdates, 2u) << "a good message after the flood is applied";
    EXPECT_EQ(stats.framesSent, static_cast<std::uint64_t>(fields) + 2);
    EXPECT_LT(worstField, 0.1) << "one field's poll took " << worstField << " s";
    EXPECT_LT(std::chrono::steady_clock::now() - start, std::chrono::seconds(10));
    RecordProperty("flood_burst_kept", std::to_string(burst));
    RecordProperty("flood_worst_field_ms", figure(worstField * 1e3));
}

}  // namespace

namespace {

// Keeps every field's bytes.
class CapturingSink final : public io::FrameSink {
  public:
    int open(const io::VideoFormat& format, std::string*) override {
        format_ = format;
        return 0;
    }
    int writeField(const io::FieldBuffer& field) override {
        const std::uint8_t* begin = field.data;
        fields.emplace_back(begin, begin + static_cast<std::size_t>(field.lines) * field.stride);
        return 0;
    }
    int close(std::string*) override { return 0; }
    const io::VideoFormat& format() const override { return format_; }
    std::vector<std::vector<std::uint8_t>> fields;

  private:
    io::VideoFormat format_;
};

std::vector<std::vector<std::uint8_t>> captureFields(World& world, sim::PoseSource& poses,
                                                     double seconds) {
    CapturingSink sink;
    const sim::PipelineResult result = runSimulated(world, poses, sink, seconds, 12.0);
    EXPECT_TRUE(result.ok()) << result.error;
    return sink.fields;
}

}  // namespace

// The host path against the CSV path: a host flying a straight line (Entity Control at 20 Hz, one
// Rate Control) against the same line from a trajectory, under the simulated clock. Angles travel
// as float degrees and are chosen representable, so they arrive bit for bit; positions go through
// latitude and longitude and come back to within rounding (not bit for bit in general).
TEST(CigiSession, HostDrivenFieldsAgainstTheSameTrajectoryFromCsv) {
    World world;
    const glm::dvec3 p0{600.0, 700.0, world.map.maxHeight() + 150.0};
    const glm::dvec3 v{48.0, 64.0, -2.0};
    const double seconds = 1.0;
    ig::Pose a, b;
    a.position = p0;
    a.yaw = ig::degToRad(36.5);
    a.pitch = ig::degToRad(-8.0);
    b = a;
    b.position = p0 + v * seconds;
    sim::TrajectoryPoses csv(sim::Trajectory::fromSamples({{0.0, a}, {seconds, b}}, "line"));
    const auto fromCsv = captureFields(world, csv, seconds);

    sim::CigiPoseSource source(world.map, world.options());
    std::string error;
    ASSERT_EQ(source.open(&error), 0) << error;
    world.host.ig = source.session().localEndpoint();
    const sim::GeoFrame& geo = source.session().geo();
    ScriptedHost host(source, [&](std::uint64_t n, double t) {
        if (n % 3 != 0) return;
        const glm::dvec3 g = geo.geodeticFromWorld(p0 + v * t);
        cigi::EntityControl e;
        e.latOrX = g.x;
        e.lonOrY = g.y;
        e.altOrZ = g.z;
        e.yawDeg = 36.5f;
        e.pitchDeg = -8.0f;
        std::vector<cigi::Packet> packets{e};
        if (n == 0) {
            cigi::RateControl r;
            r.xRate = static_cast<float>(v.y);
            r.yRate = static_cast<float>(v.x);
            r.zRate = static_cast<float>(-v.z);
            packets.push_back(r);
        }
        world.host.send(packets);
    });
    // A host already sending when the run starts: its first message is taken before frame 0
    // is rendered (as the CSV path's frame 0 shows the line's start).
    host.advanceTo(0.0);
    EXPECT_TRUE(source.waitForHost(0.0));
    const auto fromHost = captureFields(world, host, seconds);
    ASSERT_EQ(fromHost.size(), fromCsv.size());

    double worstPosition = 0.0;
    double worstAngle = 0.0;
    for (std::size_t n = 0; n < host.poses.size(); ++n) {
        const ig::Pose want = csv.advanceTo(host.times[n]);
        worstPosition =
            std::max(worstPosition, glm::length(host.poses[n].position - want.position));
        worstAngle = std::max({worstAngle, std::abs(host.poses[n].yaw - want.yaw),
                               std::abs(host.poses[n].pitch - want.pitch),
                               std::abs(host.poses[n].roll - want.roll)});
    }
    std::size_t identical = 0, bytes = 0, differing = 0;
    int worstByte = 0;
    for (std::size_t n = 0; n < fromCsv.size(); ++n) {
        ASSERT_EQ(fromHost[n].size(), fromCsv[n].size());
        identical += fromHost[n] == fromCsv[n];
        for (std::size_t i = 0; i < fromCsv[n].size(); ++i) {
            const int d = std::abs(int(fromHost[n][i]) - int(fromCsv[n][i]));
            differing += d != 0;
            worstByte = std::max(worstByte, d);
        }
        bytes += fromCsv[n].size();
    }
    EXPECT_LT(worstAngle, 1e-12);
    // Measured: the poses differ by rounding only (under a nanometre), and no field differs by a
    // single bit (the casters' fixed-point stepping does not see such differences here).
    EXPECT_EQ(identical, fromCsv.size());
    EXPECT_EQ(worstByte, 0);
    EXPECT_LT(worstPosition, 1e-6);
    RecordProperty("fields", std::to_string(fromCsv.size()));
    RecordProperty("identical_fields", std::to_string(identical));
    RecordProperty("differing_bytes", std::to_string(differing) + " of " + std::to_string(bytes));
    RecordProperty("worst_byte_difference", std::to_string(worstByte));
    RecordProperty("worst_pose_position_m", figure(worstPosition));
    RecordProperty("worst_pose_angle_rad", figure(worstAngle));
    std::printf(
        "host vs csv: %zu of %zu fields identical, %zu of %zu bytes differ (worst %d), "
        "pose within %.3g m and %.3g rad\n",
        identical, fromCsv.size(), differing, bytes, worstByte, worstPosition, worstAngle);
}

namespace {

// A host at 60 Hz flying a straight, turning line falls silent at 1 s and comes back at 4 s:
// the ownship dead-reckons along the line until 1 s + the extrapolation limit, then holds; the
// watchdog reports one outage (when, how long, fields extrapolated and held), and the pose seen
// by predict() (the renderer's side) holds too.
TEST(CigiSession, SilentHostIsExtrapolatedThenHeldAndReported) {
    World world;
    sim::CigiOptions options = world.options();
    options.hostTimeout = 0.25;
    options.extrapolateLimit = 1.5;
    sim::CigiPoseSource source(world.map, options);
    std::string error;
    ASSERT_EQ(source.open(&error), 0) << error;
    world.host.ig = source.session().localEndpoint();
    const sim::GeoFrame& geo = source.session().geo();
    const glm::dvec3 p0{1000.0, 1200.0, world.map.maxHeight() + 300.0};
    const glm::dvec3 v{30.0, 40.0, 0.5};
    const auto truth = [&](double t) { return p0 + v * t; };
    const auto send = [&](double t) {
        const glm::dvec3 g = geo.geodeticFromWorld(truth(t));
        cigi::EntityControl e;
        e.latOrX = g.x;
        e.lonOrY = g.y;
        e.altOrZ = g.z;
        e.yawDeg = 36.0f;
        cigi::RateControl r;
        r.xRate = static_cast<float>(v.y);
        r.yRate = static_cast<float>(v.x);
        r.zRate = static_cast<float>(-v.z);
        world.host.send({e, r});
    };
    const int silentFrom = 60, backAt = 240, fields = 300;  // 1 s, 4 s, 5 s
    double lastMessage = 0.0;
    std::vector<glm::dvec3> got;
    for (int n = 0; n < fields; ++n) {
        const double t = n * kPeriod;
        if (n < silentFrom || n >= backAt) send(t);
        if (n < silentFrom) lastMessage = t;
        got.push_back(source.advanceTo(t).position);
        world.host.receiveAll();
    }
    const double holdFrom = lastMessage + options.extrapolateLimit;
    int extrapolated = 0, held = 0, noticedAt = -1;
    for (int n = silentFrom; n < backAt; ++n) {
        const double t = n * kPeriod;
        const glm::dvec3 want = truth(std::min(t, holdFrom));
        EXPECT_LT(glm::length(got[n] - want), 1e-6) << "field " << n;
        if (t - lastMessage > options.hostTimeout) {
            if (noticedAt < 0) noticedAt = n;
            (t > holdFrom ? held : extrapolated) += 1;
        }
    }
    EXPECT_GT(held, 60);
    // Back: the line again from the first message on.
    for (int n = backAt; n < fields; ++n)
        EXPECT_LT(glm::length(got[n] - truth(n * kPeriod)), 1e-6) << "field " << n;

    const sim::CigiStats& stats = source.session().stats();
    EXPECT_EQ(stats.hostLosses, 1u);
    ASSERT_EQ(stats.outages.size(), 1u);
    const sim::HostOutage& o = stats.outages[0];
    EXPECT_DOUBLE_EQ(o.lastMessage, lastMessage);
    EXPECT_DOUBLE_EQ(o.noticed, noticedAt * kPeriod);
    EXPECT_NEAR(o.length, backAt * kPeriod - lastMessage, 1e-12);
    EXPECT_FALSE(o.ongoing);
    EXPECT_EQ(o.fieldsExtrapolated, static_cast<std::uint64_t>(extrapolated));
    EXPECT_EQ(o.fieldsHeld, static_cast<std::uint64_t>(held));

    // Silent again to the end: an ongoing outage; predict() holds as advanceTo() does.
    for (int n = fields; n < fields + 200; ++n)
        source.advanceTo(n * kPeriod);
    EXPECT_EQ(stats.hostLosses, 2u);
    ASSERT_EQ(stats.outages.size(), 2u);
    EXPECT_TRUE(stats.outages[1].ongoing);
    const double last2 = (fields - 1) * kPeriod;
    EXPECT_LT(glm::length(source.predict(100.0).position - truth(last2 + options.extrapolateLimit)),
              1e-6);
}

// The eye of a view: the entity's rotation then the view's (yaw right about the entity's z down,
// pitch up, roll right), checked against rotation matrices built another way (glm::rotate).
TEST(CigiView, EyePoseComposesTheViewOnTheEntity) {
    const auto basis = [](const ig::Pose& p) {
        const ig::CameraBasis b = ig::CameraBasis::fromPose(p);
        return glm::dmat3(b.forward, b.right, -b.up);  // world from (x forward, y right, z down)
    };
    const auto rotation = [](double yaw, double pitch, double roll) {
        glm::dmat4 m(1.0);
        m = glm::rotate(m, yaw, glm::dvec3(0, 0, 1));
        m = glm::rotate(m, pitch, glm::dvec3(0, 1, 0));  // about y right: x turns to -z, up
        m = glm::rotate(m, roll, glm::dvec3(1, 0, 0));
        return glm::dmat3(m);
    };
    ig::Pose entity;
    entity.position = {100.0, 200.0, 300.0};
    EXPECT_EQ(sim::eyePose(entity, {}).position, entity.position);
    double worst = 0.0;
    int cases = 0;
    for (double ey : {0.0, 0.7, -2.5})
        for (double ep : {0.0, 0.3, -1.2})
            for (double er : {0.0, 0.4, -2.9})
                for (double vy : {-0.5236, 0.5236, 2.0})
                    for (double vp : {0.0, 0.25, -0.6})
                        for (double vr : {0.0, -0.3}) {
                            entity.yaw = ey;
                            entity.pitch = ep;
                            entity.roll = er;
                            sim::ViewOffset view{{2.0, -1.0, 0.5}, vy, vp, vr};
                            const ig::Pose eye = sim::eyePose(entity, view);
                            const glm::dmat3 want = basis(entity) * rotation(vy, vp, vr);
                            const glm::dmat3 got = basis(eye);
                            for (int c = 0; c < 3; ++c)
                                worst = std::max(worst, glm::length(got[c] - want[c]));
                            const glm::dvec3 offset = entity.position + basis(entity) * view.offset;
                            EXPECT_LT(glm::length(eye.position - offset), 1e-12);
                            ++cases;
                        }
    EXPECT_EQ(cases, 486);
    EXPECT_LT(worst, 1e-12);
    RecordProperty("worst_axis_error", figure(worst));
    // A level entity: the view's yaw adds to the heading.
    entity.yaw = 0.7;
    entity.pitch = entity.roll = 0.0;
    const ig::Pose left = sim::eyePose(entity, {{}, -30.0 * kDeg, 0.0, 0.0});
    EXPECT_NEAR(left.yaw, 0.7 - 30.0 * kDeg, 1e-15);
    EXPECT_NEAR(left.pitch, 0.0, 1e-15);
    EXPECT_NEAR(left.roll, 0.0, 1e-15);
}

// View Control and View Definition for this image generator's view are applied (only their
// enabled fields); another view's are not; an asymmetric frustum, or a new field of view once
// the run has begun, is refused and reported.
TEST(CigiView, ViewPacketsForThisViewOnly) {
    World world;
    sim::CigiOptions options = world.options();
    options.viewId = 2;
    sim::CigiPoseSource source(world.map, options);
    std::string error;
    ASSERT_EQ(source.open(&error), 0) << error;
    world.host.ig = source.session().localEndpoint();
    cigi::ViewControl mine;
    mine.viewId = 2;
    mine.yawEnable = mine.xEnable = true;
    mine.yawDeg = 330.0f;  // 30 degrees left
    mine.x = 3.0f;
    mine.y = 7.0f;  // not enabled
    cigi::ViewControl other = mine;
    other.viewId = 1;
    other.yawDeg = 30.0f;
    cigi::ViewDefinition def;
    def.viewId = 2;
    def.leftEnable = def.rightEnable = true;
    def.leftDeg = -25.0f;
    def.rightDeg = 25.0f;
    world.host.send({mine, other, def});
    const ig::Pose p0 = source.advanceTo(0.0);
    const sim::CigiSession& s = source.session();
    EXPECT_NEAR(s.view().yaw, -30.0 * kDeg, 1e-7);
    EXPECT_EQ(s.view().offset, glm::dvec3(3.0, 0.0, 0.0));
    EXPECT_NEAR(s.viewHfov(), 50.0 * kDeg, 1e-7);
    EXPECT_EQ(s.stats().viewControls, 1u);
    EXPECT_EQ(s.stats().viewDefinitions, 1u);
    EXPECT_NEAR(p0.yaw, options.startPose.yaw - 30.0 * kDeg, 1e-7);
    // Pitch alone: the yaw set before stays.
    cigi::ViewControl pitchOnly;
    pitchOnly.viewId = 2;
    pitchOnly.pitchEnable = true;
    pitchOnly.pitchDeg = -10.0f;
    world.host.send({pitchOnly});
    source.advanceTo(kPeriod);
    EXPECT_NEAR(s.view().yaw, -30.0 * kDeg, 1e-7);
    EXPECT_NEAR(s.view().pitch, -10.0 * kDeg, 1e-7);

    // During the run: the same field of view again changes nothing, a wider one is the field's
    // from this field on, a lopsided or too wide one is refused and changes nothing.
    source.session().freezeFieldOfView(s.viewHfov());
    EXPECT_NEAR(source.view().hfov, 50.0 * kDeg, 1e-7);
    cigi::ViewDefinition wider = def, lopsided = def, tooWide = def;
    wider.leftDeg = -40.0f;
    wider.rightDeg = 40.0f;
    lopsided.rightDeg = 35.0f;
    tooWide.leftDeg = -89.5f;
    tooWide.rightDeg = 89.5f;
    world.host.send({def, wider, lopsided, tooWide});
    source.advanceTo(2 * kPeriod);
    EXPECT_EQ(s.stats().viewDefinitions, 3u);  // the same one again, and the wider one
    EXPECT_EQ(s.stats().fieldOfViewChanges, 1u);
    EXPECT_EQ(s.stats().viewDefinitionsNotApplied, 2u);
    EXPECT_NEAR(s.viewHfov(), 80.0 * kDeg, 1e-7);
    EXPECT_NEAR(s.fieldHfov(), 80.0 * kDeg, 1e-7);
    EXPECT_NEAR(source.view().hfov, 80.0 * kDeg, 1e-7);
    int reported = 0;
    for (const std::string& e : s.stats().firstErrors)
        reported += e.find("View Definition for view 2") != std::string::npos;
    EXPECT_EQ(reported, 2);
}

// Two channels driven by one host: image generators for views 0 and 1 on their own ports,
// yawed -30 and +30 degrees with 60-degree fields of view, meet at the ownship's heading. Each
// renders its eye (the reference caster, as ig-render would): the right edge column of the
// left channel and the left edge column of the right one look half a pixel either side of the
// same edge, so they differ as two neighbouring columns of one image do: the seam's mean
// difference must be within 1.5 times that of the neighbouring columns beside the edge in each
// image (0.51 against 1.00 levels measured at 256 x 192; the pixel grids of two planes 60
// degrees apart cannot line up exactly, so no tighter pixel-for-pixel bound holds),
// while columns 60 degrees apart (the right channel's own right edge) differ many times more.
TEST(CigiView, TwoChannelsMeetAtTheirSharedEdge) {
    World world;
    sim::CigiOptions options = world.options();
    options.startPose.position = {1900.0, 1000.0, world.map.maxHeight() + 100.0};
    options.startPose.yaw = 45.0 * kDeg;
    options.viewId = 0;
    sim::CigiPoseSource left(world.map, options);
    options.viewId = 1;
    sim::CigiPoseSource right(world.map, options);
    std::string error;
    ASSERT_EQ(left.open(&error), 0) << error;
    ASSERT_EQ(right.open(&error), 0) << error;

    const glm::dvec3 g = left.session().geo().geodeticFromWorld(options.startPose.position);
    cigi::EntityControl e;
    e.latOrX = g.x;
    e.lonOrY = g.y;
    e.altOrZ = g.z;
    e.yawDeg = 45.0f;
    e.pitchDeg = -20.0f;
    std::vector<cigi::Packet> packets{e};
    for (std::uint16_t view : {0, 1}) {
        cigi::ViewControl vc;
        vc.viewId = view;
        vc.yawEnable = true;
        vc.yawDeg = view == 0 ? 330.0f : 30.0f;
        cigi::ViewDefinition vd;
        vd.viewId = view;
        vd.leftEnable = vd.rightEnable = true;
        vd.leftDeg = -30.0f;
        vd.rightDeg = 30.0f;
        packets.push_back(vc);
        packets.push_back(vd);
    }
    // One host message to each image generator (one sender, as a host with two channels).
    const std::vector<std::uint8_t> bytes = world.host.encode(packets);
    ASSERT_EQ(world.host.socket.sendTo(bytes, left.session().localEndpoint()), 0);
    ASSERT_EQ(world.host.socket.sendTo(bytes, right.session().localEndpoint()), 0);
    const ig::Pose l = left.advanceTo(0.0), r = right.advanceTo(0.0);
    EXPECT_EQ(world.host.receiveAll().size(), 2u) << "a Start of Frame from each channel";
    EXPECT_LT(glm::length(l.position - r.position), 1e-9);
    EXPECT_NEAR(left.session().viewHfov(), 60.0 * kDeg, 1e-7);
    EXPECT_NEAR(right.session().viewHfov(), 60.0 * kDeg, 1e-7);
    // Pitched down, each eye's heading is not just the entity's plus 30 degrees: compare the
    // shared edge's direction instead: the left eye's right edge and the right eye's left edge.
    const ig::Intrinsics k = ig::Intrinsics::fromFov(256, 192, left.session().viewHfov());
    const ig::CameraBasis bl = ig::CameraBasis::fromPose(l), br = ig::CameraBasis::fromPose(r);
    for (double v : {-1.0, 0.0, 1.0}) {
        const double half = 0.5 * k.width, vy = v * 0.5 * k.height;
        const glm::dvec3 dl = glm::normalize(bl.forward * k.focal + bl.right * half + bl.up * vy);
        const glm::dvec3 dr = glm::normalize(br.forward * k.focal - br.right * half + br.up * vy);
        EXPECT_LT(glm::length(dl - dr), 1e-6) << "edge row " << v;
    }

    const auto caster = ig::makeCaster(ig::CasterKind::Reference, world.map);
    const ig::RenderedFrame fl = ig::renderFrame(*caster, world.map, l, k);
    const ig::RenderedFrame fr = ig::renderFrame(*caster, world.map, r, k);
    const auto columnDiff = [&](const ig::RenderedFrame& a, int xa, const ig::RenderedFrame& b,
                                int xb) {
        double sum = 0.0;
        for (int y = 0; y < k.height; ++y) {
            const ig::Rgb8 pa = a.color[static_cast<std::size_t>(y * k.width + xa)];
            const ig::Rgb8 pb = b.color[static_cast<std::size_t>(y * k.width + xb)];
            sum += std::abs(pa.r - pb.r) + std::abs(pa.g - pb.g) + std::abs(pa.b - pb.b);
        }
        return sum / (3.0 * k.height);
    };
    // Neighbouring columns beside the edge, in each image.
    const double typical =
        0.5 * (columnDiff(fl, k.width - 2, fl, k.width - 1) + columnDiff(fr, 0, fr, 1));
    const double seam = columnDiff(fl, k.width - 1, fr, 0);
    const double wrong = columnDiff(fl, k.width - 1, fr, k.width - 1);
    EXPECT_GT(typical, 0.5) << "the terrain is too plain to tell a seam from a column";
    EXPECT_LE(seam, 1.5 * typical);
    EXPECT_GT(wrong, 4.0 * typical);
    RecordProperty("seam_mean_abs", figure(seam));
    RecordProperty("neighbour_columns_median", figure(typical));
    RecordProperty("far_edges_mean_abs", figure(wrong));
}

}  // namespace
