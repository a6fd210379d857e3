// The truth's fast path against its slow twin: the table walk against the model walk ray for
// ray, and whole lines against TruthComputer's reference (every object, every pixel of the box's
// rectangle, the model asked at every voxel).
#include "sim/truth.hpp"

#include "ig/scene.hpp"
#include "ig/vox.hpp"
#include "sim/scene_motion.hpp"

#include <gtest/gtest.h>
#include <glm/geometric.hpp>
#include "common/box_vox.hpp"

#include <unistd.h>
#include <cmath>
#include <filesystem>
#include <random>
#include <string>
#include <vector>

namespace {

std::string tmpDir() {
    const std::string dir = std::string(VIG_TEST_TMP) + "/truth-fast-" + std::to_string(::getpid());
    std::filesystem::create_directories(dir);
    return dir;
}

// A flat map 100 m high with a ridge along y = 300 m (objects behind it are hidden).
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

// Two models: a sparse random one (a third of its voxels filled, some of them transparent
// cavities of opacity 0, its filled box smaller than its grid) and a solid box.
void writeModels(const std::string& dir) {
    ig::VoxFile vox;
    vox.palette = ig::defaultVoxPalette();
    vox.palette[9].a = 0;  // a cavity
    std::mt19937 rng(5);
    ig::VoxModel sparse(12, 10, 14);
    for (int z = 1; z < 13; ++z)
        for (int y = 2; y < 10; ++y)
            for (int x = 0; x < 11; ++x)
                if (rng() % 3 == 0) sparse.set(x, y, z, rng() % 5 == 0 ? 9 : 7);
    vox.models.push_back(sparse);
    ig::writeVox(dir + "/sparse.vox", vox);
    vig_test::writeBoxVox(dir + "/box.vox", 4, 4, 6);
}

struct Scene {
    ig::TerrainMap map = ridgeMap();
    ig::Scene scene;
    std::unique_ptr<sim::SceneMotion> motion;
    std::unique_ptr<sim::TruthScene> truth;

