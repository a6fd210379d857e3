// Voxel objects drawn by the fast casters' footprint pass, against the per-pixel trace on the
// same terrain (bit for bit) and against the reference caster (over pose sweeps on Puget Sound
// and Goleta, with objects placed where each pose looks).
#include "ig/object_pass.hpp"
#include "ig/caster.hpp"
#include "ig/image_compare.hpp"
#include "ig/object_trace.hpp"
#include "ig/pose_sweep.hpp"
#include "ig/sticks.hpp"
#include "ig/terrain_io.hpp"
#include "ig/vox.hpp"

#include "common/objects_in_view.hpp"

#include <gtest/gtest.h>
#include <glm/geometric.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>
#include <numbers>
#include <string>
#include <vector>

namespace {

using namespace ig;

const TerrainMap& puget() {
    static const TerrainMap map = loadPugetSound();
    return map;
}
const TerrainMap& goleta() {
    static const TerrainMap map = loadGoleta();
    return map;
}

using vig_test::objectsInView;
using vig_test::shippedModels;

RenderedFrame renderWith(const TerrainMap& map, RenderOptions options, CasterKind kind,
                         const ObjectLayer* layer, const Pose& pose, const Intrinsics& in) {
    if (layer != nullptr) options.objects = {layer};
    const auto caster = makeCaster(kind, map, options);
    return renderFrame(*caster, map, pose, in);
}

// How a frame's objects compare with the reference's.
struct ObjectAgreement {
    std::size_t refPixels = 0;           // the reference's object pixels
    std::size_t idDiffer = 0;            // pixels whose id differs
    std::size_t idDifferSameGround = 0;  // ... where the terrain-only frames agree (depth 1e-4)
    std::size_t depthOff = 0;            // same non-zero id, depth off by more than 1 %
    double maePct = 0.0;                 // mean colour error over the union of object pixels
    std::size_t pixels = 0;              // that union
};

ObjectAgreement compareObjects(const RenderedFrame& got, const RenderedFrame& ref,
                               const RenderedFrame& gotTerrain, const RenderedFrame& refTerrain) {
    ObjectAgreement a;
    double err = 0.0;
    std::size_t n = 0;
    for (std::size_t i = 0; i < ref.objectId.size(); ++i) {
        const std::uint16_t g = got.objectId[i], r = ref.objectId[i];
        a.refPixels += r != 0;
        if (g != r) {
            ++a.idDiffer;
            const float dg = gotTerrain.depth[i], dr = refTerrain.depth[i];
            const bool same = dg == dr || std::abs(dg - dr) <= 1e-4f * dr;
            a.idDifferSameGround += same;
        } else if (r != 0 && !(std::abs(got.depth[i] - ref.depth[i]) <= 0.01f * ref.depth[i])) {
            ++a.depthOff;
        }
        if (g == 0 && r == 0) continue;
        const Rgb8 p = got.color[i], q = ref.color[i];
        err += std::abs(p.r - q.r) + std::abs(p.g - q.g) + std::abs(p.b - q.b);
        ++n;
    }
    a.pixels = n;
    a.maePct = n ? 100.0 * err / (3.0 * 255.0 * static_cast<double>(n)) : 0.0;
    return a;
}

std::vector<CasterKernel> kernelsOnThisProcessor() {
    std::vector<CasterKernel> k;
    for (const CasterKernel c : {CasterKernel::Scalar, CasterKernel::Avx2, CasterKernel::Avx512})
        if (casterKernelMissing(c).empty()) k.push_back(c);
    return k;
}

// Pixels where two frames differ in id, colour or depth (to the bit).
struct FrameDifference {
    std::size_t id = 0, color = 0, depth = 0;
};
FrameDifference differences(const RenderedFrame& a, const RenderedFrame& b) {
    FrameDifference d;
    for (std::size_t i = 0; i < a.color.size(); ++i) {
        d.id += a.objectId[i] != b.objectId[i];
        d.color += !(a.color[i] == b.color[i]);
        d.depth += a.depth[i] != b.depth[i];
    }
    return d;
}

// The pass (boxes walked or splatted as it chooses, every box splatted, every box walked)
// against the per-pixel trace, all over the same fast terrain image: the same ids, colours and
// depths to the bit on every pixel.
void expectPassEqualsPerPixelTrace(const TerrainMap& map, int poses) {
    const Intrinsics in = Intrinsics::fromFov(128, 96, degToRad(60.0));
    std::size_t objectPixels = 0, splattedByChoice = 0, walkedByChoice = 0;
    int k = 0;
    for (const Pose& pose : sweepPoses(map, poses)) {
        const auto layer = objectsInView(map, pose, in);
        ++k;
        if (!layer) continue;
        const RenderedFrame terrain = renderWith(map, {}, CasterKind::Fast, nullptr, pose, in);
        const Camera camera(pose, in);
        const std::vector<const ObjectLayer*> layers = {layer.get()};
        RenderedFrame twin = terrain;
        twin.objectId.assign(terrain.color.size(), 0);
        drawObjectsPerPixel(layers, SkyModel{}, camera, twin, 0, in.width);
        const double chosen = ObjectPassOptions{}.splatPixelsPerColumn;
        for (const double perColumn : {chosen, 0.0, static_cast<double>(INFINITY)}) {
            RenderedFrame pass = terrain;
            pass.objectId.assign(terrain.color.size(), 0);
            ObjectPassStats stats;
            drawObjects(layers, SkyModel{}, camera, pass, 0, in.width, false,
                        ObjectPassOptions{perColumn, &stats});
            const FrameDifference d = differences(pass, twin);
            EXPECT_EQ(d.id, 0u) << "pose " << k - 1 << ", splat at " << perColumn;
            EXPECT_EQ(d.color, 0u) << "pose " << k - 1 << ", splat at " << perColumn;
            EXPECT_EQ(d.depth, 0u) << "pose " << k - 1 << ", splat at " << perColumn;
            if (perColumn == 0.0) {
                EXPECT_EQ(stats.splatted, stats.boxes);
            } else if (std::isinf(perColumn)) {
                EXPECT_EQ(stats.splatted, 0u);
            } else {
                splattedByChoice += stats.splatted;
                walkedByChoice += stats.boxes - stats.splatted;
            }
        }
        for (std::size_t i = 0; i < twin.color.size(); ++i)
            objectPixels += twin.objectId[i] != 0;
    }
    EXPECT_GT(objectPixels, static_cast<std::size_t>(poses) * 200u);
    // The sweep's objects are about 30 pixels tall at the nearest ground: both kinds are chosen.
    EXPECT_GT(splattedByChoice, 0u);
    EXPECT_GT(walkedByChoice, 0u);
}

TEST(ObjectPass, EqualsThePerPixelTraceOverPugetSoundSweep) {
    expectPassEqualsPerPixelTrace(puget(), 16);
}

TEST(ObjectPass, EqualsThePerPixelTraceOverGoletaSweep) {
    expectPassEqualsPerPixelTrace(goleta(), 16);
}

// The fast casters with objects against the reference with the same objects. Where the terrain
// images agree the ids agree (a pixel's objects are walked up to its terrain depth); the id may
// differ only where the two casters see different ground (the multiresolution caster's coarse
// levels far away, a silhouette's rounding), which the bounds below allow for.
struct SweepFigures {
    std::size_t refPixels = 0, idDiffer = 0, idDifferSameGround = 0, depthOff = 0;
    double maePct = 0.0;       // over every pose's object pixels together
    double worstMaePct = 0.0;  // the worst pose's
};

// A sweep's poses, their objects and the reference's frames with and without them, made once
// per map for every caster compared.
struct ReferenceSweep {
    struct View {
        Pose pose;
        std::unique_ptr<ObjectLayer> layer;
        RenderedFrame ref, refTerrain;
    };
    std::vector<View> views;
};

constexpr int kSweepPoses = 10;

const ReferenceSweep& referenceSweep(const TerrainMap& map, const Intrinsics& in) {
    static std::vector<std::pair<const TerrainMap*, std::unique_ptr<ReferenceSweep>>> cache;
    for (const auto& [m, sweep] : cache)
        if (m == &map) return *sweep;
    auto sweep = std::make_unique<ReferenceSweep>();
    for (const Pose& pose : sweepPoses(map, kSweepPoses)) {
        ReferenceSweep::View v;
        v.pose = pose;
        v.layer = objectsInView(map, pose, in);
        if (!v.layer) continue;
        v.ref = renderWith(map, {}, CasterKind::Reference, v.layer.get(), pose, in);
        v.refTerrain = renderWith(map, {}, CasterKind::Reference, nullptr, pose, in);
        sweep->views.push_back(std::move(v));
    }
    cache.emplace_back(&map, std::move(sweep));
    return *cache.back().second;
}

SweepFigures sweepAgainstReference(const TerrainMap& map, const RenderOptions& options,
                                   CasterKind kind) {
    const Intrinsics in = Intrinsics::fromFov(128, 96, degToRad(60.0));
    SweepFigures s;
    double errSum = 0.0, pixels = 0.0;
    for (const ReferenceSweep::View& v : referenceSweep(map, in).views) {
        const RenderedFrame got = renderWith(map, options, kind, v.layer.get(), v.pose, in);
        const RenderedFrame gotTerrain = renderWith(map, options, kind, nullptr, v.pose, in);
        const ObjectAgreement a = compareObjects(got, v.ref, gotTerrain, v.refTerrain);
        s.refPixels += a.refPixels;
        s.idDiffer += a.idDiffer;
        s.idDifferSameGround += a.idDifferSameGround;
        s.depthOff += a.depthOff;
        s.worstMaePct = std::max(s.worstMaePct, a.maePct);
        errSum += a.maePct * static_cast<double>(a.pixels);
        pixels += static_cast<double>(a.pixels);
    }
    s.maePct = pixels > 0.0 ? errSum / pixels : 0.0;
    return s;
}

void expectAgreesWithReference(const char* what, const SweepFigures& s, double idFraction) {
    std::printf(
        "%s: %zu object pixels, ids differ on %zu (%zu where the terrain agrees), depth "
        "off on %zu, colour error %.3f %% (worst pose %.3f %%)\n",
        what, s.refPixels, s.idDiffer, s.idDifferSameGround, s.depthOff, s.maePct, s.worstMaePct);
    EXPECT_GT(s.refPixels, 2000u) << what;
    EXPECT_EQ(s.idDifferSameGround, 0u) << what;
    EXPECT_LE(static_cast<double>(s.idDiffer), idFraction * static_cast<double>(s.refPixels))
        << what;
    EXPECT_EQ(s.depthOff, 0u) << what;
    EXPECT_LE(s.maePct, 0.5) << what;
}

TEST(ObjectPass, FastCasterMatchesReferenceOverPugetSoundSweep) {
    const TerrainMap& map = puget();
    for (const CasterKernel kernel : kernelsOnThisProcessor()) {
        for (const int levels : {0, kLevelsAuto}) {
            RenderOptions o;
            o.kernel = kernel;
            o.levels = levels;
            const std::string what = "Puget Sound, " + std::string(casterKernelName(kernel)) +
                                     (levels == 0 ? ", levels 0" : ", levels auto");
            // Single level: the terrain is the reference's, so are the objects. Levels auto: the
            // coarse levels' ground in the distance hides or shows an object's foot differently.
            expectAgreesWithReference(what.c_str(), sweepAgainstReference(map, o, CasterKind::Fast),
                                      levels == 0 ? 0.0 : 0.02);
        }
    }
}

TEST(ObjectPass, FastCasterMatchesReferenceOverGoletaSweep) {
    const TerrainMap& map = goleta();
    for (const int levels : {0, kLevelsAuto}) {
        RenderOptions o;
        o.levels = levels;
        expectAgreesWithReference(levels == 0 ? "Goleta, levels 0" : "Goleta, levels auto",
                                  sweepAgainstReference(map, o, CasterKind::Fast),
                                  levels == 0 ? 0.0 : 0.02);
    }
}

TEST(ObjectPass, SpanAndSupersampleCastersMatchReference) {
    const TerrainMap& map = puget();
    RenderOptions span;
    expectAgreesWithReference("Puget Sound, span",
                              sweepAgainstReference(map, span, CasterKind::Span), 0.02);
    RenderOptions autoSuper;
    autoSuper.supersample = kSupersampleAuto;
    // Objects are sampled at the pixel centre over the averaged terrain colour (the ground
    // under an object's foot is the nearest of the pixel's rays).
    expectAgreesWithReference("Puget Sound, supersample auto",
                              sweepAgainstReference(map, autoSuper, CasterKind::Fast), 0.02);
}

// ---- Hard cases on a flat map ---------------------------------------------------------------

// A flat 65 x 65 map at 10 m, 100 m high; `ridge` raises the row y = 300 m to 400 m.
TerrainMap flatMap(bool ridge = false) {
    TerrainMap map(65, 65, 10.0, 10.0, 0.1, 0.0);
    for (int iy = 0; iy < 65; ++iy)
        for (int ix = 0; ix < 65; ++ix) {
            map.setRaw(ix, iy, ridge && iy == 30 ? 4000 : 1000);
            map.setColor(ix, iy, Rgb8{90, 140, 60});
        }
    map.updateRange();
    return map;
}

std::size_t pixelsOf(const RenderedFrame& f, std::uint16_t id) {
    return static_cast<std::size_t>(std::count(f.objectId.begin(), f.objectId.end(), id));
}

TEST(ObjectPass, OneVoxelMastIsDrawnAtEveryPitch) {
    const TerrainMap map = flatMap();
    ObjectModel mast;
    mast.name = "mast";
    mast.grid = VoxModel(1, 1, 40);
    mast.palette = defaultVoxPalette();
    for (int z = 0; z < 40; ++z)
        mast.grid.set(0, 0, z, static_cast<std::uint8_t>(1 + z));
    ObjectLayer layer(map, 0.5);
    layer.place(mast, Placement{9, 320.25, 320.25, 100.0, 0.0, 0.5});  // 0.5 m wide, 20 m tall
    layer.finish();
    const Intrinsics in = Intrinsics::fromFov(96, 72, degToRad(40.0));
    for (int pitchDeg = 0; pitchDeg >= -90; pitchDeg -= 10) {
        // 60 m from the mast's middle, looking at it.
        const double pitch = degToRad(pitchDeg);
        Pose pose;
        pose.position = {320.25, 320.25 - 60.0 * std::cos(pitch), 110.0 - 60.0 * std::sin(pitch)};
        pose.pitch = pitch;
        const RenderedFrame ref = renderWith(map, {}, CasterKind::Reference, &layer, pose, in);
        for (const int levels : {0, kLevelsAuto}) {
            RenderOptions o;
            o.levels = levels;
            const RenderedFrame got = renderWith(map, o, CasterKind::Fast, &layer, pose, in);
            EXPECT_GT(pixelsOf(got, 9), 0u) << "pitch " << pitchDeg;
            EXPECT_EQ(got.objectId, ref.objectId) << "pitch " << pitchDeg << " levels " << levels;
        }
    }
}

// Objects overlapping in the same cells: their voxels are entered at the same points, and the
// pass must order them as the reference does (by id), whichever box it walks first.
TEST(ObjectPass, ObjectsSharingCellsAreOrderedAsTheReference) {
    const TerrainMap map = flatMap();
    const ObjectModel& tree = shippedModels()[0];
    const ObjectModel& leaves = shippedModels()[1];
    ObjectLayer layer(map, 0.5);
    // Placed in decreasing id order, each pair on one spot with different headings.
    for (int i = 0; i < 6; ++i) {
        const double x = 300.0 + 7.0 * i, y = 330.0 + 3.0 * (i % 2);
        layer.place(i % 2 ? leaves : tree,
                    Placement{static_cast<std::uint16_t>(40 - 2 * i), x, y, 100.0, 0.3 * i, 0.5});
        layer.place(tree, Placement{static_cast<std::uint16_t>(39 - 2 * i), x, y, 100.0,
                                    0.3 * i + 0.8, 0.5});
    }
    layer.finish();
    const Intrinsics in = Intrinsics::fromFov(160, 120, degToRad(40.0));
    for (const double pitchDeg : {0.0, -20.0, -60.0}) {
        Pose pose;
        pose.position = pitchDeg > -30.0 ? glm::dvec3{318.0, 300.0, 108.0 - pitchDeg}
                                         : glm::dvec3{318.0, 318.0, 140.0};
        pose.pitch = degToRad(pitchDeg);
        const RenderedFrame ref = renderWith(map, {}, CasterKind::Reference, &layer, pose, in);
        const RenderedFrame got = renderWith(map, {}, CasterKind::Fast, &layer, pose, in);
        EXPECT_GT(ref.objectId.size() - pixelsOf(ref, 0), 1000u) << "pitch " << pitchDeg;
        EXPECT_EQ(got.objectId, ref.objectId) << "pitch " << pitchDeg;
        EXPECT_TRUE(got.color == ref.color) << "pitch " << pitchDeg;
    }
}

// Objects a few metres from the eye, each cell many pixels wide, are splatted: every shipped model
// (opaque, semi-transparent leaves, glass and a doorway of cavities, a thin floating mast), seen
// level, from above, straight down, from below their tops and from inside the house, equal to the
// per-pixel trace to the bit, and so does the pass that walks every box. Straight down, many rays
// pass within rounding of a cell's vertical edge (the view that found the whole-box walk taking
// the other side face there). Three views look straight down from above cell corners (one a
// terrain cell's): rays along the image's diagonals pass exactly through cells' vertical edges
// and corners, and through object cells' corners on terrain cells' edges (the views that found
// the per-pixel walk's first object cell in a terrain cell, placed by position, taking the other
// side face or passing a voxel). The last two stand inside the house with the eye on cell lines.
TEST(ObjectPass, SplattedNearObjectsEqualThePerPixelTrace) {
    const TerrainMap map = flatMap();
    ObjectLayer layer(map, 0.5);
    for (int i = 0; i < 8; ++i) {
        const double a = 0.8 * i;
        layer.place(shippedModels()[static_cast<std::size_t>(i % 4)],
                    Placement{static_cast<std::uint16_t>(20 + i), 320.0 + 9.0 * std::cos(a),
                              320.0 + 9.0 * std::sin(a), 100.0, 0.4 * i, 0.5});
    }
    layer.finish();
    const std::vector<const ObjectLayer*> layers = {&layer};
    const Intrinsics in = Intrinsics::fromFov(160, 120, degToRad(70.0));
    struct View {
        glm::dvec3 at;
        double yawDeg, pitchDeg;
    };
    // The house (id 22) stands at 0.8 * 2 rad; the last view is inside it.
    const glm::dvec3 house{320.0 + 9.0 * std::cos(1.6), 320.0 + 9.0 * std::sin(1.6), 102.0};
    const View views[] = {
        {{320.1, 300.2, 104.0}, 0.0, 0.0},     {{320.3, 305.1, 112.0}, 10.0, -30.0},
        {{321.13, 322.37, 140.0}, 0.0, -90.0}, {{330.2, 318.3, 101.0}, 95.0, 25.0},
        {{300.4, 340.1, 106.0}, 135.0, -8.0},  {house, 30.0, -5.0},
        {{321.0, 322.0, 140.0}, 0.0, -90.0},   {{320.0, 320.0, 135.0}, 0.0, -90.0},
        {{318.5, 321.0, 128.0}, 90.0, -90.0},  {{319.5, 329.0, 102.0}, 30.0, -5.0},
        {{320.0, 329.5, 101.0}, 200.0, 0.0}};
    std::size_t splatted = 0, objectPixels = 0;
    for (const View& v : views) {
        Pose pose;
        pose.position = v.at;
        pose.yaw = degToRad(v.yawDeg);
        pose.pitch = degToRad(v.pitchDeg);
        const Camera camera(pose, in);
        const RenderedFrame terrain = renderWith(map, {}, CasterKind::Fast, nullptr, pose, in);
        RenderedFrame twin = terrain, pass = terrain, walked = terrain;
        for (RenderedFrame* f : {&twin, &pass, &walked})
            f->objectId.assign(terrain.color.size(), 0);
        drawObjectsPerPixel(layers, SkyModel{}, camera, twin, 0, in.width);
        ObjectPassStats stats;
        drawObjects(layers, SkyModel{}, camera, pass, 0, in.width, false,
                    ObjectPassOptions{ObjectPassOptions{}.splatPixelsPerColumn, &stats});
        drawObjects(layers, SkyModel{}, camera, walked, 0, in.width, false,
                    ObjectPassOptions{INFINITY, nullptr});
        const FrameDifference d = differences(pass, twin), w = differences(walked, twin);
        const std::size_t shown = twin.objectId.size() - pixelsOf(twin, 0);
        EXPECT_EQ(d.id, 0u) << "view at yaw " << v.yawDeg << " pitch " << v.pitchDeg;
        EXPECT_EQ(d.depth, 0u) << "view at yaw " << v.yawDeg << " pitch " << v.pitchDeg;
        EXPECT_EQ(w.id + w.depth, 0u) << "view at yaw " << v.yawDeg << " pitch " << v.pitchDeg;
        EXPECT_EQ(d.color, 0u) << "view at " << v.at.x << "," << v.at.y << " yaw " << v.yawDeg
                               << " pitch " << v.pitchDeg;
        EXPECT_EQ(w.color, 0u) << "view at " << v.at.x << "," << v.at.y << " yaw " << v.yawDeg
                               << " pitch " << v.pitchDeg;
        EXPECT_GT(shown, 500u) << "view at " << v.at.x << "," << v.at.y;  // each view sees some
        splatted += stats.splatted;
        objectPixels += shown;
    }
    EXPECT_GE(splatted, 8u);
    EXPECT_GT(objectPixels, 20000u);
}

// Each box cell's height range is the hull of its entries of the box's id, whatever the other
// objects sharing the cell hold (+inf, -inf where it holds none): the walk passes a cell whose
// range the ray misses without looking at its entries. Its grid lines are the exact walk's.
TEST(ObjectPass, BoxColumnRangesAndGridLinesAreTheWalks) {
    const TerrainMap map = flatMap();
    ObjectLayer layer(map, 0.5);
    for (int i = 0; i < 6; ++i) {
        const double x = 300.0 + 4.0 * i, y = 330.0 + 2.0 * (i % 2);
        layer.place(shippedModels()[static_cast<std::size_t>(i) % shippedModels().size()],
                    Placement{static_cast<std::uint16_t>(10 + i), x, y, 100.0 + i, 0.4 * i, 0.5});
    }
    layer.finish();
    const StickTable& table = layer.table();
    std::size_t empty = 0, held = 0;
    for (const ObjectBox& box : layer.boxes()) {
        const float* r = layer.boxColumnRanges(box);
        for (std::int64_t cy = box.cy0; cy <= box.cy1; ++cy) {
            for (std::int64_t cx = box.cx0; cx <= box.cx1; ++cx, r += 2) {
                float lo = INFINITY, hi = -INFINITY;
                for (const ObjectCell& c : layer.cellsAt(cx, cy)) {
                    if (c.id != box.id) continue;
                    lo = std::min(lo, c.baseZ + table.bottom(c.stick));
                    hi = std::max(hi, c.baseZ + table.top(c.stick));
                }
                EXPECT_EQ(r[0], lo) << "id " << box.id << " cell " << cx << "," << cy;
                EXPECT_EQ(r[1], hi) << "id " << box.id << " cell " << cx << "," << cy;
                (lo > hi ? empty : held) += 1;
            }
        }
    }
    EXPECT_GT(held, 100u);
    EXPECT_GT(empty, 0u);  // the models' boxes have empty corners
    // The grid lines kept with each box are the walk's own (the terrain cell's edge where a line
    // is one), increasing, one object cell apart.
    const int k = layer.subdivision();
    for (const ObjectBox& box : layer.boxes()) {
        const double* xs = layer.boxLinesX(box);
        const double* ys = layer.boxLinesY(box);
        for (std::int64_t i = 0; i <= box.cx1 - box.cx0 + 1; ++i) {
            EXPECT_EQ(xs[i], objectGridLine(box.cx0 + i, k, map.spacingX(), layer.cellSizeX()));
            EXPECT_NEAR(xs[i], static_cast<double>(box.cx0 + i) * layer.cellSizeX(), 1e-9);
        }
        for (std::int64_t i = 0; i <= box.cy1 - box.cy0 + 1; ++i) {
            EXPECT_EQ(ys[i], objectGridLine(box.cy0 + i, k, map.spacingY(), layer.cellSizeY()));
            EXPECT_NEAR(ys[i], static_cast<double>(box.cy0 + i) * layer.cellSizeY(), 1e-9);
        }
    }
}

// 300 walls of one voxel's depth on one row of cells: each wall's cells hold 300 entries, more
// than a box's 16-bit cell index counts, so the boxes search their rows instead.
TEST(ObjectPass, CrowdedRowsSearchedWithoutTheCellIndex) {
    const TerrainMap map = flatMap();
    ObjectModel wall;
    wall.name = "wall";
    wall.grid = VoxModel(256, 1, 4);
    wall.palette = defaultVoxPalette();
    for (int z = 0; z < 4; ++z)
        for (int x = 0; x < 256; ++x)
            wall.grid.set(x, 0, z, static_cast<std::uint8_t>(1 + (x + z) % 250));
    ObjectLayer layer(map, 0.5);
    for (int i = 0; i < 300; ++i)
        layer.place(
            wall, Placement{static_cast<std::uint16_t>(1000 - i), 320.0, 320.25, 100.0, 0.0, 0.5});
    layer.finish();
    Pose pose;
    pose.position = {320.0, 300.0, 104.0};
    pose.pitch = degToRad(-5.0);
    const Intrinsics in = Intrinsics::fromFov(64, 48, degToRad(60.0));
    const RenderedFrame ref = renderWith(map, {}, CasterKind::Reference, &layer, pose, in);
    const RenderedFrame got = renderWith(map, {}, CasterKind::Fast, &layer, pose, in);
    EXPECT_GT(pixelsOf(ref, 701), 100u);  // the lowest id, first of the voxels entered together
    EXPECT_EQ(got.objectId, ref.objectId);
    EXPECT_TRUE(got.color == ref.color);
}

TEST(ObjectPass, ObjectBehindARidgeHasNoPixel) {
    ObjectModel box;
    box.name = "box";
    box.grid = VoxModel(2, 2, 2);
    box.palette = defaultVoxPalette();
    for (auto& v : box.grid.voxels)
        v = 50;
    for (const bool ridge : {false, true}) {
        const TerrainMap map = flatMap(ridge);
        ObjectLayer layer(map, 1.0);
        layer.place(box, Placement{4, 320.0, 400.0, 100.0, 0.0, 5.0});  // 10 m cube behind y = 300
        layer.finish();
        Pose pose;
        pose.position = {320.0, 150.0, 150.0};
        pose.pitch = degToRad(-10.0);
        const Intrinsics in = Intrinsics::fromFov(96, 72, degToRad(40.0));
        for (const CasterKind kind : {CasterKind::Fast, CasterKind::Span}) {
            const RenderedFrame f = renderWith(map, {}, kind, &layer, pose, in);
            if (ridge)
                EXPECT_EQ(pixelsOf(f, 4), 0u);
            else
                EXPECT_GT(pixelsOf(f, 4), 20u);
        }
    }
}

// An empty scene leaves every image of every fast caster as it is without one, bit for bit.
TEST(ObjectPass, EmptySceneLeavesImagesBitForBit) {
    const TerrainMap& map = puget();
    const ObjectLayer empty(map, 1.0);
    const Intrinsics in = Intrinsics::fromFov(96, 64, degToRad(60.0));
    RenderOptions l0, lauto, super;
    lauto.levels = kLevelsAuto;
    super.supersample = kSupersampleAuto;
    const std::vector<std::pair<CasterKind, RenderOptions>> casters = {{CasterKind::Fast, l0},
                                                                       {CasterKind::Fast, lauto},
                                                                       {CasterKind::Fast, super},
                                                                       {CasterKind::Span, l0}};
    for (const Pose& pose : sweepPoses(map, 6)) {
        for (const auto& [kind, o] : casters) {
            const RenderedFrame without = renderWith(map, o, kind, nullptr, pose, in);
            const RenderedFrame with = renderWith(map, o, kind, &empty, pose, in);
            EXPECT_TRUE(without.objectId.empty());
            EXPECT_EQ(with.objectId, std::vector<std::uint16_t>(with.color.size(), 0));
            EXPECT_TRUE(with.color == without.color);
            EXPECT_TRUE(with.depth == without.depth);
        }
    }
}

// The image with objects does not depend on the thread count, nor on drawing the frame by its
// work units (columns) instead of render().
TEST(ObjectPass, OutputIndependentOfThreadsAndUnits) {
    const TerrainMap& map = puget();
    const Intrinsics in = Intrinsics::fromFov(160, 120, degToRad(60.0));
    for (const Pose& pose : sweepPoses(map, 4)) {
        const auto layer = objectsInView(map, pose, in);
        if (!layer) continue;
        RenderOptions one, three;
        one.threads = 1;
        three.threads = 3;
        const RenderedFrame a = renderWith(map, one, CasterKind::Fast, layer.get(), pose, in);
        const RenderedFrame b = renderWith(map, three, CasterKind::Fast, layer.get(), pose, in);
        EXPECT_GT(a.objectId.size() - pixelsOf(a, 0), 0u);
        EXPECT_EQ(a.objectId, b.objectId);
        EXPECT_TRUE(a.color == b.color);
        EXPECT_TRUE(a.depth == b.depth);
        // Unit by unit, on a frame whose id image is allocated first.
        RenderOptions o;
        o.objects = {layer.get()};
        const auto caster = makeCaster(CasterKind::Fast, map, o);
        const Camera camera(pose, in);
        RenderedFrame u = a;
        std::fill(u.color.begin(), u.color.end(), Rgb8{});
        std::fill(u.depth.begin(), u.depth.end(), 0.0f);
        std::fill(u.objectId.begin(), u.objectId.end(), 0);
        UnitCounters counters;
        for (int unit = caster->workUnits(camera) - 1; unit >= 0; --unit)
            caster->renderUnit(camera, u, unit, counters);
        EXPECT_EQ(u.objectId, a.objectId);
        EXPECT_TRUE(u.color == a.color);
        EXPECT_TRUE(u.depth == a.depth);
    }
}

}  // namespace
