// A CIGI host's entities drawn by the renderer process: placed on the field thread at each
// render request's instant and carried with the request through the frame ring, they give the
// video and truth the renderer thread gives (simulated clock, byte for byte).
#include "sim/cigi_session.hpp"

#include "ig/scene.hpp"
#include "ig/vox.hpp"
#include "io/cigi.hpp"
#include "io/field_clock.hpp"
#include "io/file_sinks.hpp"
#include "sim/frame_ring.hpp"
#include "sim/pipeline.hpp"
#include "sim/render_process.hpp"
#include "sim/scene_motion.hpp"
#include "sim/truth.hpp"

#include "common/box_vox.hpp"
#include "common/cigi_host.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <unistd.h>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

namespace {

namespace cigi = io::cigi;

ig::TerrainMap flatMap() {
    ig::TerrainMap map(65, 65, 10.0, 10.0, 0.1, 0.0);
    for (int iy = 0; iy < 65; ++iy) {
        for (int ix = 0; ix < 65; ++ix) {
            map.setRaw(ix, iy, 1000 + 40 * ((ix + iy) % 3));
            map.setColor(ix, iy, ig::Rgb8{static_cast<std::uint8_t>(60 + ix * 2), 140, 60});
        }
    }
    map.updateRange();
    return map;
}

std::string tmpDir() {
    const std::string dir =
        std::string(VIG_TEST_TMP) + "/host-process-" + std::to_string(::getpid());
    std::filesystem::create_directories(dir);
    return dir;
}

struct HostRun {
    std::vector<std::uint8_t> video;          // every field's pixels, in order
    std::vector<std::uint64_t> entityPixels;  // per field: pixels whose id is the entity's
    std::string truth;
};

// The ownship 200 m south of the entity, 60 m up, looking north; entity 42 (a box) driving
// east at 8 m/s (or `speed`) on the ground; field ids and truth recorded; with `restamp`, the
// processor re-stamps the entity at each field's instant.
HostRun runWith(sim::RendererMode mode, bool restamp = false, float speed = 8.0f) {
    ig::TerrainMap map = flatMap();
    const std::string dir = tmpDir();
    vig_test::writeBoxVox(dir + "/box.vox", 4, 2, 3);
    const ig::Scene scene = ig::parseScene(
        R"({"cell_m": 2, "models": {"box": {"vox": "box.vox"}},
            "objects": [{"id": 5, "model": "box", "x": 330, "y": 340, "heading": 20, "scale": 4}]})",
        dir + "/scene.json", map);
    const sim::SceneMotion motion(scene);

    vig_test::CigiHost host;
    sim::CigiOptions options;
    options.bind = {vig_test::kLoopback, 0};
    options.host = host.socket.localEndpoint();
    options.origin = {47.0, -122.0, 0.0};
    options.startPose.position = {312.0, 130.0, 160.0};
    options.entityTypes = {{10, scene.modelIndex("box"), 4.0}};
    sim::CigiPoseSource source(map, options);
    std::string error;
    EXPECT_EQ(source.open(&error), 0) << error;
    host.ig = source.session().localEndpoint();
    const sim::GeoFrame& geo = source.session().geo();
    cigi::EntityControl own;
    own.entityId = 0;
    const glm::dvec3 g0 = geo.geodeticFromWorld({312.0, 130.0, 160.0});
    own.latOrX = g0.x;
    own.lonOrY = g0.y;
    own.altOrZ = g0.z;
    own.pitchDeg = -10.0f;
    cigi::EntityControl box;
    box.entityId = 42;
    box.entityType = 10;
    const glm::dvec3 g1 = geo.geodeticFromWorld({290.0, 320.0, 0.0});
    box.latOrX = g1.x;
    box.lonOrY = g1.y;
    box.altOrZ = g1.z;
    box.yawDeg = 90.0f;
    box.groundClamp = cigi::GroundClamp::NonConformal;
    cigi::RateControl rate;
    rate.entityId = 42;
    rate.yRate = speed;  // CIGI world rates: y east
    host.send({own, box, rate});

    sim::RenderGeometry geometry;
    geometry.windowWidth = 96;
    geometry.windowHeight = 64;
    geometry.hfov = 0.7;
    geometry.margin = 8;
    sim::PipelineOptions po;
    po.duration = 0.5;
    po.clock = sim::ClockMode::Simulated;
    po.rendererMode = mode;
    po.maxFramePixels = sim::maxFramePixels(geometry);
    po.objectIds = true;
    sim::ExtraObjects extra;
    if (mode == sim::RendererMode::Process) {
        po.requestObjects = [&](double t, std::vector<sim::ExtraObject>& out) {
            source.objectsAt(t, out);
        };
        extra = [](double, std::vector<sim::ExtraObject>& out) {
            const auto carried = sim::requestObjects();
            out.assign(carried.begin(), carried.end());
        };
    } else {
        extra = [&](double t, std::vector<sim::ExtraObject>& out) { source.objectsAt(t, out); };
    }
    // The truth lists the host's entities too, placed at each field's instant by the session.
    po.truthObjects = [&](double t, std::vector<sim::ExtraObject>& out) {
        source.session().objectsAt(t, out);
    };
    std::optional<sim::TruthScene> motionScene;
    std::optional<sim::ObjectMotionBetween> between;
    std::vector<sim::ExtraObject> atFrame, atField;
    if (restamp) {
        motionScene.emplace(scene, motion, map);
        between.emplace(*motionScene);
        po.objectMotion = [&](double frameTime, double fieldTime) {
            source.session().objectsAt(frameTime, atFrame);
            source.session().objectsAt(fieldTime, atField);
            return between->between(frameTime, fieldTime, atFrame, atField);
        };
    }
    HostRun run;
    po.onField = [&](const prp::Field& field, const io::FieldBuffer& buffer) {
        for (int l = 0; l < buffer.lines; ++l) {
            const std::uint8_t* row = buffer.data + static_cast<std::size_t>(l) * buffer.stride;
            run.video.insert(run.video.end(), row, row + 96 * 3);
        }
        run.entityPixels.push_back(static_cast<std::uint64_t>(
            std::count(field.objectId.begin(), field.objectId.end(), std::uint16_t{42})));
    };
    io::NullSink sink;
    sink.open({96, 64, io::PixelFormat::Rgb8}, &error);
    auto clock = io::makeSimulatedClock();
    const sim::TruthScene truthScene(scene, motion, map);
    const sim::TruthCamera camera{sim::renderIntrinsics(geometry, ig::Pose{}).window(), 96, 64};
    const std::string path = dir + "/truth-" + std::to_string(static_cast<int>(mode)) + ".jsonl";
    std::FILE* file = std::fopen(path.c_str(), "w");
    EXPECT_NE(file, nullptr);
    {
        sim::TruthWriter writer(truthScene, camera, file, 96, 32, true, 4);
        po.truth = &writer;
        sim::Pipeline pipeline(
            source,
            sim::makeSceneRenderer(map, geometry, ig::CasterKind::Naive, {}, scene, motion, extra),
            sink, *clock, po);
        const sim::PipelineResult result = pipeline.run();
        EXPECT_TRUE(result.ok()) << result.error;
        EXPECT_EQ(writer.finish(), "");
    }
    std::fclose(file);
    std::ifstream in(path);
    run.truth.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
    return run;
}

