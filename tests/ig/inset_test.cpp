// High-resolution insets nested in a global terrain: what nesting does to both maps, the image
// inside an inset against the whole fine terrain rendered in memory, no spike across an inset's
// border along a slow flight, control points, threads, and the refusals.
#include "ig/inset.hpp"

#include "ig/appearance.hpp"
#include "ig/error.hpp"
#include "ig/image_compare.hpp"
#include "ig/lighting_pass.hpp"
#include "ig/scene.hpp"
#include "ig/synthetic.hpp"
#include "ig/terrain_io.hpp"
#include "ig/vox.hpp"

#include <gtest/gtest.h>
#include <unistd.h>
#include <glm/geometric.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <random>
#include <vector>

namespace ig {
namespace {

constexpr std::uint64_t kSeed = 7;
constexpr double kSpacing = 8.0;

// A 512² synthetic map at 8 m with a 64 x 48-cell inset four times finer (2 m) at cell (200, 210).
NestedTerrain nested(int blendCells = 16) {
    std::vector<InsetSource> sources;
    sources.push_back(syntheticInset(kSeed, kSpacing, 200, 210, 64, 48, 4));
    return NestedTerrain(makeSyntheticTerrain(512, kSeed, kSpacing), std::move(sources),
                         blendCells);
}

const NestedTerrain& shared() {
    static const NestedTerrain t = nested();
    return t;
}

// The nested surface as one map at the inset's spacing over the whole global extent: the
// inset's samples inside it, the global bilinear surface and colours (rounded) elsewhere.
const TerrainMap& wholeFine() {
    static const TerrainMap w = shared().fineEquivalent();
    return w;
}

Pose lookingAtTheInset(double yawDeg, double pitchDeg, double range, double up) {
    const Inset& in = shared().insets()[0];
    const glm::dvec2 c = 0.5 * (in.coverMin + in.coverMax);
    const double yaw = degToRad(yawDeg);
    // Yaw 0 looks north (+y), 90 east (+x): stand `range` metres behind the centre.
    Pose p;
    p.position = {c.x - range * std::sin(yaw), c.y - range * std::cos(yaw), 0.0};
    p.position.z = shared().surfaceHeight(p.position.x, p.position.y) + up;
    p.yaw = yaw;
    p.pitch = degToRad(pitchDeg);
    return p;
}

// The pixels of `truth` whose hit lies over the inset's square, at least `edge` metres
// inside its border.
std::vector<std::size_t> pixelsInside(const RenderedFrame& truth, const Inset& in, double edge) {
    const Camera cam(truth.pose, truth.intrinsics);
    std::vector<std::size_t> out;
    for (int y = 0; y < truth.height(); ++y) {
        for (int x = 0; x < truth.width(); ++x) {
            const std::size_t i = static_cast<std::size_t>(y) * truth.width() + x;
            if (!std::isfinite(truth.depth[i])) continue;
            const glm::dvec3 p =
                truth.pose.position +
                double(truth.depth[i]) * glm::normalize(cam.rayDirection(x + 0.5, y + 0.5));
            if (p.x >= in.coverMin.x + edge && p.y >= in.coverMin.y + edge &&
                p.x <= in.coverMax.x - edge && p.y <= in.coverMax.y - edge) {
                out.push_back(i);
            }
        }
    }
    return out;
}

// The colours of `frame` at `pixels`.
std::vector<Rgb8> colorsAt(const RenderedFrame& frame, const std::vector<std::size_t>& pixels) {
    std::vector<Rgb8> out;
    out.reserve(pixels.size());
    for (const std::size_t i : pixels)
        out.push_back(frame.color[i]);
    return out;
}

TEST(Insets, TheGlobalSurfaceStaysUnderTheInsetAndMeetsItOnItsEdge) {
    const NestedTerrain& t = shared();
    const Inset& in = t.insets()[0];
    const TerrainMap& g = t.global();
    auto insetAt = [&](double x, double y) {
        return in.map.surfaceHeight(x - in.origin.x, y - in.origin.y);
    };
    std::mt19937 rng(3);
    std::uniform_real_distribution<double> ux(in.coverMin.x, in.coverMax.x),
        uy(in.coverMin.y, in.coverMax.y);
    for (int i = 0; i < 20000; ++i) {
        const double x = ux(rng), y = uy(rng);
        ASSERT_LE(g.surfaceHeight(x, y), insetAt(x, y) + 1e-9) << "at " << x << ", " << y;
        ASSERT_EQ(t.surfaceHeight(x, y), insetAt(x, y));
    }
    // On the edge, the inset is the global surface, up to its samples rounded up.
    double worst = 0.0;
    const double fs = in.map.spacingX();
    const int nx = static_cast<int>(std::lround((in.coverMax.x - in.coverMin.x) / fs));
    const int ny = static_cast<int>(std::lround((in.coverMax.y - in.coverMin.y) / fs));
    auto edge = [&](double x, double y) {
        const double d = insetAt(x, y) - g.surfaceHeight(x, y);
        EXPECT_GE(d, -1e-9);
        worst = std::max(worst, d);
    };
    for (int k = 0; k <= nx; ++k) {
        edge(in.coverMin.x + k * fs, in.coverMin.y);
        edge(in.coverMin.x + k * fs, in.coverMax.y);
    }
    for (int k = 0; k <= ny; ++k) {
        edge(in.coverMin.x, in.coverMin.y + k * fs);
        edge(in.coverMax.x, in.coverMin.y + k * fs);
    }
    EXPECT_LE(worst, g.heightScale() + 1e-9);
    // Without the blend the edge is a step: the fine data against the global surface.
    const NestedTerrain sharp = nested(0);
    const Inset& si = sharp.insets()[0];
    double step = 0.0;
    for (int k = 0; k <= nx; ++k) {
        const double x = si.coverMin.x + k * fs, y = si.coverMin.y;
        step = std::max(step, std::abs(si.map.surfaceHeight(x - si.origin.x, y - si.origin.y) -
                                       sharp.global().surfaceHeight(x, y)));
    }
    EXPECT_GT(step, 10.0 * g.heightScale());
    // The flight model's ground is on or over the nested surface, and the global one elsewhere.
    const TerrainMap upper = t.upperGround();
    for (int i = 0; i < 20000; ++i) {
        const double x = ux(rng), y = uy(rng);
        ASSERT_GE(upper.surfaceHeight(x, y), t.surfaceHeight(x, y) - 1e-9);
    }
    for (int j = 0; j < g.height(); j += 5) {
        for (int i = 0; i < g.width(); i += 5) {
            if (i >= in.x0 && i <= in.x1 && j >= in.y0 && j <= in.y1) continue;
            ASSERT_EQ(upper.raw(i, j), g.raw(i, j));
        }
    }
    // Away from the edge the inset holds detail the global samples lack.
    const TerrainMap plain = makeSyntheticTerrain(512, kSeed, kSpacing);
    double detail = 0.0;
    for (int v = 32; v < ny - 32; ++v) {
        for (int u = 32; u < nx - 32; ++u) {
            const double x = in.coverMin.x + u * fs, y = in.coverMin.y + v * fs;
            detail = std::max(detail, std::abs(insetAt(x, y) - plain.surfaceHeight(x, y)));
        }
    }
    EXPECT_GT(detail, 1.0);
    // Outside, the global map is untouched.
    for (int j = 0; j < g.height(); j += 3) {
        for (int i = 0; i < g.width(); i += 3) {
            if (i >= in.x0 && i <= in.x1 && j >= in.y0 && j <= in.y1) continue;
            ASSERT_EQ(g.raw(i, j), plain.raw(i, j));
        }
    }
}

struct Comparison {
    double maeInside = 0.0;    // per cent, pixels whose ray meets the inset's interior
    double worstInside = 0.0;  // levels of 255, largest channel difference there
    double badInside = 0.0;    // fraction of those pixels more than 2 levels apart
    int inside = 0;
    double maeAll = 0.0;
};

// Compares `frame` with `truth` (the whole fine terrain's render), over the pixels whose true
// hit lies inside the inset at least `edge` metres from its border.
Comparison compare(const RenderedFrame& frame, const RenderedFrame& truth, double edge) {
    const std::vector<std::size_t> inside = pixelsInside(truth, shared().insets()[0], edge);
    Comparison c;
    for (const std::size_t i : inside) {
        const Rgb8 u = frame.color[i], v = truth.color[i];
        const int d = std::max({std::abs(u.r - v.r), std::abs(u.g - v.g), std::abs(u.b - v.b)});
        c.worstInside = std::max(c.worstInside, double(d));
        if (d > 2) c.badInside += 1.0;
    }
    c.inside = static_cast<int>(inside.size());
    if (c.inside > 0) {
        c.maeInside = meanAbsErrorPct(colorsAt(frame, inside), colorsAt(truth, inside));
        c.badInside /= c.inside;
    }
    c.maeAll = meanAbsErrorPct(frame.color, truth.color);
    return c;
}

TEST(Insets, InsideTheImageIsTheWholeFineTerrainsRender) {
    const NestedTerrain& t = shared();
    const Intrinsics intr = Intrinsics::fromFov(240, 160, degToRad(50), 8);
    const struct {
        double yaw, pitch, range, up;
    } views[] = {{0, -25, 500, 150},
                 {70, -40, 300, 220},
                 {200, -12, 900, 120},
                 {315, -70, 80, 400},
                 {135, -8, 1200, 250}};
    for (const CasterKind kind : {CasterKind::Fast, CasterKind::Reference}) {
        RenderOptions options;
        options.levels = 0;
        const auto nestedCaster = makeNestedCaster(kind, t, options);
        const auto wholeCaster = makeCaster(kind, wholeFine(), options);
        const TerrainMap plain = makeSyntheticTerrain(512, kSeed, kSpacing);
        const auto plainCaster = makeCaster(kind, plain, options);
        for (const auto& v : views) {
            const Pose pose = lookingAtTheInset(v.yaw, v.pitch, v.range, v.up);
            const RenderedFrame frame = renderNestedFrame(*nestedCaster, t, pose, intr);
            const RenderedFrame truth = renderFrame(*wholeCaster, wholeFine(), pose, intr);
            const RenderedFrame coarse = renderFrame(*plainCaster, plain, pose, intr);
            const Comparison c = compare(frame, truth, 2.0);
            const Comparison without = compare(coarse, truth, 2.0);
            std::printf(
                "%s yaw %g: %d px inside; MAE %.4f %% (worst %g, %.3f %% > 2 levels), "
                "whole frame %.4f %%; the global map alone %.3f %% inside\n",
                std::string(casterName(kind)).c_str(), v.yaw, c.inside, c.maeInside, c.worstInside,
                100.0 * c.badInside, c.maeAll, without.maeInside);
            ASSERT_GT(c.inside, 1000);
            // The same samples, offset: only rounding of the ray's coordinates differs, and
            // where a ray grazes a silhouette it may land on the other side.
            EXPECT_LE(c.maeInside, 0.05);
            EXPECT_LE(c.badInside, 0.005);
            // Outside, the global bilinear surface against its rounded finer copy.
            EXPECT_LE(c.maeAll, 0.25);
            // The inset is visible: the global map alone is much further from the truth.
            EXPECT_GE(without.maeInside, 5.0 * std::max(c.maeInside, 0.01));
            // The control points lie on the nested surface and are the truth's.
            for (int k = 0; k < kControlPointCount; ++k) {
                const glm::dvec4 p = frame.controlPoints[k].world, q = truth.controlPoints[k].world;
                ASSERT_EQ(p.w, q.w);
                if (p.w == 0.0) continue;
                EXPECT_NEAR(p.z, t.surfaceHeight(p.x, p.y), 1e-3);
                EXPECT_LE(glm::length(glm::dvec3(p) - glm::dvec3(q)),
                          0.1 + 1e-4 * glm::length(glm::dvec3(q) - pose.position));
            }
        }
    }
}

// Frame-to-frame mean colour differences of a slow flight (the level-blending tests' flight,
// 6 m a frame) that crosses the inset's border at 150 m, looking ahead at -6 degrees.
std::vector<double> flightAcross(const Caster& caster, const NestedTerrain* nestedTerrain,
                                 const TerrainMap& map, int frames) {
    const Inset& in = shared().insets()[0];
    const Intrinsics intr = Intrinsics::fromFov(160, 90, degToRad(60));
    std::vector<double> diffs;
    std::vector<Rgb8> prev;
    for (int i = 0; i < frames; ++i) {
        Pose pose;
        pose.position = {in.coverMin.x - 200.0 + 6.0 * i, in.coverMin.y + 60.0 + 6.0 * i, 0.0};
        pose.position.z = 150.0 + shared().surfaceHeight(in.coverMin.x, in.coverMin.y);
        pose.yaw = degToRad(45.0);
        pose.pitch = degToRad(-6.0);
        RenderedFrame frame = nestedTerrain ? renderNestedFrame(caster, *nestedTerrain, pose, intr)
                                            : renderFrame(caster, map, pose, intr);
        if (!prev.empty()) diffs.push_back(meanAbsErrorPct(frame.color, prev));
        prev = std::move(frame.color);
    }
    return diffs;
}

double median(std::vector<double> v) {
    std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
    return v[v.size() / 2];
}

TEST(Insets, NoSpikeAcrossTheBorderAlongASlowFlight) {
    RenderOptions options;
    options.levels = kLevelsAuto;
    const auto nestedCaster = makeNestedCaster(CasterKind::Fast, shared(), options);
    const auto wholeCaster = makeCaster(CasterKind::Fast, wholeFine(), options);
    const TerrainMap plain = makeSyntheticTerrain(512, kSeed, kSpacing);
    const auto plainCaster = makeCaster(CasterKind::Fast, plain, options);
    const NestedTerrain sharp = nested(0);
    const auto sharpCaster = makeNestedCaster(CasterKind::Fast, sharp, options);
    const std::vector<double> nestedDiffs = flightAcross(*nestedCaster, &shared(), {}, 60);
    const std::vector<double> wholeDiffs = flightAcross(*wholeCaster, nullptr, wholeFine(), 60);
    const std::vector<double> plainDiffs = flightAcross(*plainCaster, nullptr, plain, 60);
    const std::vector<double> sharpDiffs = flightAcross(*sharpCaster, &sharp, {}, 60);
    auto worstOf = [](const std::vector<double>& v) {
        return *std::max_element(v.begin(), v.end());
    };
    const double mNested = median(nestedDiffs), worst = worstOf(nestedDiffs);
    std::printf(
        "across the border: nested median %.3f %% worst %.3f %%; whole fine map %.3f / "
        "%.3f %%; global map alone %.3f / %.3f %%; unblended inset %.3f / %.3f %%\n",
        mNested, worst, median(wholeDiffs), worstOf(wholeDiffs), median(plainDiffs),
        worstOf(plainDiffs), median(sharpDiffs), worstOf(sharpDiffs));
    ASSERT_GT(mNested, 0.0);
    EXPECT_LE(worst, 2.0 * mNested);
}

// Objects over an inset (a scene's placements standing on the nested surface): drawn by the
// global pass, hidden where the inset's relief lies nearer. The object ids and the image are
// those of the whole fine terrain with the same objects.
TEST(Insets, ObjectsStandOnTheInsetAndItsReliefHidesThem) {
    const NestedTerrain& t = shared();
    const std::string dir = ::testing::TempDir() + "inset_objects_" + std::to_string(::getpid());
    std::filesystem::create_directories(dir);
    VoxFile vox;
    vox.palette = defaultVoxPalette();
    vox.models.push_back(VoxModel(3, 3, 12));
    for (auto& v : vox.models[0].voxels)
        v = 7;
    writeVox(dir + "/mast.vox", vox);
    const Inset& in = t.insets()[0];
    std::string objects;
    int id = 1;
    for (int i = 0; i < 5; ++i) {
        for (int j = 0; j < 4; ++j) {
            const double x = in.coverMin.x + (in.coverMax.x - in.coverMin.x) * (i + 0.5) / 5;
            const double y = in.coverMin.y + (in.coverMax.y - in.coverMin.y) * (j + 0.5) / 4;
            objects += std::string(objects.empty() ? "" : ",") + R"({"id": )" +
                       std::to_string(id++) + R"(, "model": "mast", "x": )" + std::to_string(x) +
                       R"(, "y": )" + std::to_string(y) + R"(, "scale": 2})";
        }
    }
    const std::string json =
        R"({"cell_m": 1, "models": {"mast": {"vox": "mast.vox"}}, "objects": [)" + objects + "]}";
    const NestedGround ground(t.maps());
    const Scene overNested =
        parseScene(json, dir + "/s.json", t.global(), true, kMaxSceneCellVisits, &ground);
    const Scene overFine =
        parseScene(json, dir + "/s.json", wholeFine(), true, kMaxSceneCellVisits, &ground);
    for (std::size_t k = 0; k < overNested.staticLayer->objects().size(); ++k) {
        const PlacedObject& o = overNested.staticLayer->objects()[k];
        EXPECT_EQ(o.z, t.surfaceHeight(o.x, o.y));  // on the inset, over the lowered global map
        EXPECT_GT(o.z, t.global().surfaceHeight(o.x, o.y) - 1e-9);
    }
    const Intrinsics intr = Intrinsics::fromFov(240, 160, degToRad(50), 8);
    for (const CasterKind kind : {CasterKind::Fast, CasterKind::Reference}) {
        RenderOptions options;
        options.levels = 0;
        options.objects = {overNested.staticLayer.get()};
        const auto nestedCaster = makeNestedCaster(kind, t, options);
        options.objects = {overFine.staticLayer.get()};
        const auto wholeCaster = makeCaster(kind, wholeFine(), options);
        RenderOptions bare;
        bare.levels = 0;
        const auto bareCaster = makeNestedCaster(kind, t, bare);
        // The global pass alone: the objects over the lowered global surface, none hidden by
        // the inset's relief.
        options.objects = {overNested.staticLayer.get()};
        const auto globalCaster = makeCaster(kind, t.global(), options);
        std::size_t hidden = 0;
        for (const double yaw : {0.0, 110.0, 230.0}) {
            const Pose pose = lookingAtTheInset(yaw, -8, 700, 35);
            const RenderedFrame a = renderNestedFrame(*nestedCaster, t, pose, intr);
            const RenderedFrame b = renderFrame(*wholeCaster, wholeFine(), pose, intr);
            const RenderedFrame none = renderNestedFrame(*bareCaster, t, pose, intr);
            const RenderedFrame g = renderFrame(*globalCaster, t.global(), pose, intr);
            std::size_t objectPx = 0, differ = 0;
            for (std::size_t i = 0; i < a.objectId.size(); ++i) {
                objectPx += b.objectId[i] != 0;
                differ += a.objectId[i] != b.objectId[i];
                hidden += g.objectId[i] != 0 && a.objectId[i] == 0;
            }
            const Comparison c = compare(a, b, 2.0);
            std::printf("%s yaw %g: %zu object px, %zu ids differ; MAE %.4f %% of the frame\n",
                        std::string(casterName(kind)).c_str(), yaw, objectPx, differ, c.maeAll);
            ASSERT_GT(objectPx, 200u);
            // Silhouettes: a ray grazing a mast's edge or a ridge in front of it may land on
            // the other side in either render.
            EXPECT_LE(differ, objectPx / 50 + 2);
            EXPECT_LE(c.maeAll, 0.1);
            // Without objects, no ids.
            EXPECT_TRUE(std::all_of(none.objectId.begin(), none.objectId.end(),
                                    [](std::uint16_t v) { return v == 0; }));
        }
        std::printf("%s: %zu object px the inset's relief hides\n",
                    std::string(casterName(kind)).c_str(), hidden);
        EXPECT_GT(hidden, 10u);  // 28 here
    }
    std::filesystem::remove_all(dir);
}

TEST(Insets, TheImageDoesNotDependOnTheThreadCount) {
    const Intrinsics intr = Intrinsics::fromFov(200, 120, degToRad(50), 4);
    const Pose pose = lookingAtTheInset(30, -20, 700, 200);
    std::vector<Rgb8> first;
    std::vector<float> firstDepth;
    for (const int threads : {1, 2, 3}) {
        RenderOptions options;
        options.levels = kLevelsAuto;
        options.threads = threads;
        const auto caster = makeNestedCaster(CasterKind::Fast, shared(), options);
        const RenderedFrame f = renderNestedFrame(*caster, shared(), pose, intr);
        if (first.empty()) {
            first = f.color;
            firstDepth = f.depth;
            continue;
        }
        EXPECT_EQ(f.color, first);
        EXPECT_EQ(f.depth, firstDepth);
    }
}

TEST(Insets, ACameraUnderTheInsetsSurfaceIsRefused) {
    const Inset& in = shared().insets()[0];
    Pose p;
    p.position = {in.coverMin.x + 100.0, in.coverMin.y + 40.0, 0.0};
    p.position.z = shared().surfaceHeight(p.position.x, p.position.y) - 0.01;
    const auto caster = makeNestedCaster(CasterKind::Fast, shared());
    EXPECT_THROW(renderNestedFrame(*caster, shared(), p, Intrinsics::fromFov(64, 48, 1.0)),
                 InputError);
    p.position.z += 0.5;
    EXPECT_NO_THROW(renderNestedFrame(*caster, shared(), p, Intrinsics::fromFov(64, 48, 1.0)));
}

TEST(Insets, WhatDoesNotFitIsRefusedNamingTheInset) {
    const TerrainMap global = makeSyntheticTerrain(64, kSeed, kSpacing);
    auto expectRefused = [&](InsetSource src, const char* what) {
        src.name = "inset A";
        try {
            NestedTerrain t(global, {std::move(src)});
            ADD_FAILURE() << what << ": accepted";
        } catch (const InputError& e) {
            EXPECT_NE(std::string(e.what()).find("inset A"), std::string::npos) << e.what();
        }
    };
    InsetSource ok = syntheticInset(kSeed, kSpacing, 10, 10, 8, 8, 4);
    EXPECT_NO_THROW(NestedTerrain(global, {ok}));
    InsetSource s = ok;
    s.factor = 3;
    expectRefused(s, "factor 3");
    s = ok;
    s.x0 = 60;
    expectRefused(s, "outside the map");
    s = ok;
    s.x0 = -1;
    expectRefused(s, "negative corner");
    s = ok;
    s.fine = TerrainMap(32, 33, 2.0, 2.0, 0.1, -100.0);
    expectRefused(s, "not whole cells");
    s = ok;
    s.fine = TerrainMap(33, 33, 2.5, 2.5, 0.1, -100.0);
    expectRefused(s, "spacing");
    s = ok;
    s.fine = TerrainMap(33, 33, 2.0, 2.0, 10.0, -100.0);
    s.fine.setRaw(3, 3, 65000);
    expectRefused(s, "heights out of range");
    // Two insets that touch.
    InsetSource b = syntheticInset(kSeed, kSpacing, 18, 10, 4, 4, 4);
    b.name = "inset B";
    try {
        NestedTerrain t(global, {ok, b});
        ADD_FAILURE() << "touching insets accepted";
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find("inset B"), std::string::npos) << e.what();
    }
    EXPECT_THROW(NestedTerrain(global, {ok}, -1), InputError);
    EXPECT_THROW(makeNestedCaster(CasterKind::Span, NestedTerrain(global, {ok})), InputError);
}

}  // namespace
}  // namespace ig

