#include "sim/truth.hpp"

#include "ig/caster.hpp"
#include "ig/scene.hpp"
#include "ig/vox.hpp"
#include "io/field_clock.hpp"
#include "io/file_sinks.hpp"
#include "io/frame_sink.hpp"
#include "sim/frame_ring.hpp"
#include "sim/pipeline.hpp"
#include "sim/trajectory.hpp"
#include "sim/trajectory_poses.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "common/box_vox.hpp"
#include "common/counting_new.hpp"

#include <cmath>
#include <cstdio>
#include <filesystem>

#include <unistd.h>
#include <fstream>
#include <map>
#include <numbers>
#include <string>
#include <vector>

namespace {

// One folder per test process: ctest runs the tests of this file side by side.
std::string tmpDir() {
    const std::string dir = std::string(VIG_TEST_TMP) + "/truth-" + std::to_string(::getpid());
    std::filesystem::create_directories(dir);
    return dir;
}

// A flat map 100 m high (65 x 65 samples, 10 m apart) with a ridge along y = 300 m rising to
// 400 m: a camera south of it at 180 m cannot see what stands north of it.
ig::TerrainMap ridgeMap() {
    ig::TerrainMap map(65, 65, 10.0, 10.0, 0.1, 0.0);
    for (int iy = 0; iy < 65; ++iy) {
        for (int ix = 0; ix < 65; ++ix) {
            map.setRaw(ix, iy, iy == 30 ? 4000 : 1000);
            map.setColor(ix, iy, ig::Rgb8{90, 140, 60});
        }
    }
    map.updateRange();
    return map;
}

// A scene of solid boxes (4 x 4 x 6 voxels of 4 m): one in front of the ridge (id 1), one
// behind it (id 2), one driving east at 12 m/s in front of it (id 3).
struct World {
    ig::TerrainMap map = ridgeMap();
    ig::Scene scene;
    std::unique_ptr<sim::SceneMotion> motion;

    World() {
        const std::string dir = tmpDir();
        vig_test::writeBoxVox(dir + "/box.vox", 4, 4, 6);
        std::ofstream(dir + "/drive.csv") << "t,x,y,z,yaw_deg,pitch_deg,roll_deg\n"
                                             "0,240,230,0,90,0,0\n"
                                             "10,360,230,0,90,0,0\n";
        scene = ig::parseScene(R"({"cell_m": 2,
            "models": {"box": {"vox": "box.vox"}},
            "objects": [{"id": 1, "model": "box", "x": 330, "y": 200, "heading": 20, "scale": 4},
                        {"id": 2, "model": "box", "x": 320, "y": 420, "heading": 0, "scale": 4},
                        {"id": 3, "model": "box", "trajectory": "drive.csv", "scale": 4}]})",
                               dir + "/scene.json", map);
        motion = std::make_unique<sim::SceneMotion>(scene);
        ig::includeStickTops(map, *scene.staticLayer);
    }
};

// The camera flies north toward the objects, 80 m above the ground, looking a little down.
sim::Trajectory cameraPath() {
    std::vector<sim::TrajectorySample> s(2);
    for (int i = 0; i < 2; ++i) {
        s[i].t = 2.0 * i;
        s[i].pose.position = {300.0 + 4.0 * i, 40.0 + 30.0 * i, 180.0};
        s[i].pose.yaw = 0.02 * i;
        s[i].pose.pitch = -0.12;
        s[i].pose.roll = 0.03 * i;
    }
    return sim::Trajectory::fromSamples(s, "camera");
}

struct TruthRun {
    std::vector<std::string> lines;
    // Per field: visible pixels of each id counted in the field's own warped ids.
    std::vector<std::map<int, std::uint64_t>> counts;
    std::vector<prp::WarpModel> models;
};

// The trajectory's poses, with a host's field of view `hfov` from time `at` on (a CIGI View
// Definition during the run; never when `hfov` is 0).
class ZoomingPoses final : public sim::PoseSource {
  public:
    ZoomingPoses(sim::Trajectory trajectory, double at, double hfov)
        : poses_(std::move(trajectory)), at_(at), hfov_(hfov) {}
    ig::Pose advanceTo(double t) override {
        t_ = t;
        return poses_.advanceTo(t);
    }
    ig::Pose predict(double t) override { return poses_.predict(t); }
    double startTime() const override { return poses_.startTime(); }
    sim::RenderView view() const override { return {hfov_ > 0.0 && t_ >= at_ ? hfov_ : 0.0, 0.0}; }

