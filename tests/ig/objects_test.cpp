#include "ig/caster.hpp"
#include "ig/error.hpp"
#include "ig/object_trace.hpp"
#include "ig/pyramid.hpp"
#include "ig/scene.hpp"
#include "ig/sticks.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <string>
#include <vector>

#include <unistd.h>

namespace {

using namespace ig;

constexpr Rgb8 kGround{90, 140, 60};

// A flat 65 x 65 map at 10 m, 100 m high, one colour; `ridge` raises the row y = 300 m to 400 m.
TerrainMap flatMap(bool ridge = false) {
    TerrainMap map(65, 65, 10.0, 10.0, 0.1, 0.0);
    for (int iy = 0; iy < 65; ++iy)
        for (int ix = 0; ix < 65; ++ix) {
            map.setRaw(ix, iy, ridge && iy == 30 ? 4000 : 1000);
            map.setColor(ix, iy, kGround);
        }
    map.updateRange();
    return map;
}

// A model of sx x sy x sz voxels, filled by `fill(x, y, z)` -> palette index (0 empty).
template <typename F>
ObjectModel model(int sx, int sy, int sz, F fill) {
    ObjectModel m;
    m.name = "test";
    m.grid = VoxModel(sx, sy, sz);
    m.palette = defaultVoxPalette();
    for (int z = 0; z < sz; ++z)
        for (int y = 0; y < sy; ++y)
            for (int x = 0; x < sx; ++x)
                m.grid.set(x, y, z, static_cast<std::uint8_t>(fill(x, y, z)));
    return m;
}

RenderedFrame render(const TerrainMap& map, const ObjectLayer* layer, const Pose& pose, int w = 96,
                     int h = 72, double fovDeg = 40.0) {
    RenderOptions options;
    if (layer != nullptr) options.objects.push_back(layer);
    const auto caster = makeCaster(CasterKind::Reference, map, options);
    return renderFrame(*caster, map, pose, Intrinsics::fromFov(w, h, degToRad(fovDeg)));
}

Pose nadir(double x, double y, double z) {
    Pose p;
    p.position = {x, y, z};
    p.pitch = -std::numbers::pi / 2;
    return p;
}

std::uint64_t pixelsOf(const RenderedFrame& f, std::uint16_t id) {
    std::uint64_t n = 0;
    for (const std::uint16_t v : f.objectId)
        n += v == id;
    return n;
}

TEST(StickTable, RunsAreClassifiedAndSplitByEmptySpace) {
    StickTable table;
    const Rgba8 red{200, 0, 0, 255}, green{0, 200, 0, 255}, glass{0, 0, 200, 128}, hole{0, 0, 0, 0};
    // z 0-1 uniform red, z 2 empty, z 3-4 textured, z 5 empty, z 6-8 complex (glass, cavity, red).
    const std::vector<Rgba8> c = {red, red, {}, red, green, {}, glass, hole, red};
    const std::vector<std::uint8_t> present = {1, 1, 0, 1, 1, 0, 1, 1, 1};
    const std::uint32_t s = table.addColumn(c, present, 0.5f);
    ASSERT_EQ(table.runCount(s), 3);
    EXPECT_EQ(table.voxelHeight(s), 0.5f);
    const StickRun a = table.run(s, 0), b = table.run(s, 1), d = table.run(s, 2);
    EXPECT_EQ(a.type, StickType::Uniform);
    EXPECT_EQ(a.first, 0);
    EXPECT_EQ(a.count, 2);
    EXPECT_EQ(a.voxel(1), red);
    EXPECT_EQ(b.type, StickType::Textured);
    EXPECT_EQ(b.first, 3);
    EXPECT_EQ(b.voxel(1), green);
    EXPECT_EQ(d.type, StickType::Complex);
    EXPECT_EQ(d.first, 6);
    EXPECT_EQ(d.count, 3);
    EXPECT_EQ(d.voxel(0), glass);
    EXPECT_EQ(d.voxel(1), hole);
    EXPECT_FLOAT_EQ(table.top(s), 4.5f);
    EXPECT_FLOAT_EQ(table.bottom(s), 0.0f);
    // Words: 4 header + (1 + 1) + (1 + 2) + (1 + 3).
    EXPECT_EQ(table.words(), 13u);
    // A floating run (a deck): its bottom is above the base.
    const std::uint32_t deck =
        table.addColumn(std::vector<Rgba8>{{}, {}, red}, std::vector<std::uint8_t>{0, 0, 1}, 1.0f);
    EXPECT_FLOAT_EQ(table.bottom(deck), 2.0f);
    EXPECT_EQ(table.addColumn(std::vector<Rgba8>{{}}, std::vector<std::uint8_t>{0}, 1.0f),
              StickTable::kNone);
}

TEST(StickTable, IdenticalSticksShareStorage) {
    const TerrainMap map = flatMap();
    // A "tree": trunk column and a canopy, 6 x 6 x 10.
    const ObjectModel tree = model(6, 6, 10, [](int x, int y, int z) {
        if (z < 4) return (x == 2 || x == 3) && (y == 2 || y == 3) ? 100 : 0;
        return 200;
    });
    ObjectLayer shared(map, 1.0), unshared(map, 1.0, false);
    for (int i = 0; i < 50; ++i) {
        const Placement p{static_cast<std::uint16_t>(i + 1),
                          40.0 + 10.0 * (i % 10),
                          40.0 + 10.0 * (i / 10),
                          100.0,
                          0.3 * i,
                          1.0};
        shared.place(tree, p);
        unshared.place(tree, p);
    }
    shared.finish();
    unshared.finish();
    EXPECT_EQ(shared.cellEntries(), unshared.cellEntries());
    // Shared: the trunk column and the canopy-only column, once each.
    EXPECT_EQ(shared.table().lists(), 2u);
    EXPECT_GT(unshared.table().bytes(), 10 * shared.table().bytes());
}

TEST(ObjectLayer, HeadingTurnsTheModelsYAxis) {
    const TerrainMap map = flatMap();
    // 1 x 5 x 1: a bar along the model's y axis.
    const ObjectModel bar = model(1, 5, 1, [](int, int, int) { return 1; });
    for (const double headingDeg : {0.0, 90.0}) {
        ObjectLayer layer(map, 1.0);
        layer.place(bar,
                    Placement{1, 200.5, 200.5, 100.0, headingDeg * std::numbers::pi / 180, 1.0});
        layer.finish();
        int alongX = 0, alongY = 0;
        for (int d = -2; d <= 2; ++d) {
            alongX += !layer.cellsAt(200 + d, 200).empty();
            alongY += !layer.cellsAt(200, 200 + d).empty();
        }
        if (headingDeg == 0.0) {
            EXPECT_EQ(alongY, 5);
            EXPECT_EQ(alongX, 1);
        } else {
            EXPECT_EQ(alongX, 5);
            EXPECT_EQ(alongY, 1);
        }
        EXPECT_EQ(layer.objects().at(0).cells, 5);
    }
}

TEST(ObjectLayer, PyramidBoundsStickTopsOnlyWithObjects) {
    TerrainMap map = flatMap();
    const TerrainPyramid before(map);
    const ObjectModel mast = model(1, 1, 50, [](int, int, int) { return 1; });
    ObjectLayer layer(map, 10.0);
    layer.place(mast, Placement{1, 305.0, 305.0, 100.0, 0.0, 2.0});  // 100 m tall
    layer.finish();
    ObjectLayer none(map, 10.0);
    none.finish();
    includeStickTops(map, none);
    EXPECT_EQ(map.maxHeight(), 100.0);
    includeStickTops(map, layer);
    EXPECT_GE(map.cellMaxRaw(30, 30) * map.heightScale(), 200.0);
    const TerrainPyramid after(map);
    for (int j = 1; j < after.nodeLevelCount(); ++j) {
        EXPECT_GE(after.nodeMaxRaw(j, 30 >> j, 30 >> j) * 0.1, 200.0) << j;
        EXPECT_LT(before.nodeMaxRaw(j, 30 >> j, 30 >> j) * 0.1, 200.0) << j;
    }
}

TEST(ObjectCaster, OpaqueBoxSeenFromAboveHasItsColourAndId) {
    const TerrainMap map = flatMap();
    const ObjectModel box = model(4, 4, 4, [](int, int, int) { return 216; });  // red ramp ee
    ObjectLayer layer(map, 1.0);
    layer.place(box, Placement{9, 320.0, 320.0, 100.0, 0.0, 5.0});  // 20 m cube
    layer.finish();
    const RenderedFrame f = render(map, &layer, nadir(320.0, 320.0, 300.0));
    const std::size_t centre = 36 * 96 + 48;
    EXPECT_EQ(f.objectId[centre], 9);
    EXPECT_EQ(f.color[centre], (Rgb8{0xee, 0, 0}));
    EXPECT_NEAR(f.depth[centre], 180.0, 0.01);  // top at 120 m, half a pixel off the axis
    // The box's projected footprint: 20 m at 180 m with focal 96 / (2 tan 20deg).
    const double focal = 48.0 / std::tan(degToRad(20.0));
    const double side = 20.0 / 180.0 * focal;
    EXPECT_NEAR(static_cast<double>(pixelsOf(f, 9)), side * side, 4 * side);
    const auto stats = objectPixelStats(f);
    ASSERT_EQ(stats.size(), 1u);
    EXPECT_EQ(stats[0].pixels, pixelsOf(f, 9));
}

TEST(ObjectCaster, HalfOpaqueVoxelBlendsWithWhatIsBehind) {
    const TerrainMap map = flatMap();
    ObjectModel glass = model(1, 1, 1, [](int, int, int) { return 1; });
    const Rgba8 c{200, 40, 240, 128};
    glass.palette[1] = c;
    ObjectLayer layer(map, 1.0);
    layer.place(glass, Placement{5, 320.0, 320.0, 100.0, 0.0, 30.0});
    layer.finish();
    const RenderedFrame f = render(map, &layer, nadir(320.0, 320.0, 300.0));
    const std::size_t centre = 36 * 96 + 48;
    const float a = 128.0f / 255.0f;
    auto blend = [&](int voxel, int ground) {
        return static_cast<int>(std::lround(a * voxel + (1.0f - a) * ground));
    };
    EXPECT_EQ(f.objectId[centre], 5);
    EXPECT_NEAR(f.color[centre].r, blend(c.r, kGround.r), 1);
    EXPECT_NEAR(f.color[centre].g, blend(c.g, kGround.g), 1);
    EXPECT_NEAR(f.color[centre].b, blend(c.b, kGround.b), 1);
    EXPECT_NEAR(f.depth[centre], 170.0, 0.01);
}

TEST(ObjectCaster, CavityShowsTheSceneWithoutTheObject) {
    const TerrainMap map = flatMap();
    // A 5 x 1 x 5 wall with a 3 x 3 window of fully transparent voxels in its middle.
    ObjectModel wall = model(
        5, 1, 5, [](int x, int, int z) { return x >= 1 && x <= 3 && z >= 1 && z <= 3 ? 2 : 1; });
    wall.palette[1] = Rgba8{230, 230, 230, 255};
    wall.palette[2] = Rgba8{255, 0, 0, 0};
    ObjectLayer layer(map, 1.0);
    layer.place(wall, Placement{3, 320.0, 320.0, 100.0, 0.0, 4.0});  // 20 x 4 x 20 m
    layer.finish();
    // Looking north at the wall from 60 m south of it, slightly down.
    Pose pose;
    pose.position = {320.0, 260.0, 112.0};
    pose.pitch = degToRad(-5.0);
    const RenderedFrame with = render(map, &layer, pose);
    const RenderedFrame without = render(map, nullptr, pose);
    ASSERT_TRUE(without.objectId.empty());
    const auto stats = objectPixelStats(with);
    ASSERT_EQ(stats.size(), 1u);
    std::uint64_t throughWindow = 0;
    for (std::size_t i = 0; i < with.color.size(); ++i) {
        if (with.objectId[i] != 0) continue;
        // Every pixel no object covers is the terrain-only image's, bit for bit.
        ASSERT_EQ(with.color[i], without.color[i]) << i;
        ASSERT_EQ(with.depth[i], without.depth[i]) << i;
        const int x = static_cast<int>(i % 96), y = static_cast<int>(i / 96);
        throughWindow += x > stats[0].x0 && x < stats[0].x1 && y > stats[0].y0 && y < stats[0].y1;
    }
    // The window is a hole through the wall's box.
    EXPECT_GT(throughWindow, stats[0].pixels / 4);
}

TEST(ObjectCaster, ObjectBehindARidgeIsHidden) {
    const ObjectModel box = model(2, 2, 2, [](int, int, int) { return 50; });
    for (const bool ridge : {false, true}) {
        const TerrainMap map = flatMap(ridge);
        ObjectLayer layer(map, 1.0);
        layer.place(box, Placement{4, 320.0, 400.0, 100.0, 0.0, 5.0});  // 10 m cube behind y = 300
        layer.finish();
        Pose pose;
        pose.position = {320.0, 150.0, 150.0};
        pose.pitch = degToRad(-10.0);
        const RenderedFrame f = render(map, &layer, pose);
        if (ridge) {
            EXPECT_EQ(pixelsOf(f, 4), 0u);
            EXPECT_TRUE(objectPixelStats(f).empty());
        } else {
            EXPECT_GT(pixelsOf(f, 4), 20u);
        }
    }
}

TEST(ObjectCaster, VisiblePixelCountsEqualTheIdImage) {
    const TerrainMap map = flatMap();
    const ObjectModel box =
        model(3, 3, 6, [](int x, int y, int z) { return 1 + (x + y + z) % 200; });
    ObjectLayer layer(map, 2.0);
    for (int i = 0; i < 12; ++i) {
        layer.place(box, Placement{static_cast<std::uint16_t>(100 + i), 250.0 + 12.0 * (i % 4),
                                   300.0 + 15.0 * (i / 4), 100.0, 0.4 * i, 2.0});
    }
    layer.finish();
    Pose pose;
    pose.position = {280.0, 240.0, 160.0};
    pose.pitch = degToRad(-35.0);
    const RenderedFrame f = render(map, &layer, pose);
    std::uint64_t total = 0;
    for (const ObjectPixels& o : objectPixelStats(f)) {
        EXPECT_EQ(o.pixels, pixelsOf(f, o.id));
        for (int y = 0; y < f.height(); ++y)
            for (int x = 0; x < f.width(); ++x)
                if (f.objectId[static_cast<std::size_t>(y) * 96 + x] == o.id) {
                    EXPECT_TRUE(x >= o.x0 && x <= o.x1 && y >= o.y0 && y <= o.y1);
                }
        total += o.pixels;
    }
    EXPECT_GT(objectPixelStats(f).size(), 6u);
    EXPECT_EQ(total, f.objectId.size() - pixelsOf(f, 0));
    // The naive caster draws the same objects over its terrain.
    RenderOptions options;
    options.objects.push_back(&layer);
    const auto naive = makeCaster(CasterKind::Naive, map, options);
    const RenderedFrame g =
        renderFrame(*naive, map, pose, Intrinsics::fromFov(96, 72, degToRad(40.0)));
    EXPECT_EQ(g.objectId, f.objectId);
}

// ---- Scene files
// ---------------------------------------------------------------------------------

std::string tmpDir() {
    const std::filesystem::path dir =
        std::filesystem::path(VIG_TEST_TMP) / ("scene-" + std::to_string(::getpid()));
    std::filesystem::create_directories(dir);
    return dir.string();
}

std::string sceneError(const std::string& json, const TerrainMap& map) {
    try {
        parseScene(json, tmpDir() + "/s.json", map);
    } catch (const InputError& e) {
        return e.what();
    }
    return "";
}

TEST(Scene, PlacesObjectsScatterAndMovingOnes) {
    const TerrainMap map = flatMap();
    VoxFile vox;
    vox.palette = defaultVoxPalette();
    vox.models.push_back(VoxModel(2, 2, 3));
    for (auto& v : vox.models[0].voxels)
        v = 7;
    writeVox(tmpDir() + "/tree.vox", vox);
    const Scene s = parseScene(R"({"cell_m": 2,
        "models": {"tree": {"vox": "tree.vox"}},
        "objects": [{"id": 7, "model": "tree", "x": 100, "y": 120, "heading": 30, "scale": 2},
                    {"id": 8, "model": "tree", "trajectory": "road.csv", "scale": 1}],
        "scatter": [{"model": "tree", "count": 40, "area": [200, 200, 500, 500], "seed": 3,
                     "max_slope_deg": 30, "scale": 2}]})",
                               tmpDir() + "/s.json", map);
    EXPECT_EQ(s.staticLayer->subdivision(), 5);
    ASSERT_EQ(s.staticLayer->objects().size(), 41u);
    EXPECT_EQ(s.staticLayer->objects()[0].id, 7);
    EXPECT_EQ(s.staticLayer->objects()[1].id, 9);  // scattered ids follow the highest given
    EXPECT_EQ(s.staticLayer->objects()[40].id, 48);
    for (const PlacedObject& o : s.staticLayer->objects()) {
        EXPECT_EQ(o.z, 100.0);  // on the ground
        EXPECT_GE(o.x, o.id == 7 ? 100.0 : 200.0);
    }
    ASSERT_EQ(s.moving.size(), 1u);
    EXPECT_EQ(s.moving[0].trajectory, tmpDir() + "/road.csv");
    const Placement where{0, 300.0, 300.0, 0.0, 0.0, 1.0};
    const ObjectLayer stamp = s.stampMoving(std::span(&where, 1));
    ASSERT_EQ(stamp.objects().size(), 1u);
    EXPECT_EQ(stamp.objects()[0].id, 8);
    EXPECT_EQ(stamp.objects()[0].z, 100.0);
}