namespace ig {
namespace {

// Real terrain: the Goleta elevation model and orthophoto. The global map keeps every fourth
// sample; an inset gives back the full data over 32 x 30 of its cells.
TEST(Insets, RealTerrainInsideTheInsetIsTheFullDataRendered) {
    const TerrainMap full = loadGoleta();
    const int f = 4;
    const int gw = (full.width() - 1) / f + 1, gh = (full.height() - 1) / f + 1;
    TerrainMap coarse(gw, gh, full.spacingX() * f, full.spacingY() * f, full.heightScale(),
                      full.heightOffset());
    for (int j = 0; j < gh; ++j) {
        for (int i = 0; i < gw; ++i) {
            coarse.setRaw(i, j, full.raw(i * f, j * f));
            coarse.setColor(i, j, full.colorAt(i * f, j * f));
        }
    }
    coarse.updateRange();
    const int x0 = 40, y0 = 50, cx = 32, cy = 30;
    InsetSource src;
    src.name = "Goleta at full resolution";
    src.x0 = x0;
    src.y0 = y0;
    src.factor = f;
    src.fine = TerrainMap(cx * f + 1, cy * f + 1, full.spacingX(), full.spacingY(),
                          full.heightScale(), full.heightOffset());
    for (int v = 0; v <= cy * f; ++v) {
        for (int u = 0; u <= cx * f; ++u) {
            src.fine.setRaw(u, v, full.raw(x0 * f + u, y0 * f + v));
            src.fine.setColor(u, v, full.colorAt(x0 * f + u, y0 * f + v));
        }
    }
    src.fine.updateRange();
    std::vector<InsetSource> sources;
    sources.push_back(std::move(src));
    const NestedTerrain t(coarse, std::move(sources));
    const Inset& in = t.insets()[0];
    const glm::dvec2 c = 0.5 * (in.coverMin + in.coverMax);
    const Intrinsics intr = Intrinsics::fromFov(200, 150, degToRad(45));
    RenderOptions options;
    options.levels = kLevelsAuto;
    const auto nestedCaster = makeNestedCaster(CasterKind::Fast, t, options);
    const auto fullCaster = makeCaster(CasterKind::Fast, full, options);
    const auto coarseCaster = makeCaster(CasterKind::Fast, coarse, options);
    const double edge = 16 * full.spacingX() + 2.0;  // past the blend
    for (const double yaw : {0.0, 120.0, 240.0}) {
        Pose pose;
        pose.yaw = degToRad(yaw);
        pose.pitch = degToRad(-50.0);
        const double back = 0.6 * (in.coverMax.x - in.coverMin.x);
        pose.position = {c.x - back * std::sin(pose.yaw), c.y - back * std::cos(pose.yaw), 0.0};
        pose.position.z = t.upperGround().surfaceHeight(pose.position.x, pose.position.y) +
                          0.8 * (in.coverMax.x - in.coverMin.x);
        const RenderedFrame frame = renderNestedFrame(*nestedCaster, t, pose, intr);
        const RenderedFrame truth = renderFrame(*fullCaster, full, pose, intr);
        const RenderedFrame before = renderFrame(*coarseCaster, coarse, pose, intr);
        // Pixels whose full-data hit lies inside the inset, past its blend.
        const std::vector<std::size_t> inside = pixelsInside(truth, in, edge);
        const std::vector<Rgb8> a = colorsAt(frame, inside), b = colorsAt(truth, inside),
                                p = colorsAt(before, inside);
        const double mae = meanAbsErrorPct(a, b), maeBefore = meanAbsErrorPct(p, b);
        std::printf(
            "Goleta yaw %g: %zu px inside; MAE against the full data %.4f %%, the coarse "
            "map alone %.3f %%\n",
            yaw, a.size(), mae, maeBefore);
        ASSERT_GT(a.size(), 2000u);
        EXPECT_LE(mae, 0.05);
        EXPECT_GE(maeBefore, 10.0 * std::max(mae, 0.01));
    }
}

}  // namespace
}  // namespace ig

