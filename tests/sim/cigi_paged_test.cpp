// A CIGI host's queries over a terrain database paged beyond memory (sim/terrain_queries.hpp):
// HAT/HOT, lines of sight and the sensors' terrain checks are answered on a thread of their own
// from the database's samples. The answers equal those of a session over the same map held
// whole, to the byte, a field or more later; a tile that cannot be read makes its answers
// invalid, never wrong; the field thread never waits for the disk.
#include "sim/cigi_session.hpp"
#include "sim/terrain_queries.hpp"

#include "common/cigi_host.hpp"
#include "common/small_terrain_db.hpp"
#include "ig/inset.hpp"
#include "ig/paged_ground.hpp"
#include "ig/paged_insets.hpp"
#include "ig/paged_terrain.hpp"
#include "ig/synthetic.hpp"
#include "ig/terrain_db.hpp"
#include "ig/terrain_db_build.hpp"
#include "io/cigi.hpp"

#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <future>
#include <map>
#include <numbers>
#include <optional>
#include <utility>
#include <variant>
#include <vector>

namespace {

namespace cigi = io::cigi;
using Host = vig_test::CigiHost;
using vig_test::kLoopback;
constexpr double kPeriod = 1001.0 / 60000.0;

sim::CigiOptions optionsFor(const Host& host, const ig::TerrainMap& map) {
    sim::CigiOptions o;
    o.bind = {kLoopback, 0};
    o.host = host.socket.localEndpoint();
    o.origin = {47.0, -122.0, 10.0};
    o.startPose.position = {500.0, 500.0, map.maxHeight() + 200.0};
    o.entityTypes = {{10, 0, 1.0}};
    return o;
}

// What a session sent, by packet kind and request (or sensor) id: the packet and its bytes.
struct Sent {
    cigi::Packet packet;
    std::vector<std::uint8_t> bytes;
    bool operator==(const Sent& o) const { return bytes == o.bytes; }
};
using Answers = std::map<std::pair<std::size_t, std::uint32_t>, Sent>;

bool validOf(const cigi::Packet& p) {
    return std::visit(
        [](const auto& a) {
            if constexpr (requires { a.valid; }) {
                return static_cast<bool>(a.valid);
            } else {
                return false;
            }
        },
        p);
}

std::uint32_t idOf(const cigi::Packet& p) {
    return std::visit(
        [](const auto& x) -> std::uint32_t {
            if constexpr (requires { x.requestId; }) {
                return x.requestId;
            } else if constexpr (requires { x.sensorId; }) {
                return x.sensorId;
            } else {
                return 0xffffffffu;
            }
        },
        p);
}

// Takes what the host received; the number of answers (Start of Frame left out).
std::size_t take(Host& host, Answers& out) {
    std::size_t n = 0;
    for (const cigi::Message& m : host.receiveAll()) {
        for (const cigi::Packet& p : m.packets) {
            if (std::holds_alternative<cigi::StartOfFrame>(p)) continue;
            std::vector<std::uint8_t> bytes;
            cigi::encodePacket(p, cigi::ByteOrder::Big, bytes);
            out[{p.index(), idOf(p)}] = Sent{p, std::move(bytes)};
            ++n;
        }
    }
    return n;
}

// One session over the map in memory, one over its database paged through a small cache.
struct Pair {
    vig_test::SmallTerrainDb small{"cigi_paged"};
    ig::TerrainDb db = ig::TerrainDb::open(small.path);
    // The paged session's map is a sparse one with nothing placed: it has the map's geometry
    // and none of its samples, so an answer that read it instead of asking the thread would
    // be wrong.
    ig::PagedTerrain empty{db, [] {
                               ig::PagedTerrain::Options o;
                               o.cache.budgetBytes = std::size_t{1} << 20;
                               return o;
                           }()};
    ig::PagedGround ground{db, ig::PagedGround::Options{}};
    sim::PagedTerrainQueries queries{db, [] {
                                         sim::PagedTerrainQueries::Options o;
                                         o.budgetBytes = std::size_t{192} << 10;
                                         return o;
                                     }()};
    Host memoryHost, pagedHost;
    sim::CigiSession memory{small.map, optionsFor(memoryHost, small.map)};
    sim::CigiSession paged{empty.map(), [&] {
                               sim::CigiOptions o = optionsFor(pagedHost, small.map);
                               o.ground = &ground;
                               o.terrainQueries = &queries;
                               return o;
                           }()};

