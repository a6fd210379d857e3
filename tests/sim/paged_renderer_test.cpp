// The real-time renderer over a terrain database paged by the view (sim::makePagedRenderer):
// frames along a flight, none of them waiting after the first, equal the in-memory render to
// the bit wherever their tiles were resident, and the misses are counted.
#include "sim/pipeline.hpp"

#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "common/box_vox.hpp"
#include "common/small_terrain_db.hpp"
#include "ig/caster.hpp"
#include "ig/scene.hpp"
#include "ig/synthetic.hpp"
#include "ig/terrain_db.hpp"
#include "ig/terrain_db_build.hpp"
#include "sim/stereo_output.hpp"

namespace {

// A 1025 x 1025 synthetic map (10 m) in tiles of 16, paged through 2 MB.
struct Database {
    ig::TerrainMap map = ig::makeSyntheticTerrain(1024, 11);
    std::string path =
        vig_test::testTmpPath("paged_renderer", "map_" + std::to_string(::getpid()) + ".db");
    Database() {
        auto source = ig::mapRowSource(map);
        ig::DbBuildOptions o;
        o.tileSize = 16;
        ig::buildTerrainDb(*source, path, o);
    }
    ~Database() { std::filesystem::remove(path); }
};

bool sameFrame(const ig::RenderedFrame& a, const ig::RenderedFrame& b) {
    if (a.color.size() != b.color.size()) return false;
    for (std::size_t i = 0; i < a.color.size(); ++i)
        if (!(a.color[i] == b.color[i]) || a.depth[i] != b.depth[i]) return false;
    for (std::size_t i = 0; i < a.controlPoints.size(); ++i)
        if (a.controlPoints[i].world != b.controlPoints[i].world) return false;
    return true;
}

// A 96 x 64 view (margin 8), the fast caster's levels auto, paged through 2 MB.
struct Viewing {
    sim::RenderGeometry geometry;
    ig::RenderOptions options;
    ig::PagedTerrain::Options paging;
    Viewing() {
        geometry.windowWidth = 96;
        geometry.windowHeight = 64;
        geometry.margin = 8;
        options.levels = ig::kLevelsAuto;
        paging.cache.budgetBytes = std::size_t{2} << 20;
        // Full detail, as the in-memory twins draw, however fast this machine writes tiles.
        paging.placeBudgetMs = 0.0;
    }
};

TEST(PagedRenderer, FramesWithTheirTilesResidentEqualTheInMemoryRender) {
    const Database d;
    const ig::TerrainDb db = ig::TerrainDb::open(d.path);
    const Viewing setup;
    const sim::RenderGeometry& geometry = setup.geometry;
    const ig::RenderOptions& options = setup.options;
    const ig::PagedTerrain::Options& paging = setup.paging;
    for (const ig::CasterKind kind : {ig::CasterKind::Fast}) {
        SCOPED_TRACE(std::string(ig::casterName(kind)));
        auto log = std::make_shared<sim::PagingLog>();
        sim::FrameRenderer paged = sim::makePagedRenderer(db, paging, geometry, kind, options, log);
        sim::FrameRenderer whole = sim::makeCasterRenderer(d.map, geometry, kind, options);
        // 300 m/s low over the map, turning 60 degrees a second, a frame every 1/30 s.
        std::size_t exact = 0;
        ig::Pose pose;
        const int frames = 45;
        for (int i = 0; i < frames; ++i) {
            const double t = i / 30.0;
            pose.yaw = 0.4 + t * M_PI / 3.0;
            pose.position = {2000.0 + 300.0 * t * std::sin(0.4 + t * M_PI / 6.0),
                             2000.0 + 300.0 * t * std::cos(0.4 + t * M_PI / 6.0), 0.0};
            pose.position.z = d.map.surfaceHeight(pose.position.x, pose.position.y) + 120.0;
            pose.pitch = -0.25;
            const ig::RenderedFrame a = paged(pose, t, static_cast<std::uint64_t>(i));
            ASSERT_EQ(log->frames().size(), static_cast<std::size_t>(i + 1));
            const sim::PagingLog::Frame f = log->frames().back();
            EXPECT_GT(f.required, 0u);
            if (i == 0) {
                EXPECT_EQ(f.substituted, 0u) << "the first frame waits for its tiles";
            }
            if (f.substituted == 0) {
                const ig::RenderedFrame b = whole(pose, t, static_cast<std::uint64_t>(i));
                EXPECT_TRUE(sameFrame(a, b))
                    << "frame " << i << ": every tile resident, yet not the in-memory frame";
                ++exact;
            }
        }
        // The same pose again once the loaders have caught up: the full frame.
        bool caughtUp = false;
        for (int tries = 0; tries < 200 && !caughtUp; ++tries) {
            const ig::RenderedFrame a = paged(pose, 10.0 + tries, 1000);
            if (log->frames().back().substituted == 0) {
                caughtUp = true;
                EXPECT_TRUE(sameFrame(a, whole(pose, 10.0 + tries, 1000)));
            } else {
                std::this_thread::sleep_for(std::chrono::milliseconds(10));
            }
        }
        EXPECT_TRUE(caughtUp) << "the tiles never came";
        EXPECT_GT(log->frames().back().tilesRead, 0u);
        std::printf("%s: %zu of %d frames with every tile resident, %llu tiles read\n",
                    std::string(ig::casterName(kind)).c_str(), exact, frames,
                    static_cast<unsigned long long>(log->frames().back().tilesRead));
        EXPECT_GE(exact, 1u);
    }
}

// Over the placing budget the frames are drawn at lower detail: the detail the paging chose is
// the one the frame was cast with (its intrinsics), and the log's.
TEST(PagedRenderer, FramesOverThePlacingBudgetAreDrawnAtLowerDetail) {
    const Database d;
    const ig::TerrainDb db = ig::TerrainDb::open(d.path);
    Viewing setup;
    setup.paging.placeBudgetMs = 1e-6;  // no frame's writes fit
    setup.paging.minDetail = 0.5;
    auto log = std::make_shared<sim::PagingLog>();
    sim::FrameRenderer paged = sim::makePagedRenderer(db, setup.paging, setup.geometry,
                                                      ig::CasterKind::Fast, setup.options, log);
    ig::Pose pose;
    for (int i = 0; i < 12; ++i) {
        const double t = i / 30.0;
        pose.yaw = 0.4 + t * M_PI / 3.0;
        pose.position = {2000.0 + 300.0 * t, 2000.0 + 300.0 * t, 0.0};
        pose.position.z = d.map.surfaceHeight(pose.position.x, pose.position.y) + 120.0;
        pose.pitch = -0.25;
        const ig::RenderedFrame a = paged(pose, t, static_cast<std::uint64_t>(i));
        EXPECT_EQ(a.intrinsics.detail, log->frames().back().detail) << "frame " << i;
        if (i == 0) {
            EXPECT_EQ(a.intrinsics.detail, 1.0) << "the first frame waits, at full detail";
        } else {
            EXPECT_EQ(a.intrinsics.detail, 0.5) << "frame " << i;
        }
    }
}

// A renderer process is forked from the field process after the log is made, and makes its own
// paged map: its frames' paging reaches the field process's log, marked with its process and
// its own peak resident set, as a renderer thread's would.
TEST(PagedRenderer, ARendererProcessLogsWhereTheFieldProcessReads) {
    const Database d;
    const ig::TerrainDb db = ig::TerrainDb::open(d.path);
    const Viewing setup;
    auto log = std::make_shared<sim::PagingLog>();
    sim::FrameRenderer paged = sim::makePagedRenderer(db, setup.paging, setup.geometry,
                                                      ig::CasterKind::Fast, setup.options, log);
    constexpr int kFrames = 3;
    const pid_t pid = fork();
    ASSERT_GE(pid, 0);
    if (pid == 0) {
        ig::Pose pose;
        for (int i = 0; i < kFrames; ++i) {
            pose.yaw = 0.4 + 0.1 * i;
            pose.position = {2000.0 + 50.0 * i, 2000.0, 0.0};
            pose.position.z = d.map.surfaceHeight(pose.position.x, pose.position.y) + 120.0;
            pose.pitch = -0.25;
            const ig::RenderedFrame f = paged(pose, i / 30.0, static_cast<std::uint64_t>(i));
            if (f.width() == 0) _exit(2);
        }
        _exit(0);
    }
    int status = 0;
    ASSERT_EQ(waitpid(pid, &status, 0), pid);
    ASSERT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0);
    const std::vector<sim::PagingLog::Frame> frames = log->frames();
    ASSERT_EQ(frames.size(), static_cast<std::size_t>(kFrames));
    for (int i = 0; i < kFrames; ++i) {
        EXPECT_EQ(frames[i].pid, pid) << "frame " << i;
        EXPECT_EQ(frames[i].time, i / 30.0);
        EXPECT_GT(frames[i].required, 0u);
        EXPECT_GT(frames[i].peakRssBytes, 0u);
    }
    EXPECT_EQ(frames[0].substituted, 0u) << "the first frame waits for its tiles";
    EXPECT_GT(frames.back().tilesRead, 0u);
}