  private:
    sim::TrajectoryPoses poses_;
    double at_, hfov_;
    double t_ = -1.0;
};

TruthRun runWithTruth(World& world, prp::WarpModel warp, sim::RendererMode mode,
                      double duration = 1.0, double startHfov = 0.0, double zoomAt = 0.0,
                      double zoomHfov = 0.0) {
    sim::RenderGeometry geometry;
    geometry.windowWidth = 128;
    geometry.windowHeight = 96;
    geometry.margin = 16;
    if (startHfov > 0.0) geometry.hfov = startHfov;
    sim::PipelineOptions options;
    options.duration = duration;
    options.clock = sim::ClockMode::Simulated;
    options.prp.model = warp;
    options.rendererMode = mode;
    options.maxFramePixels = sim::maxFramePixels(geometry);
    options.objectIds = true;
    TruthRun run;
    options.onField = [&](const prp::Field& field, const io::FieldBuffer&) {
        std::map<int, std::uint64_t> c;
        for (const std::uint16_t id : field.objectId)
            if (id != 0) ++c[id];
        run.counts.push_back(c);
        run.models.push_back(field.warp.model);
    };
    ZoomingPoses poses(cameraPath(), zoomAt, zoomHfov);
    io::NullSink sink;
    std::string error;
    sink.open({128, 96, io::PixelFormat::Rgb8}, &error);
    auto clock = io::makeSimulatedClock();
    const sim::TruthScene truthScene(world.scene, *world.motion, world.map);
    sim::TruthCamera camera;
    camera.window = sim::renderIntrinsics(geometry, ig::Pose{}).window();
    camera.outWidth = 128;
    camera.outHeight = 96;
    const std::string path = tmpDir() + "/truth.jsonl";
    std::FILE* file = std::fopen(path.c_str(), "w");
    EXPECT_NE(file, nullptr);
    {
        sim::TruthWriter writer(truthScene, camera, file, 128, 48, true, 4);
        options.truth = &writer;
        sim::Pipeline pipeline(poses,
                               sim::makeSceneRenderer(world.map, geometry, ig::CasterKind::Naive,
                                                      {}, world.scene, *world.motion),
                               sink, *clock, options);
        const sim::PipelineResult result = pipeline.run();
        EXPECT_TRUE(result.ok()) << result.error;
        EXPECT_EQ(writer.finish(), "");
        EXPECT_EQ(writer.written(), pipeline.fieldCount());
    }
    std::fclose(file);
    std::ifstream in(path);
    for (std::string line; std::getline(in, line);)
        run.lines.push_back(line);
    return run;
}

const nlohmann::json* findObject(const nlohmann::json& field, int id) {
    for (const nlohmann::json& o : field["objects"])
        if (o["id"] == id) return &o;
    return nullptr;
}

TEST(FrameRing, CarriesObjectIds) {
    sim::FrameRing ring(64, 1, true);
    ig::RenderedFrame f;
    f.sequence = 1;
    f.intrinsics = ig::Intrinsics::fromFov(8, 8, 1.0, 0);
    f.color.assign(64, ig::Rgb8{1, 2, 3});
    f.depth.assign(64, 5.0f);
    f.objectId.resize(64);
    for (std::size_t i = 0; i < 64; ++i)
        f.objectId[i] = static_cast<std::uint16_t>(i * 1000);
    ASSERT_TRUE(ring.publish(f, 1));
    ig::RenderedFrame got;
    std::string why;
    ASSERT_EQ(ring.fetch(got, &why), sim::FrameRing::Fetch::New) << why;
    EXPECT_EQ(got.objectId, f.objectId);
    // A frame without ids: the fetched frame has none.
    f.sequence = 2;
    f.objectId.clear();
    ASSERT_TRUE(ring.publish(f, 2));
    ASSERT_EQ(ring.fetch(got, &why), sim::FrameRing::Fetch::New) << why;
    EXPECT_TRUE(got.objectId.empty());
    // Ids of the wrong size, or a ring without an id plane: refused.
    f.objectId.assign(10, 1);
    EXPECT_FALSE(ring.publish(f, 3));
    sim::FrameRing plain(64);
    f.objectId.assign(64, 1);
    EXPECT_FALSE(plain.publish(f, 3));
}