TEST(HostEntities, RendererProcessDrawsWhatTheThreadDraws) {
    const HostRun thread = runWith(sim::RendererMode::Thread);
    const HostRun process = runWith(sim::RendererMode::Process);
    ASSERT_EQ(thread.entityPixels.size(), 30u);
    // The entity shows once the first frame rendered after the host's first message is out
    // (the first frames precede it), and moves.
    std::string counts;
    for (const std::uint64_t n : thread.entityPixels)
        counts += std::to_string(n) + " ";
    EXPECT_GT(*std::min_element(thread.entityPixels.begin() + 12, thread.entityPixels.end()), 20u)
        << counts;
    EXPECT_NE(thread.entityPixels[12], thread.entityPixels[29]) << counts;
    EXPECT_EQ(thread.entityPixels, process.entityPixels);
    EXPECT_FALSE(thread.video.empty());
    EXPECT_TRUE(thread.video == process.video) << "the videos differ";
    EXPECT_NE(thread.truth.find("\"id\":5"), std::string::npos);
    EXPECT_EQ(thread.truth, process.truth);
    // The host's entity in every field's truth once it shows: the field's own count of its
    // pixels, their box inside its exact box projected at the field's pose (within the warp's
    // pixel), and moving.
    std::istringstream lines(thread.truth);
    std::size_t n = 0, listed = 0;
    for (std::string line; std::getline(lines, line); ++n) {
        const nlohmann::json field = nlohmann::json::parse(line);
        const nlohmann::json* entity = nullptr;
        for (const nlohmann::json& o : field["objects"])
            if (o["id"] == 42) entity = &o;
        ASSERT_LT(n, thread.entityPixels.size());
        if (thread.entityPixels[n] == 0) continue;
        ASSERT_NE(entity, nullptr) << "field " << n;
        ++listed;
        EXPECT_EQ((*entity)["visible_px"], thread.entityPixels[n]) << "field " << n;
        EXPECT_TRUE((*entity)["moving"].get<bool>());
        const nlohmann::json& box = (*entity)["bbox"];
        const nlohmann::json& truth = (*entity)["true_bbox"];
        ASSERT_TRUE(truth.is_array()) << "field " << n;
        for (int k = 0; k < 2; ++k) {
            EXPECT_GE(box[k].get<double>(), truth[k].get<double>() - 1.5) << "field " << n;
            EXPECT_LE(box[k + 2].get<double>(), truth[k + 2].get<double>() + 1.5) << "field " << n;
        }
    }
    EXPECT_GE(listed, 15u);
}