    Pair() {
        std::string error;
        EXPECT_EQ(memory.open(&error), 0) << error;
        EXPECT_EQ(paged.open(&error), 0) << error;
        memoryHost.ig = memory.localEndpoint();
        pagedHost.ig = paged.localEndpoint();
        memory.poll(0.0);
        paged.poll(0.0);
        memoryHost.receiveAll();
        pagedHost.receiveAll();
    }
    void send(const std::vector<cigi::Packet>& packets) {
        memoryHost.send(packets);
        pagedHost.send(packets);
    }
    const ig::TerrainMap& map() const { return small.map; }
};

// The part of a map that requests cover: [x0, x1] x [y0, y1], points `step` metres apart.
struct Area {
    double x0 = 0.0, y0 = 0.0, x1 = 0.0, y1 = 0.0, step = 1.0;
};

// HAT, HOT and extended requests at a grid of points between samples, over the whole map (or
// `area`).
template <typename P>
std::vector<cigi::Packet> heightRequests(const P& p, std::optional<Area> area = {}) {
    const Area a = area.value_or(Area{7.3, 3.9, p.map().extentX(), p.map().extentY(), 0.0});
    const double sx = area ? a.step : 211.7, sy = area ? a.step : 197.3;
    std::vector<cigi::Packet> out;
    std::uint16_t id = 0;
    for (double x = a.x0; x < a.x1; x += sx) {
        for (double y = a.y0; y < a.y1; y += sy) {
            const glm::dvec3 g = p.memory.geo().geodeticFromWorld({x, y, 2500.0});
            for (cigi::HatHotType type :
                 {cigi::HatHotType::Hat, cigi::HatHotType::Hot, cigi::HatHotType::Extended}) {
                cigi::HatHotRequest q;
                q.requestId = id++;
                q.type = type;
                q.latOrX = g.x;
                q.lonOrY = g.y;
                q.altOrZ = g.z;
                out.push_back(q);
            }
        }
    }
    return out;
}

// Lines of sight: segments down through the terrain and over it, vectors down at the terrain,
// from a grid of points over the whole map (or `area`).
template <typename P>
std::vector<cigi::Packet> lineRequests(const P& p, std::optional<Area> area = {}) {
    const Area a = area.value_or(
        Area{100.0, 150.0, p.map().extentX() - 100.0, p.map().extentY() - 100.0, 0.0});
    const double sx = area ? a.step : 293.0, sy = area ? a.step : 611.0;
    std::vector<cigi::Packet> out;
    std::uint16_t id = 0;
    const double top = p.map().maxHeight();
    for (double x = a.x0; x < a.x1; x += sx) {
        for (double y = a.y0; y < a.y1; y += sy) {
            const glm::dvec3 src{x, y, top + 60.0};
            const glm::dvec3 gs = p.memory.geo().geodeticFromWorld(src);
            for (const double dz : {-1500.0, 40.0}) {
                const glm::dvec3 gd =
                    p.memory.geo().geodeticFromWorld(src + glm::dvec3{120.0, 900.0, dz});
                cigi::LosSegmentRequest q;
                q.requestId = id++;
                q.extended = dz < 0.0;
                q.sourceLatOrX = gs.x;
                q.sourceLonOrY = gs.y;
                q.sourceAltOrZ = gs.z;
                q.destinationLatOrX = gd.x;
                q.destinationLonOrY = gd.y;
                q.destinationAltOrZ = gd.z;
                out.push_back(q);
            }
            cigi::LosVectorRequest v;
            v.requestId = id++;
            v.extended = true;
            v.azimuthDeg = static_cast<float>(std::fmod(x * 0.37, 360.0) - 180.0);
            v.elevationDeg = -20.0f;
            v.maxRangeM = 3000.0f;
            v.sourceLatOrX = gs.x;
            v.sourceLonOrY = gs.y;
            v.sourceAltOrZ = gs.z;
            out.push_back(v);
        }
    }
    return out;
}

TEST(CigiPaged, AnswersEqualTheInMemorySessionsToTheByteAFieldLater) {
    Pair p;
    for (const auto& requests : {heightRequests(p), lineRequests(p)}) {
        ASSERT_GT(requests.size(), 40u);
        Answers memory, paged;
        p.send(requests);
        // The session over the map in memory answers in the next fields, 64 a field.
        int field = 1;
        for (; memory.size() < requests.size() && field < 50; ++field) {
            p.memory.poll(field * kPeriod);
            take(p.memoryHost, memory);
        }
        ASSERT_EQ(memory.size(), requests.size());
        // The paged one hands them to its thread; each goes out in the field after its answer
        // is ready (here: the next, waiting for the thread between fields).
        const std::uint64_t deferredBefore = p.paged.stats().deferredAnswers;
        int pagedField = 1;
        for (; paged.size() < requests.size() && pagedField < 60; ++pagedField) {
            p.paged.poll(pagedField * kPeriod);
            const std::size_t got = take(p.pagedHost, paged);
            if (pagedField == 1) {
                EXPECT_EQ(got, 0u) << "answered before its tiles were read";
            }
            p.queries.waitIdle();
        }
        ASSERT_EQ(paged.size(), requests.size());
        EXPECT_EQ(pagedField, field + 1) << "one field later than in memory";
        std::size_t same = 0;
        for (const auto& [key, bytes] : memory) {
            const auto it = paged.find(key);
            ASSERT_NE(it, paged.end()) << key.second;
            same += it->second == bytes;
            EXPECT_TRUE(it->second == bytes) << "request " << key.second;
        }
        EXPECT_EQ(same, requests.size());
        EXPECT_EQ(p.paged.stats().deferredAnswers - deferredBefore, requests.size());
    }
    const sim::PagedTerrainQueries::Stats q = p.queries.stats();
    EXPECT_EQ(q.unknown, 0u);
    EXPECT_EQ(q.refused, 0u);
    // The map's 256 level-0 tiles are more than the cache holds: tiles were read, let go and
    // read again.
    EXPECT_GT(q.tilesRead, 100u);
    EXPECT_EQ(p.paged.stats().unknownTerrain, 0u);
    RecordProperty("tiles_read", std::to_string(q.tilesRead));
    RecordProperty("batches", std::to_string(q.batches));
}

TEST(CigiPaged, SensorsSeeWhatTheInMemorySessionSeesAFieldLater) {
    Pair p;
    // The ownship low over the middle of the map; twelve entities on rings around it, a few
    // metres over the surface, some behind hills; sensor i tracks entity i.
    const ig::TerrainMap& map = p.map();
    const glm::dvec3 eye{0.5 * map.extentX(), 0.5 * map.extentY(), 0.0};
    std::vector<cigi::Packet> packets;
    cigi::EntityControl own;
    const glm::dvec3 ge =
        p.memory.geo().geodeticFromWorld({eye.x, eye.y, map.surfaceHeight(eye.x, eye.y) + 30.0});
    own.latOrX = ge.x;
    own.lonOrY = ge.y;
    own.altOrZ = ge.z;
    own.yawDeg = 0.0f;
    packets.push_back(own);
    const int n = 12;
    for (int i = 1; i <= n; ++i) {
        const double a = 0.1 + 2.0 * std::numbers::pi * i / n, r = 300.0 + 60.0 * i;
        const double x = eye.x + r * std::sin(a), y = eye.y + r * std::cos(a);
        cigi::EntityControl e;
        e.entityId = static_cast<std::uint16_t>(i);
        e.entityType = 10;
        const glm::dvec3 g =
            p.memory.geo().geodeticFromWorld({x, y, map.surfaceHeight(x, y) + 3.0});
        e.latOrX = g.x;
        e.lonOrY = g.y;
        e.altOrZ = g.z;
        packets.push_back(e);
        cigi::SensorControl s;
        s.viewId = 0;
        s.sensorId = static_cast<std::uint8_t>(i);
        s.sensorOn = true;
        s.trackMode = cigi::SensorTrackMode::Target;
        s.extendedResponse = true;
        packets.push_back(s);
        cigi::ComponentControl c;
        c.componentClass = cigi::kComponentClassSensor;
        c.instanceId = static_cast<std::uint16_t>(i);
        c.componentId = 0;
        c.data[0] = static_cast<std::uint32_t>(i);
        packets.push_back(c);
    }
    p.send(packets);
    // The ownship turns slowly: each field the memory session's sensors against the paged
    // one's of the next field (it answers from the terrain's check asked a field before).
    int tracking = 0, lost = 0, compared = 0;
    std::vector<Answers> memory, paged;
    for (int field = 1; field <= 24; ++field) {
        if (field > 1) {
            cigi::EntityControl turn = own;
            turn.yawDeg = static_cast<float>(15.0 * (field / 2));
            p.send({turn});
        }
        Answers m, q;
        p.memory.poll(field * kPeriod);
        take(p.memoryHost, m);
        p.paged.poll(field * kPeriod);
        take(p.pagedHost, q);
        p.queries.waitIdle();
        memory.push_back(std::move(m));
        paged.push_back(std::move(q));
    }
    // Even fields turn; the odd field after holds the pose: its check was asked at the same
    // pose, so its statuses equal the memory session's.
    for (std::size_t f = 2; f < memory.size(); f += 2) {
        ASSERT_EQ(memory[f].size(), static_cast<std::size_t>(n));
        ASSERT_EQ(paged[f].size(), static_cast<std::size_t>(n));
        for (const auto& [key, bytes] : memory[f]) {
            ASSERT_TRUE(paged[f].count(key));
            EXPECT_TRUE(paged[f].at(key) == bytes) << "sensor " << key.second << " field " << f;
            ++compared;
        }
    }
    for (const auto& fieldAnswers : memory) {
        for (const auto& [key, sent] : fieldAnswers) {
            const auto& r = std::get<cigi::SensorExtendedResponse>(sent.packet);
            (r.status == cigi::SensorStatus::Tracking ? tracking : lost)++;
        }
    }
    EXPECT_GT(compared, 100);
    EXPECT_GT(tracking, 10) << "the test sees entities";
    EXPECT_GT(lost, 10) << "the test hides entities";
}

TEST(CigiPaged, TilesThatCannotBeReadMakeAnswersInvalidNotWrong) {
    Pair p;
    // Every level-0 tile east of the middle is unreadable for the queries' thread.
    const int half = p.db.layout().tilesX(ig::TileKind::Display, 0) / 2;
    p.queries.setWithheld([half](const ig::TileKey& k) {
        return k.kind == ig::TileKind::Display && k.level == 0 && k.tx >= half;
    });
    const double eastFrom = half * p.db.layout().tileSize() * p.map().spacingX();
    const std::vector<cigi::Packet> requests = heightRequests(p);
    std::map<std::uint32_t, double> xOf;
    for (const cigi::Packet& r : requests) {
        const auto& q = std::get<cigi::HatHotRequest>(r);
        xOf[q.requestId] = p.memory.geo().worldFromGeodetic(q.latOrX, q.lonOrY, q.altOrZ).x;
    }
    Answers memory, paged;
    p.send(requests);
    for (int field = 1; field < 60 && paged.size() < requests.size(); ++field) {
        p.memory.poll(field * kPeriod);
        take(p.memoryHost, memory);
        p.paged.poll(field * kPeriod);
        take(p.pagedHost, paged);
        p.queries.waitIdle();
    }
    ASSERT_EQ(paged.size(), requests.size());
    std::size_t west = 0, east = 0;
    for (const auto& [key, sent] : paged) {
        const bool valid = validOf(sent.packet);
        // A cell's tile is the one holding its south-west sample.
        const double x = xOf.at(key.second);
        if (x < eastFrom - 1e-6) {
            EXPECT_TRUE(valid) << key.second;
            EXPECT_TRUE(sent == memory.at(key)) << key.second;
            ++west;
        } else if (x >= eastFrom + p.map().spacingX()) {
            EXPECT_FALSE(valid) << "request " << key.second << " at x " << x;
            ++east;
        }
    }
    EXPECT_GT(west, 100u);
    EXPECT_GT(east, 100u);
    EXPECT_GE(p.paged.stats().unknownTerrain, east);
    EXPECT_EQ(p.queries.stats().unknown, p.paged.stats().unknownTerrain);
}

TEST(CigiPaged, TheFieldThreadNeverWaitsForTheDisk) {
    Pair p;
    // The disk hangs: every tile read waits until the test lets it go (at most 60 s, so a
    // failing test ends).
    std::promise<void> release;
    std::shared_future<void> gate = release.get_future().share();
    p.queries.setWithheld([gate](const ig::TileKey&) {
        gate.wait_for(std::chrono::seconds(60));
        return false;
    });
    const std::vector<cigi::Packet> requests = lineRequests(p);
    p.send(requests);
    Answers paged;
    // Fields go on, each with its Start of Frame and no answer, while the reads hang.
    for (int field = 1; field <= 10; ++field) {
        p.paged.poll(field * kPeriod);
        const auto messages = p.pagedHost.receiveAll();
        ASSERT_EQ(messages.size(), 1u) << "field " << field;
        ASSERT_EQ(messages[0].packets.size(), 1u) << "field " << field;
        EXPECT_TRUE(std::holds_alternative<cigi::StartOfFrame>(messages[0].packets[0]));
    }
    EXPECT_EQ(p.queries.outstanding(), requests.size());
    release.set_value();
    p.queries.waitIdle();
    for (int field = 11; field < 40 && paged.size() < requests.size(); ++field) {
        p.paged.poll(field * kPeriod);
        take(p.pagedHost, paged);
    }
    EXPECT_EQ(paged.size(), requests.size());
    EXPECT_GE(p.paged.stats().maxAnswerFields, 10u);
}

// A database holding an inset (a 256² map at 8 m, a 2 m inset over 48 x 40 cells), and the
// same nested terrain in memory: one session over each, and one over the global map alone.
struct InsetPair {
    std::string path =
        vig_test::testTmpPath("cigi_paged", "insets_" + std::to_string(::getpid()) + ".db");
    static ig::InsetSource inset() { return ig::syntheticInset(5, 8.0, 100, 100, 48, 40, 4); }
    ig::NestedTerrain nested{ig::makeSyntheticTerrain(256, 5, 8.0), {inset()}, 16};
    ig::NestedMaps maps = nested.maps();
    ig::NestedGround nestedGround{maps};
    ig::TerrainMap plain = ig::makeSyntheticTerrain(256, 5, 8.0);
    ig::TerrainDb db = [&] {
        auto rows = ig::mapRowSource(plain);
        ig::DbBuildOptions o;
        o.tileSize = 16;
        o.insets = {inset()};
        ig::buildTerrainDb(*rows, path, o);
        return ig::TerrainDb::open(path);
    }();
    ig::PagedTerrain empty{db, [] {
                               ig::PagedTerrain::Options o;
                               o.cache.budgetBytes = std::size_t{1} << 20;
                               return o;
                           }()};
    ig::PagedGround ground{db, ig::PagedGround::Options{}};
    ig::PagedNestedGround pagedNestedGround{ground, db, ig::PagedGround::Options{}};
    sim::PagedTerrainQueries queries{db, [] {
                                         sim::PagedTerrainQueries::Options o;
                                         o.budgetBytes = std::size_t{512} << 10;
                                         return o;
                                     }()};
    Host memoryHost, pagedHost, plainHost;
    sim::CigiSession memory{nested.global(), [&] {
                                sim::CigiOptions o = optionsFor(memoryHost, nested.global());
                                o.ground = &nestedGround;
                                o.surface = &maps;
                                return o;
                            }()};
    sim::CigiSession paged{empty.map(), [&] {
                               sim::CigiOptions o = optionsFor(pagedHost, nested.global());
                               o.ground = &pagedNestedGround;
                               o.terrainQueries = &queries;
                               return o;
                           }()};
    sim::CigiSession flat{plain, optionsFor(plainHost, plain)};