    Scene() {
        const std::string dir = tmpDir();
        writeModels(dir);
        std::string objects;
        int id = 0;
        for (int iy = 0; iy < 14; ++iy) {
            for (int ix = 0; ix < 20; ++ix) {
                ++id;
                if (!objects.empty()) objects += ',';
                objects += "{\"id\": " + std::to_string(id) + ", \"model\": \"" +
                           (id % 3 ? "sparse" : "box") +
                           "\", \"x\": " + std::to_string(60 + 25 * ix + (id * 7) % 11) +
                           ", \"y\": " + std::to_string(90 + 22 * iy + (id * 5) % 9) +
                           ", \"heading\": " + std::to_string((37 * id) % 360) +
                           ", \"scale\": " + (id % 4 ? "1.5" : "0.7") + "}";
            }
        }
        scene = ig::parseScene(
            "{\"cell_m\": 2, \"models\": {\"sparse\": {\"vox\": \"sparse.vox\"}, "
            "\"box\": {\"vox\": \"box.vox\"}}, \"objects\": [" +
                objects + "]}",
            dir + "/scene.json", map);
        motion = std::make_unique<sim::SceneMotion>(scene);
        truth = std::make_unique<sim::TruthScene>(scene, *motion, map);
    }
};

// Ray for ray, the table walk answers as the model walk: rays from all around each placed
// sparse model toward random points of its box (and beside it), and rays along the axes through
// voxel faces and edges exactly (directions with zero components, origins on the grid).
TEST(TruthFast, WalkAnswersAsTheModelWalk) {
    const Scene s;
    std::mt19937 rng(11);
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    std::uint64_t rays = 0, hits = 0;
    int checked = 0;
    for (const sim::TruthObject& o : s.truth->staticObjects()) {
        if (o.id % 3 == 0) continue;
        if (checked == 12) break;
        ++checked;
        ASSERT_NE(o.solid, nullptr);
        const auto corners = sim::objectCorners(o);
        glm::dvec3 centre{0.0};
        for (const glm::dvec3& c : corners)
            centre += c * 0.125;
        for (int k = 0; k < 4000; ++k) {
            const glm::dvec3 from =
                centre + 25.0 * glm::normalize(glm::dvec3{u(rng), u(rng), u(rng)});
            const glm::dvec3 to = corners[static_cast<std::size_t>(k % 8)] * (0.5 + 0.5 * u(rng)) +
                                  centre * (0.5 - 0.5 * u(rng)) + glm::dvec3{u(rng), u(rng), 0.0};
            const glm::dvec3 dir = glm::normalize(to - from);
            const bool slow = sim::rayMeetsObject(o, from, dir);
            ASSERT_EQ(sim::rayMeetsObjectFast(o, from, dir), slow) << "object " << o.id;
            ++rays;
            hits += slow ? 1 : 0;
        }
        // Along the axes, from a grid of origins in model voxels' units (faces hit exactly).
        sim::TruthObject aligned = o;
        aligned.heading = 0.0;
        for (int i = -2; i <= 28; ++i) {
            for (int j = -2; j <= 24; ++j) {
                const double x = o.x + o.scale * (0.5 * i - 6.0),
                             y = o.y + o.scale * (0.5 * j - 5.0);
                for (const glm::dvec3 dir : {glm::dvec3{0, 0, -1}, glm::dvec3{0, 0, 1},
                                             glm::dvec3{1, 0, 0}, glm::dvec3{0, -1, 0}}) {
                    const glm::dvec3 from = dir.z != 0.0
                                                ? glm::dvec3{x, y, o.z + (dir.z < 0 ? 40.0 : -1.0)}
                                                : glm::dvec3{x - 30.0 * dir.x, y - 30.0 * dir.y,
                                                             o.z + o.scale * 0.5 * (i % 28)};
                    const bool slow = sim::rayMeetsObject(aligned, from, dir);
                    ASSERT_EQ(sim::rayMeetsObjectFast(aligned, from, dir), slow);
                    ++rays;
                    hits += slow ? 1 : 0;
                }
            }
        }
    }
    EXPECT_EQ(checked, 12);
    EXPECT_GT(hits, rays / 10);
    EXPECT_LT(hits, rays - rays / 10);
}

// Whole lines: the fast path (one and two workers) gives the reference's line, byte for byte,
// over views that list hundreds of objects, hidden ones (no ids), a near object whose box holds
// more than 4096 pixels (sampled every s-th pixel), boxes partly behind the eye, roll, and a
// view straight down.
TEST(TruthFast, SameLinesAsTheReference) {
    const Scene s;
    const int width = 160, height = 120, lines = height / 2;
    const sim::TruthCamera camera{ig::Intrinsics::fromFov(width, height, 1.2), width, height};
    std::vector<ig::Pose> poses(5);
    poses[0].position = {310.0, 20.0, 160.0};
    poses[0].pitch = -0.25;
    poses[0].roll = 0.05;
    poses[1].position = {200.0, 60.0, 110.0};  // low, looking along the rows: many hidden
    poses[1].yaw = 0.3;
    poses[1].pitch = -0.05;
    poses[2].position = {160.0, 160.0, 104.0};  // among the objects: near boxes, some behind
    poses[2].yaw = 1.2;
    poses[2].pitch = -0.1;
    poses[2].roll = -0.2;
    poses[3].position = {300.0, 200.0, 400.0};  // straight down
    poses[3].pitch = -std::acos(-1.0) / 2;
    poses[4].position = {330.0, 170.0, 103.0};  // right beside an object: a huge box
    poses[4].yaw = 3.0;
    std::vector<std::uint16_t> striped(static_cast<std::size_t>(width) * lines),
        empty(striped.size());
    for (std::size_t k = 0; k < striped.size(); ++k)
        striped[k] = static_cast<std::uint16_t>((k / 3) % 320);
    sim::TruthComputer fast(1), fastTwo(2), reference(1, true);
    sim::FieldTruth a, b, c;
    std::uint64_t listed = 0, sampled = 0, hidden = 0;
    for (std::size_t p = 0; p < poses.size(); ++p) {
        for (const int firstLine : {0, 1}) {
            for (const std::vector<std::uint16_t>* ids : {&striped, &empty}) {
                fast.compute(*s.truth, camera, ids->data(), width, lines, firstLine, poses[p], 0.5,
                             3, a);
                fastTwo.compute(*s.truth, camera, ids->data(), width, lines, firstLine, poses[p],
                                0.5, 3, b);
                reference.compute(*s.truth, camera, ids->data(), width, lines, firstLine, poses[p],
                                  0.5, 3, c);
                ASSERT_EQ(sim::truthLine(a), sim::truthLine(c)) << "pose " << p;
                ASSERT_EQ(sim::truthLine(b), sim::truthLine(c)) << "pose " << p;
                listed += a.objects.size();
                for (const sim::ObjectTruth& o : a.objects) {
                    hidden += o.visiblePx == 0 && o.unoccludedPx > 0 ? 1 : 0;
                    sampled += o.unoccludedPx > 4096 ? 1 : 0;
                }
            }
        }
    }
    EXPECT_GT(listed, 1000u);
    EXPECT_GT(hidden, 200u);
    EXPECT_GT(sampled, 0u);
}

}  // namespace