// The log keeps kCapacity frames and counts the rest; kMaxFailures failures, each cut to
// kFailureBytes - 1 bytes.
TEST(PagingLog, KeepsWhatFitsAndCountsTheRest) {
    sim::PagingLog log;
    EXPECT_TRUE(log.frames().empty());
    EXPECT_EQ(log.dropped(), 0u);
    for (std::size_t i = 0; i < sim::PagingLog::kCapacity + 5; ++i) {
        sim::PagingLog::Frame f;
        f.time = static_cast<double>(i);
        f.required = i;
        log.add(f);
    }
    const std::vector<sim::PagingLog::Frame> frames = log.frames();
    ASSERT_EQ(frames.size(), sim::PagingLog::kCapacity);
    EXPECT_EQ(frames.back().required, sim::PagingLog::kCapacity - 1);
    EXPECT_EQ(log.dropped(), 5u);
    const std::string longMessage(1000, 'x');
    log.addFailure("tile 3 of level 0: bad checksum");
    for (std::size_t i = 1; i < sim::PagingLog::kMaxFailures + 3; ++i)
        log.addFailure(longMessage);
    const std::vector<std::string> failures = log.failures();
    ASSERT_EQ(failures.size(), sim::PagingLog::kMaxFailures);
    EXPECT_EQ(failures[0], "tile 3 of level 0: bad checksum");
    EXPECT_EQ(failures[1], longMessage.substr(0, sim::PagingLog::kFailureBytes - 1));
}