// Mean distance of the entity's centroid in the fields from the middle of its true box, over the
// fields that show it (from the first frame that draws it).
double centroidError(const HostRun& run) {
    std::istringstream lines(run.truth);
    double sum = 0.0;
    int n = 0;
    for (std::string line; std::getline(lines, line);) {
        const nlohmann::json field = nlohmann::json::parse(line);
        for (const nlohmann::json& o : field["objects"]) {
            if (o["id"] != 42 || o["visible_px"].get<int>() == 0 || !o["true_bbox"].is_array())
                continue;
            const auto& t = o["true_bbox"];
            const double cx = 0.5 * (t[0].get<double>() + t[2].get<double>());
            const double cy = 0.5 * (t[1].get<double>() + t[3].get<double>());
            sum += std::hypot(o["centroid"][0].get<double>() - cx,
                              o["centroid"][1].get<double>() - cy);
            ++n;
        }
    }
    EXPECT_GT(n, 10);
    return n > 0 ? sum / n : 0.0;
}

// The processor re-stamps the host's entity at each field's instant, where the session
// dead-reckons it: its centroid follows its true box closer than the frame's.
TEST(HostEntities, ReStampedAtEachFieldsInstant) {
    // 60 m/s: some 3 px between frames.
    const HostRun held = runWith(sim::RendererMode::Thread, false, 60.0f);
    const HostRun restamped = runWith(sim::RendererMode::Thread, true, 60.0f);
    const double before = centroidError(held), after = centroidError(restamped);
    RecordProperty("centroid_error_px", std::to_string(before) + " -> " + std::to_string(after));
    std::printf(
        "entity centroid from its true box middle: %.6f px as rendered, %.6f px "
        "re-stamped\n",
        before, after);
    EXPECT_LT(after, 0.6 * before);
}

// The objects a request carries come back as they were posted, and only with that request.
TEST(HostEntities, RequestCarriesItsObjects) {
    sim::FrameRing ring(64);
    std::vector<sim::ExtraObject> objects(3);
    for (int i = 0; i < 3; ++i) {
        objects[i].model = i;
        objects[i].placement.id = static_cast<std::uint16_t>(100 + i);
        objects[i].placement.x = 10.5 * i;
        objects[i].placement.y = -3.25;
        objects[i].placement.z = 1e-3 * i;
        objects[i].placement.heading = 0.1 * i;
        objects[i].placement.scale = 0.25;
        objects[i].onGround = i == 1;
    }
    EXPECT_TRUE(ring.postRequest(ig::Pose{}, 1.5, 7, objects));
    std::vector<sim::ExtraObject> got;
    const sim::RenderRequest r = ring.latestRequest(&got);
    EXPECT_EQ(r.sequence, 7u);
    ASSERT_EQ(got.size(), 3u);
    for (int i = 0; i < 3; ++i) {
        EXPECT_EQ(got[i].model, i);
        EXPECT_EQ(got[i].placement.id, 100 + i);
        EXPECT_EQ(got[i].placement.x, 10.5 * i);
        EXPECT_EQ(got[i].placement.y, -3.25);
        EXPECT_EQ(got[i].placement.z, 1e-3 * i);
        EXPECT_EQ(got[i].placement.heading, 0.1 * i);
        EXPECT_EQ(got[i].placement.scale, 0.25);
        EXPECT_EQ(got[i].onGround, i == 1);
    }
    EXPECT_TRUE(ring.postRequest(ig::Pose{}, 1.6, 8));
    ring.latestRequest(&got);
    EXPECT_TRUE(got.empty());
    std::vector<sim::ExtraObject> many(sim::kMaxRequestObjects + 5);
    EXPECT_FALSE(ring.postRequest(ig::Pose{}, 1.7, 9, many));
    ring.latestRequest(&got);
    EXPECT_EQ(got.size(), sim::kMaxRequestObjects);
}

}  // namespace