TEST(Scene, EveryBadEntryIsNamed) {
    const TerrainMap map = flatMap();
    VoxFile vox;
    vox.palette = defaultVoxPalette();
    vox.models.push_back(VoxModel(1, 1, 1));
    vox.models[0].voxels[0] = 1;
    writeVox(tmpDir() + "/one.vox", vox);
    const std::string m = R"("models": {"one": {"vox": "one.vox"}})";
    auto has = [&](const std::string& json, const std::string& what) {
        const std::string e = sceneError(json, map);
        EXPECT_NE(e.find(what), std::string::npos) << "got: " << e;
    };
    has("{", "s.json: not valid JSON");
    has("{" + m + R"(, "objects": [{"id": 1, "model": "two", "x": 1, "y": 1}]})",
        "objects[0].model: unknown model 'two'");
    has("{" + m + R"(, "objects": [{"id": 1, "model": "one", "x": 1, "y": 1, "scale": -2}]})",
        "objects[0].scale: -2");
    has("{" + m + R"(, "objects": [{"id": 1, "model": "one", "x": 1e9, "y": 1}]})",
        "objects[0]: (1e+09, 1) is off the map");
    has("{" + m + R"(, "objects": [{"id": 1, "model": "one", "x": 1, "y": 1},
                                   {"id": 1, "model": "one", "x": 2, "y": 1}]})",
        "objects[1].id: id 1 is used twice");
    has("{" + m + R"(, "objects": [{"id": 0, "model": "one", "x": 1, "y": 1}]})",
        "objects[0].id: 0: ids are whole numbers 1..65535");
    has("{" + m + R"(, "objects": [{"id": 2, "model": "one", "x": "a", "y": 1}]})",
        "objects[0].x: expected a number");
    has("{" + m + R"(, "objects": [{"id": 2, "model": "one", "x": 1, "y": 1, "colour": 1}]})",
        "objects[0]: unknown key 'colour'");
    has(R"({"models": {"bad": {"vox": "missing.vox"}}})", "models.bad: ");
    has(R"({"models": {"bad": {"vox": "missing.vox"}}})", "missing.vox");
    has("{" + m + R"(, "scatter": [{"model": "one", "count": 5, "area": [0, 0, -1, 10]}]})",
        "scatter[0].area: expected x0 < x1");
    has("{" + m +
            R"(, "scatter": [{"model": "one", "count": 5, "area": [0, 0, 10, 10], "max_slope_deg": 0}]})",
        "scatter[0].max_slope_deg");
    has(R"({"cell_m": 50, "models": {}})", "cell_m: 50");
    // A placement too costly to resample: a 1000 m-per-voxel copy over 1 cm cells.
    has(R"({"cell_m": 0.01, )" + m +
            R"(, "objects": [{"id": 1, "model": "one", "x": 1, "y": 1, "scale": 1000}]})",
        "objects[0]: the placements so far sweep");
    try {
        parseScene(
            "{" + m +
                R"(, "scatter": [{"model": "one", "count": 50, "area": [0, 0, 600, 600], "scale": 100}]})",
            tmpDir() + "/s.json", map, true, 10000);
        ADD_FAILURE() << "no budget error";
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find("scatter[0]: the placements so far sweep"),
                  std::string::npos)
            << e.what();
    }
}

}  // namespace