// A scene of boxes (`json`, its box model and `drive.csv` written to a folder of the test's own)
// loaded over the map in memory and over the paged map: the grid of a paged map with nothing
// placed, the heights from a ground that places the tile under each point it is asked about.
struct SceneTwins {
    static std::string writeFiles(const std::string& name) {
        const std::string dir =
            vig_test::testTmpPath("paged_renderer", name + "_" + std::to_string(::getpid()));
        std::filesystem::create_directories(dir);
        vig_test::writeBoxVox(dir + "/box.vox", 4, 2, 3);
        std::ofstream(dir + "/drive.csv") << "t,x,y,z,yaw_deg,pitch_deg,roll_deg\n"
                                             "0,2100,2250,0,0,0,0\n"
                                             "10,2100,2450,0,0,0,0\n";
        return dir;
    }
    static ig::PagedTerrain::Options small() {
        ig::PagedTerrain::Options o;
        o.cache.budgetBytes = std::size_t{1} << 20;
        return o;
    }
    SceneTwins(const Database& d, const ig::TerrainDb& db, const std::string& name,
               const std::string& json)
        : dir(writeFiles(name)),
          whole(ig::parseScene(json, dir + "/scene.json", d.map)),
          loadMap(db, small()),
          placing(loadMap),
          paged(ig::parseScene(json, dir + "/scene.json", loadMap.map(), true,
                               ig::kMaxSceneCellVisits, &placing)) {}
    ~SceneTwins() { std::filesystem::remove_all(dir); }

    std::string dir;
    ig::Scene whole;
    ig::PagedTerrain loadMap;
    ig::PlacingGround placing;
    ig::Scene paged;
};