    InsetPair() {
        std::string error;
        for (sim::CigiSession* s : {&memory, &paged, &flat})
            EXPECT_EQ(s->open(&error), 0) << error;
        memoryHost.ig = memory.localEndpoint();
        pagedHost.ig = paged.localEndpoint();
        plainHost.ig = flat.localEndpoint();
        for (sim::CigiSession* s : {&memory, &paged, &flat})
            s->poll(0.0);
        for (Host* h : {&memoryHost, &pagedHost, &plainHost})
            h->receiveAll();
    }
    ~InsetPair() { std::filesystem::remove(path); }
    const ig::TerrainMap& map() const { return nested.global(); }
};

// Over a database's inset a host's HAT/HOT and lines of sight read the inset's surface: the
// paged session's answers equal, to the byte, those of a session over the nested terrain in
// memory, and many differ from the global map's alone.
TEST(CigiPaged, OverAnInsetAnswersAreTheNestedSurfacesToTheByte) {
    InsetPair p;
    const ig::Inset& in = p.nested.insets()[0];
    const Area around{in.coverMin.x - 60.0, in.coverMin.y - 60.0, in.coverMax.x + 60.0,
                      in.coverMax.y + 60.0, 37.3};
    for (const auto& requests : {heightRequests(p, around), lineRequests(p, around)}) {
        ASSERT_GT(requests.size(), 100u);
        Answers memory, paged, flat;
        p.memoryHost.send(requests);
        p.pagedHost.send(requests);
        p.plainHost.send(requests);
        for (int field = 1;
             field < 120 && (memory.size() < requests.size() || paged.size() < requests.size() ||
                             flat.size() < requests.size());
             ++field) {
            for (sim::CigiSession* s : {&p.memory, &p.paged, &p.flat})
                s->poll(field * kPeriod);
            take(p.memoryHost, memory);
            take(p.pagedHost, paged);
            take(p.plainHost, flat);
            p.queries.waitIdle();
        }
        ASSERT_EQ(memory.size(), requests.size());
        ASSERT_EQ(paged.size(), requests.size());
        ASSERT_EQ(flat.size(), requests.size());
        std::size_t same = 0, differFromFlat = 0, valid = 0;
        for (const auto& [key, sent] : memory) {
            same += paged.at(key) == sent;
            EXPECT_TRUE(paged.at(key) == sent) << "request " << key.second;
            differFromFlat += !(flat.at(key) == sent);
            valid += validOf(sent.packet);
        }
        std::printf(
            "%zu answers over the inset: %zu the same paged, %zu valid, %zu differ from "
            "the global map's alone\n",
            memory.size(), same, valid, differFromFlat);
        EXPECT_EQ(same, requests.size());
        EXPECT_GT(valid, requests.size() / 2);
        EXPECT_GT(differFromFlat, requests.size() / 4);
    }
    EXPECT_EQ(p.queries.stats().unknown, 0u);
    EXPECT_EQ(p.paged.stats().unknownTerrain, 0u);
}

}  // namespace