namespace ig {
namespace {

// The elevation ramp and the sun over a terrain with an inset: each map coloured over the
// global map's range and lit by its own normals; inside the inset the image is the whole fine
// terrain's, coloured and lit the same way.
TEST(Insets, LitByTheSunInsideTheInsetAsTheWholeFineTerrain) {
    NestedTerrain t = nested();
    t.applyRamp();
    const Inset& in = t.insets()[0];
    // The whole fine terrain, coloured by the ramp over the global range.
    const TerrainMap& g = t.global();
    TerrainMap whole = t.fineEquivalent();
    whole.colors() = elevationRampAlbedo(whole, g);
    auto lighting = [](const TerrainMap& normalsOf) {
        auto lit = std::make_shared<SunLighting>();
        lit->normals = std::make_shared<const TerrainNormals>(normalsOf);
        lit->clock.sun = Sun{degToRad(135.0), degToRad(30.0)};
        return lit;
    };
    RenderOptions nestedOptions, wholeOptions, unlit;
    nestedOptions.lighting = lighting(g);
    wholeOptions.lighting = lighting(whole);
    const auto nestedCaster = makeNestedCaster(CasterKind::Fast, t, nestedOptions);
    const auto wholeCaster = makeCaster(CasterKind::Fast, whole, wholeOptions);
    const auto unlitCaster = makeNestedCaster(CasterKind::Fast, t, unlit);
    const Intrinsics intr = Intrinsics::fromFov(240, 160, degToRad(50), 8);
    const glm::dvec2 c = 0.5 * (in.coverMin + in.coverMax);
    for (const double yaw : {0.0, 150.0, 260.0}) {
        Pose pose;
        pose.yaw = degToRad(yaw);
        pose.pitch = degToRad(-35.0);
        pose.position = {c.x - 400.0 * std::sin(pose.yaw), c.y - 400.0 * std::cos(pose.yaw), 0.0};
        pose.position.z = t.upperGround().surfaceHeight(pose.position.x, pose.position.y) + 300.0;
        const RenderedFrame frame = renderNestedFrame(*nestedCaster, t, pose, intr);
        const RenderedFrame truth = renderFrame(*wholeCaster, whole, pose, intr);
        const RenderedFrame dark = renderNestedFrame(*unlitCaster, t, pose, intr);
        // Past the blend and a sample more (the normals there are the whole map's).
        const double edge = 17.0 * in.map.spacingX();
        const std::vector<std::size_t> inside = pixelsInside(truth, in, edge);
        const std::vector<Rgb8> a = colorsAt(frame, inside), b = colorsAt(truth, inside),
                                d = colorsAt(dark, inside);
        const double mae = meanAbsErrorPct(a, b), unlitMae = meanAbsErrorPct(d, b);
        std::printf("lit, yaw %g: %zu px inside; MAE %.4f %% (unlit %.3f %%)\n", yaw, a.size(), mae,
                    unlitMae);
        ASSERT_GT(a.size(), 3000u);
        EXPECT_LE(mae, 0.05);
        EXPECT_GE(unlitMae, 20.0 * std::max(mae, 0.01));
    }
}

}  // namespace
}  // namespace ig