// A scene over the paged map: its placements stand on the database's ground (read tile by tile
// at load), the moving box on the renderer's own ground that follows the eye; frames with every
// tile resident equal the in-memory scene renderer's, object ids included.
TEST(PagedRenderer, SceneObjectsAsOverTheMapInMemory) {
    const Database d;
    const ig::TerrainDb db = ig::TerrainDb::open(d.path);
    const std::string json = R"({"cell_m": 2.5,
        "models": {"box": {"vox": "box.vox"}},
        "objects": [{"id": 1, "model": "box", "x": 1985, "y": 2200, "heading": 20, "scale": 4},
                    {"id": 2, "model": "box", "x": 2030, "y": 2300, "heading": 60, "scale": 4},
                    {"id": 5, "model": "box", "trajectory": "drive.csv", "scale": 4}],
        "scatter": [{"model": "box", "count": 30, "area": [1900, 2150, 2050, 2450], "seed": 3,
                     "first_id": 100, "scale": 2}]})";
    const SceneTwins twins(d, db, "scene", json);
    const ig::Scene& whole = twins.whole;
    const ig::Scene& paged = twins.paged;
    ASSERT_EQ(paged.staticLayer->objects().size(), whole.staticLayer->objects().size());
    for (std::size_t i = 0; i < whole.staticLayer->objects().size(); ++i) {
        const ig::PlacedObject& a = whole.staticLayer->objects()[i];
        const ig::PlacedObject& b = paged.staticLayer->objects()[i];
        EXPECT_EQ(a.id, b.id);
        EXPECT_EQ(a.z, b.z) << "object " << a.id;
    }
    const sim::SceneMotion wholeMotion(whole), pagedMotion(paged);

    const Viewing setup;
    const sim::RenderGeometry& geometry = setup.geometry;
    const ig::RenderOptions& options = setup.options;
    const ig::PagedTerrain::Options& paging = setup.paging;
    auto log = std::make_shared<sim::PagingLog>();
    sim::FrameRenderer inMemory =
        sim::makeSceneRenderer(d.map, geometry, ig::CasterKind::Fast, options, whole, wholeMotion);
    sim::FrameRenderer pagedRenderer =
        sim::makePagedRenderer(db, paging, geometry, ig::CasterKind::Fast, options, log,
                               sim::PagedScene{&paged, &pagedMotion, {}});
    std::size_t exact = 0, objectPixels = 0;
    for (int i = 0; i < 30; ++i) {
        const double t = i / 10.0;
        ig::Pose pose;
        pose.position = {2000.0, 2050.0 + 8.0 * i, 0.0};
        pose.position.z = d.map.surfaceHeight(pose.position.x, pose.position.y) + 40.0;
        pose.pitch = -0.2;
        const ig::RenderedFrame a = pagedRenderer(pose, t, static_cast<std::uint64_t>(i));
        if (log->frames().back().substituted != 0) continue;
        // The paged renderer's ground has the tiles around the eye once its thread has them.
        const ig::RenderedFrame b = inMemory(pose, t, static_cast<std::uint64_t>(i));
        ASSERT_EQ(a.objectId.size(), b.objectId.size());
        bool same = sameFrame(a, b) && a.objectId == b.objectId;
        if (!same && i < 3) continue;  // the moving box's ground may not be resident yet
        EXPECT_TRUE(same) << "frame " << i;
        ++exact;
        for (const std::uint16_t id : a.objectId)
            objectPixels += id != 0;
    }
    std::printf("scene: %zu of 30 frames equal to the in-memory frame, %zu object pixels\n", exact,
                objectPixels);
    EXPECT_GE(exact, 20u);
    EXPECT_GT(objectPixels, 1000u) << "the objects are in view";
}