// The truth under the simulated clock is the same, line for line, run after run, with a
// renderer thread or a renderer process; every visible count is the warped field's own.
TEST(Truth, DeterministicAndCountsTheWarpedIds) {
    World world;
    const TruthRun a = runWithTruth(world, prp::WarpModel::Auto, sim::RendererMode::Thread);
    const TruthRun b = runWithTruth(world, prp::WarpModel::Auto, sim::RendererMode::Thread);
    const TruthRun c = runWithTruth(world, prp::WarpModel::Auto, sim::RendererMode::Process);
    ASSERT_EQ(a.lines.size(), 60u);
    EXPECT_EQ(a.lines, b.lines);
    EXPECT_EQ(a.lines, c.lines);
    std::uint64_t shown = 0;
    for (std::size_t n = 0; n < a.lines.size(); ++n) {
        const nlohmann::json j = nlohmann::json::parse(a.lines[n]);
        EXPECT_EQ(j["field"], n);
        EXPECT_NEAR(j["time"].get<double>(), prp::fieldTime(0.0, n), 1e-6);
        std::map<int, std::uint64_t> listed;
        for (const nlohmann::json& o : j["objects"]) {
            if (o["visible_px"].get<std::uint64_t>() > 0) listed[o["id"]] = o["visible_px"];
        }
        EXPECT_EQ(listed, a.counts[n]) << "field " << n;
        shown += listed.size();
    }
    EXPECT_GT(shown, 60u);  // objects 1 and 3 in view most of the time
}

// Behind the ridge: in the frustum, listed, nothing visible, fully occluded.
// A host's field of view changed during the run reaches the truth at the field it is received
// for: from then on every object's true box is the one a run started at that field of view
// gives (the same 3-D box projected through the same field camera), before it the old one's.
TEST(Truth, FieldOfViewChangedDuringTheRunGivesThatFieldsTrueBoxes) {
    World world;
    const double wide = 60.0 * std::numbers::pi / 180.0, narrow = 40.0 * std::numbers::pi / 180.0;
    const double at = prp::fieldTime(0.0, 30);
    const TruthRun zoomed =
        runWithTruth(world, prp::WarpModel::Poly, sim::RendererMode::Thread, 1.0, wide, at, narrow);
    const TruthRun start =
        runWithTruth(world, prp::WarpModel::Poly, sim::RendererMode::Thread, 1.0, narrow);
    const TruthRun unzoomed =
        runWithTruth(world, prp::WarpModel::Poly, sim::RendererMode::Thread, 1.0, wide);
    ASSERT_EQ(zoomed.lines.size(), 60u);
    ASSERT_EQ(start.lines.size(), 60u);
    int compared = 0, differ = 0;
    for (std::size_t n = 0; n < zoomed.lines.size(); ++n) {
        const nlohmann::json z = nlohmann::json::parse(zoomed.lines[n]);
        const nlohmann::json s = nlohmann::json::parse(start.lines[n]);
        const nlohmann::json u = nlohmann::json::parse(unzoomed.lines[n]);
        for (const nlohmann::json& o : z["objects"]) {
            const nlohmann::json* same = findObject(n >= 30 ? s : u, o["id"]);
            const nlohmann::json* other = findObject(n >= 30 ? u : s, o["id"]);
            if (o["true_bbox"].is_null()) continue;
            ASSERT_NE(same, nullptr) << "field " << n << " object " << o["id"];
            EXPECT_EQ(o["true_bbox"], (*same)["true_bbox"]) << "field " << n << " " << o;
            EXPECT_EQ(o["range_m"], (*same)["range_m"]) << "field " << n;
            ++compared;
            if (!other || (*other)["true_bbox"] != o["true_bbox"]) ++differ;
        }
    }
    // Every field's boxes compared, and the two fields of view really give other boxes.
    EXPECT_GT(compared, 60);
    EXPECT_EQ(differ, compared);
}

TEST(Truth, ObjectBehindARidgeIsListedWithNoPixel) {
    World world;
    const TruthRun run = runWithTruth(world, prp::WarpModel::Poly, sim::RendererMode::Thread, 0.2);
    ASSERT_FALSE(run.lines.empty());
    for (const std::string& line : run.lines) {
        const nlohmann::json j = nlohmann::json::parse(line);
        const nlohmann::json* hidden = findObject(j, 2);
        ASSERT_NE(hidden, nullptr) << line;
        EXPECT_EQ((*hidden)["visible_px"], 0);
        EXPECT_GT((*hidden)["unoccluded_px"].get<int>(), 0);
        EXPECT_EQ((*hidden)["occluded"], 1.0);
        ASSERT_TRUE((*hidden)["true_bbox"].is_array());
        const nlohmann::json* front = findObject(j, 1);
        ASSERT_NE(front, nullptr);
        EXPECT_GT((*front)["visible_px"].get<int>(), 20);
        EXPECT_LT((*front)["occluded"].get<double>(), 0.25);
        EXPECT_NEAR((*front)["range_m"].get<double>(), 0.0, 1e9);
    }
}

// The moving box: its box in the warped ids against its exact 3-D box projected at each field's
// instant and pose. The warp moves the terrain, not the box, so the box lags by its motion over
// the frame's age, plus the pixel grid and the object grid's resampling.
TEST(Truth, MovingObjectBoxFollowsItsTrueBox) {
    World world;
    for (const prp::WarpModel m : {prp::WarpModel::Poly, prp::WarpModel::Depth}) {
        const TruthRun run = runWithTruth(world, m, sim::RendererMode::Thread);
        double worst[4] = {0, 0, 0, 0};
        int compared = 0;
        for (const std::string& line : run.lines) {
            const nlohmann::json j = nlohmann::json::parse(line);
            const nlohmann::json* o = findObject(j, 3);
            if (o == nullptr || (*o)["visible_px"].get<int>() == 0 ||
                !(*o)["true_bbox"].is_array() || (*o)["occluded"].get<double>() > 0.05) {
                continue;
            }
            ++compared;
            for (int k = 0; k < 4; ++k) {
                worst[k] = std::max(worst[k], std::abs((*o)["bbox"][k].get<double>() -
                                                       (*o)["true_bbox"][k].get<double>()));
            }
        }
        EXPECT_GT(compared, 40) << prp::warpModelName(m);
        // x: a pixel of grid, a cell (2 m) of resampling and the box's own motion over a frame's
        // age (12 m/s x 1/12 s at ~200 m): within 3 px; y: every other line, within 4.
        EXPECT_LE(worst[0], 3.0) << prp::warpModelName(m);
        EXPECT_LE(worst[2], 3.0) << prp::warpModelName(m);
        EXPECT_LE(worst[1], 4.0) << prp::warpModelName(m);
        EXPECT_LE(worst[3], 4.0) << prp::warpModelName(m);
        std::printf("%s: worst box edge error x0 %.2f y0 %.2f x1 %.2f y1 %.2f px over %d fields\n",
                    std::string(prp::warpModelName(m)).c_str(), worst[0], worst[1], worst[2],
                    worst[3], compared);
    }
}

// Wall clock, renderer thread drawing the objects, truth written: the field thread allocates
// nothing after warming up (the ids are warped into the field's own buffer and copied into a
// truth slot allocated before the run).
TEST(Truth, FieldThreadAllocatesNothingWithObjectsAndTruth) {
    World world;
    sim::RenderGeometry geometry;
    geometry.windowWidth = 128;
    geometry.windowHeight = 96;
    geometry.margin = 16;
    struct Sink final : io::FrameSink {
        int open(const io::VideoFormat& f, std::string*) override {
            format_ = f;
            return 0;
        }
        int writeField(const io::FieldBuffer& field) override {
            if (field.index == 60) atWarm = tThreadAllocations;
            atLast = tThreadAllocations;
            return 0;
        }
        int close(std::string*) override { return 0; }
        const io::VideoFormat& format() const override { return format_; }
        io::VideoFormat format_;
        std::size_t atWarm = 0, atLast = 0;
    } sink;
    std::string error;
    sink.open({128, 96, io::PixelFormat::Uyvy}, &error);
    sim::PipelineOptions options;
    options.duration = 1.5;
    options.renderThreads = 1;
    options.prp.model = prp::WarpModel::Auto;
    sim::TrajectoryPoses poses(cameraPath());
    auto clock = io::makeWallClock();
    const sim::TruthScene truthScene(world.scene, *world.motion, world.map);
    const sim::TruthCamera camera{sim::renderIntrinsics(geometry, ig::Pose{}).window(), 128, 96};
    std::FILE* file = std::fopen((tmpDir() + "/wall.jsonl").c_str(), "w");
    ASSERT_NE(file, nullptr);
    {
        sim::TruthWriter writer(truthScene, camera, file, 128, 48, false);
        options.truth = &writer;
        sim::Pipeline pipeline(poses,
                               sim::makeSceneRenderer(world.map, geometry, ig::CasterKind::Naive,
                                                      {}, world.scene, *world.motion),
                               sink, *clock, options);
        const sim::PipelineResult result = pipeline.run();
        ASSERT_TRUE(result.ok()) << result.error;
        EXPECT_EQ(writer.finish(), "");
        EXPECT_EQ(writer.written(), pipeline.fieldCount());
    }
    std::fclose(file);
    EXPECT_EQ(sink.atLast, sink.atWarm) << "field thread allocations after field 60";
}