// Stereo pairs over the paged map: the left eye cast, the right reprojected from it with its
// holes cast on the same paged map; both eyes' tiles placed, so a pair whose tiles were all
// resident is the in-memory stereo renderer's, both eyes to the bit; every other pair with a
// view's near and far planes (a host's View Definition), which both eyes take.
TEST(PagedRenderer, StereoPairsAsOverTheMapInMemory) {
    const Database d;
    const ig::TerrainDb db = ig::TerrainDb::open(d.path);
    const Viewing setup;
    const double separation = 300.0;  // metres: eyes far apart, the right eye sees other tiles
    auto log = std::make_shared<sim::PagingLog>();
    sim::FrameRenderer inMemory =
        sim::makeStereoRenderer(d.map, setup.geometry, separation, setup.options);
    sim::FrameRenderer paged =
        sim::makePagedRenderer(db, setup.paging, setup.geometry, ig::CasterKind::Fast,
                               setup.options, log, sim::PagedScene{}, separation);
    std::size_t exact = 0;
    for (int i = 0; i < 30; ++i) {
        const double t = i / 30.0;
        ig::Pose pose;
        pose.yaw = 0.3 + 0.5 * t;
        pose.position = {2500.0 + 200.0 * t, 2500.0 + 150.0 * t, 0.0};
        pose.position.z = d.map.surfaceHeight(pose.position.x, pose.position.y) + 60.0;
        pose.pitch = -0.2;
        sim::RenderView planes;
        if (i % 2 == 1) {
            planes.farM = 1500.0;
            planes.nearM = 100.0;
        }
        sim::setRequestView(planes);
        const ig::RenderedFrame a = paged(pose, t, static_cast<std::uint64_t>(i));
        const ig::RenderedFrame b = inMemory(pose, t, static_cast<std::uint64_t>(i));
        sim::setRequestView(sim::RenderView{});
        ASSERT_TRUE(a.right && b.right) << "a pair";
        EXPECT_EQ(a.right->nearM, i % 2 == 1 ? 100.0 : 0.0);
        if (log->frames().back().substituted != 0) continue;
        EXPECT_TRUE(sameFrame(a, b)) << "left eye, frame " << i;
        EXPECT_TRUE(sameFrame(*a.right, *b.right)) << "right eye, frame " << i;
        ++exact;
    }
    std::printf("stereo: %zu of 30 pairs with every tile resident\n", exact);
    EXPECT_GE(exact, 10u);
}

// Stereo pairs with a scene over the paged map: both eyes' terrain reprojected, then the
// objects drawn over each; a pair whose tiles were all resident is the in-memory stereo scene
// renderer's, both eyes and their object ids to the bit.
TEST(PagedRenderer, StereoPairsWithASceneAsOverTheMapInMemory) {
    const Database d;
    const ig::TerrainDb db = ig::TerrainDb::open(d.path);
    const std::string json = R"({"cell_m": 2.5,
        "models": {"box": {"vox": "box.vox"}},
        "scatter": [{"model": "box", "count": 40, "area": [1900, 2150, 2100, 2450], "seed": 3,
                     "first_id": 100, "scale": 2}]})";
    const SceneTwins twins(d, db, "stereo_scene", json);
    const sim::SceneMotion wholeMotion(twins.whole), pagedMotion(twins.paged);
    const Viewing setup;
    const double separation = 4.0;
    auto log = std::make_shared<sim::PagingLog>();
    sim::FrameRenderer inMemory = sim::makeStereoSceneRenderer(
        d.map, setup.geometry, separation, setup.options, twins.whole, wholeMotion);
    sim::FrameRenderer pagedRenderer = sim::makePagedRenderer(
        db, setup.paging, setup.geometry, ig::CasterKind::Fast, setup.options, log,
        sim::PagedScene{&twins.paged, &pagedMotion, {}}, separation);
    std::size_t exact = 0, objectPixels[2] = {0, 0};
    for (int i = 0; i < 30; ++i) {
        const double t = i / 10.0;
        ig::Pose pose;
        pose.position = {2000.0, 2050.0 + 8.0 * i, 0.0};
        pose.position.z = d.map.surfaceHeight(pose.position.x, pose.position.y) + 40.0;
        pose.pitch = -0.2;
        const ig::RenderedFrame a = pagedRenderer(pose, t, static_cast<std::uint64_t>(i));
        ASSERT_TRUE(a.right) << "a pair";
        if (log->frames().back().substituted != 0) continue;
        const ig::RenderedFrame b = inMemory(pose, t, static_cast<std::uint64_t>(i));
        ASSERT_TRUE(b.right);
        EXPECT_TRUE(sameFrame(a, b) && a.objectId == b.objectId) << "left eye, frame " << i;
        EXPECT_TRUE(sameFrame(*a.right, *b.right) && a.right->objectId == b.right->objectId)
            << "right eye, frame " << i;
        ++exact;
        for (const std::uint16_t id : a.objectId)
            objectPixels[0] += id != 0;
        for (const std::uint16_t id : a.right->objectId)
            objectPixels[1] += id != 0;
    }
    std::printf(
        "stereo scene: %zu of 30 pairs with every tile resident, %zu and %zu object "
        "pixels\n",
        exact, objectPixels[0], objectPixels[1]);
    EXPECT_GE(exact, 10u);
    EXPECT_GT(objectPixels[0], 500u) << "the objects are in view";
    EXPECT_GT(objectPixels[1], 500u) << "the objects are in the right eye too";
}

}  // namespace