// The ray test against a model placed with a heading: a ray straight down through the base
// centre meets it, one beside its rotated footprint does not.
TEST(Truth, RayMeetsTheRotatedModel) {
    ig::ObjectModel model;
    model.grid = ig::VoxModel(2, 10, 1);
    model.palette = ig::defaultVoxPalette();
    for (auto& v : model.grid.voxels)
        v = 7;
    sim::TruthObject o;
    o.model = &model;
    o.x = 100;
    o.y = 100;
    o.z = 0;
    o.scale = 1.0;
    o.heading = std::acos(-1.0) / 2;  // +y of the model along east
    o.hi[0] = 2;
    o.hi[1] = 10;
    o.hi[2] = 1;
    const glm::dvec3 down{0, 0, -1};
    EXPECT_TRUE(sim::rayMeetsObject(o, {100, 100, 50}, down));
    EXPECT_TRUE(sim::rayMeetsObject(o, {104.5, 100.5, 50}, down));   // 4.5 m east: inside
    EXPECT_FALSE(sim::rayMeetsObject(o, {100.5, 104.5, 50}, down));  // 4.5 m north: outside
    EXPECT_FALSE(sim::rayMeetsObject(o, {100, 100, 50}, glm::dvec3{0, 0, 1}));
    const auto corners = sim::objectCorners(o);
    double maxX = 0, maxY = 0;
    for (const glm::dvec3& c : corners) {
        maxX = std::max(maxX, c.x);
        maxY = std::max(maxY, c.y);
    }
    EXPECT_NEAR(maxX, 105.0, 1e-9);
    EXPECT_NEAR(maxY, 101.0, 1e-9);
}

// The per-object work spread over workers: the same line with one worker and with two, over a
// field listing a few hundred objects (many more than one worker's share of the work).
TEST(Truth, SameLineWithOneAndTwoWorkers) {
    const std::string dir = tmpDir();
    ig::TerrainMap map = ridgeMap();
    ig::VoxFile vox;
    vox.palette = ig::defaultVoxPalette();
    vox.models.push_back(ig::VoxModel(4, 4, 6));
    for (auto& v : vox.models[0].voxels)
        v = 7;
    ig::writeVox(dir + "/box-many.vox", vox);
    std::string objects;
    int id = 0;
    for (int iy = 0; iy < 16; ++iy) {
        for (int ix = 0; ix < 24; ++ix) {
            ++id;
            if (!objects.empty()) objects += ',';
            objects += "{\"id\": " + std::to_string(id) +
                       ", \"model\": \"box\", \"x\": " + std::to_string(70 + 20 * ix) +
                       ", \"y\": " + std::to_string(120 + 10 * iy) +
                       ", \"heading\": " + std::to_string((17 * id) % 360) + ", \"scale\": 2}";
        }
    }
    const ig::Scene scene = ig::parseScene(
        "{\"cell_m\": 2, \"models\": {\"box\": {\"vox\": \"box-many.vox\"}}, "
        "\"objects\": [" +
            objects + "]}",
        dir + "/scene-many.json", map);
    const sim::SceneMotion motion(scene);
    const sim::TruthScene truthScene(scene, motion, map);
    const int width = 160, height = 120, lines = height / 2;
    const ig::Intrinsics window = ig::Intrinsics::fromFov(width, height, 1.2);
    const sim::TruthCamera camera{window, width, height};
    ig::Pose pose;
    pose.position = {310.0, 20.0, 160.0};
    pose.pitch = -0.25;
    pose.roll = 0.05;
    // Ids in stripes: every object of the scene shows some pixels of the field.
    std::vector<std::uint16_t> ids(static_cast<std::size_t>(width) * lines);
    for (std::size_t k = 0; k < ids.size(); ++k)
        ids[k] = static_cast<std::uint16_t>((k / 3) % (id + 40));
    sim::TruthComputer one(1), two(2);
    sim::FieldTruth a, b;
    for (const int firstLine : {0, 1}) {
        one.compute(truthScene, camera, ids.data(), width, lines, firstLine, pose, 0.5, 7, a);
        two.compute(truthScene, camera, ids.data(), width, lines, firstLine, pose, 0.5, 7, b);
        std::uint64_t withRays = 0;
        for (const sim::ObjectTruth& o : a.objects)
            withRays += o.unoccludedPx > 0 ? 1 : 0;
        EXPECT_GT(a.objects.size(), 300u);
        EXPECT_GT(withRays, 50u);
        EXPECT_EQ(sim::truthLine(a), sim::truthLine(b));
    }
}

}  // namespace

// On the wall clock a writer that cannot keep up writes every field anyway, in order: late
// fields list the objects they show without the hidden fraction, lost fields their index and
// instant; finish() reports no error and the counts add up. Fields recorded back to back into
// two slots, far faster than any truth is worked out.
TEST(Truth, FallingBehindWritesEveryFieldInOrder) {
    World world;
    sim::RenderGeometry geometry;
    geometry.windowWidth = 128;
    geometry.windowHeight = 96;
    geometry.margin = 16;
    const sim::TruthScene truthScene(world.scene, *world.motion, world.map);
    const sim::TruthCamera camera{sim::renderIntrinsics(geometry, ig::Pose{}).window(), 128, 96};
    const sim::Trajectory path = cameraPath();
    const std::string path0 = tmpDir() + "/behind.jsonl";
    std::FILE* file = std::fopen(path0.c_str(), "w");
    ASSERT_NE(file, nullptr);
    constexpr int kFields = 300;
    std::uint64_t late = 0, lost = 0;
    {
        sim::TruthWriter writer(truthScene, camera, file, 128, 48, false, 2, 0);
        prp::Field field;
        field.width = 128;
        field.lines = 48;
        field.objectId.assign(128 * 48, 0);
        for (int y = 20; y < 30; ++y)
            for (int x = 50; x < 70; ++x)
                field.objectId[static_cast<std::size_t>(y) * 128 + x] = 1;
        for (int i = 0; i < kFields; ++i) {
            field.index = static_cast<std::uint64_t>(i);
            field.time = i * 1001.0 / 60000.0;
            field.parity = i % 2 ? prp::FieldParity::Bottom : prp::FieldParity::Top;
            writer.record(field, path.poseAt(field.time));
        }
        EXPECT_EQ(writer.finish(), "");
        EXPECT_EQ(writer.written(), static_cast<std::uint64_t>(kFields));
        late = writer.late();
        lost = writer.lost();
    }
    std::fclose(file);
    EXPECT_GT(lost, 0u);
    std::ifstream in(path0);
    int index = 0;
    std::uint64_t lateLines = 0, lostLines = 0;
    for (std::string line; std::getline(in, line); ++index) {
        const nlohmann::json j = nlohmann::json::parse(line);
        ASSERT_EQ(j["field"], index) << line;
        EXPECT_NEAR(j["time"].get<double>(), index * 1001.0 / 60000.0, 1e-6);
        if (j.contains("lost")) {
            ++lostLines;
            EXPECT_TRUE(j["objects"].is_null());
            continue;
        }
        const bool isLate = j.contains("late");
        lateLines += isLate ? 1 : 0;
        const nlohmann::json* o = findObject(j, 1);
        ASSERT_NE(o, nullptr) << line;
        EXPECT_EQ((*o)["visible_px"], 200);
        for (const nlohmann::json& e : j["objects"]) {
            if (isLate) {
                EXPECT_GT(e["visible_px"].get<int>(), 0) << line;
                EXPECT_TRUE(e["occluded"].is_null());
                EXPECT_TRUE(e["unoccluded_px"].is_null());
            } else {
                EXPECT_TRUE(e["unoccluded_px"].is_number());
            }
        }
    }
    EXPECT_EQ(index, kFields);
    EXPECT_EQ(lateLines, late);
    EXPECT_EQ(lostLines, lost);
}
