#include "sim/stereo_output.hpp"

#include "base/check.hpp"
#include "ig/error.hpp"
#include "prp/warp_apply.hpp"
#include "sim/pipeline.hpp"

#include <glm/geometric.hpp>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <memory>

namespace sim {

std::optional<StereoLayout> parseStereoLayout(std::string_view name) {
    if (name == "sbs") return StereoLayout::SideBySide;
    if (name == "tb") return StereoLayout::TopBottom;
    if (name == "anaglyph") return StereoLayout::Anaglyph;
    return std::nullopt;
}

std::string_view stereoLayoutName(StereoLayout layout) {
    switch (layout) {
        case StereoLayout::SideBySide:
            return "sbs";
        case StereoLayout::TopBottom:
            return "tb";
        case StereoLayout::Anaglyph:
            return "anaglyph";
    }
    return "?";
}

void stereoOutputSize(StereoLayout layout, int eyeWidth, int eyeHeight, int& width, int& height) {
    width = layout == StereoLayout::SideBySide ? 2 * eyeWidth : eyeWidth;
    height = layout == StereoLayout::TopBottom ? 2 * eyeHeight : eyeHeight;
}

void stereoEyeSize(StereoLayout layout, int width, int height, int& eyeWidth, int& eyeHeight) {
    eyeWidth = layout == StereoLayout::SideBySide ? width / 2 : width;
    eyeHeight = layout == StereoLayout::TopBottom ? height / 2 : height;
}

EyePoses eyePoses(const ig::Pose& head, double separation) {
    const glm::dvec3 right = ig::CameraBasis::fromPose(head).right;
    EyePoses e{head, head};
    e.left.position -= 0.5 * separation * right;
    e.right.position += 0.5 * separation * right;
    return e;
}

namespace {

// The stereo renderers' one body: the left eye by the fast caster over `map` (or the nested
// caster over `nested`), the right eye reprojected from it with its gaps cast; with `scene`,
// the terrain alone is cast and reprojected and the objects (the moving ones and `extra`'s
// stamped at the frame's instant, standing on the nested surface over insets) are drawn over
// both eyes afterwards.
FrameRenderer stereoRenderer(const ig::TerrainMap& map, const ig::NestedTerrain* nested,
                             const RenderGeometry& geometry, double separation,
                             const ig::RenderOptions& options, const ig::Scene* scene,
                             const SceneMotion* motion, ExtraObjects extra) {
    ig::StereoOptions stereo;
    stereo.eyeSeparation = separation;
    ig::validateStereoOptions(stereo);
    // Over insets: their maps, the ground the moving objects stand on, and each inset's passes
    // over the right eye's cast pixels (made once).
    std::shared_ptr<const ig::NestedMaps> maps;
    std::shared_ptr<const ig::NestedGround> ground;
    ig::RenderOptions terrainOnly = options;
    if (scene) terrainOnly.objects.clear();
    std::shared_ptr<const std::vector<ig::RenderOptions>> insetPasses;
    if (nested) {
        maps = std::make_shared<const ig::NestedMaps>(nested->maps());
        ground = std::make_shared<const ig::NestedGround>(*maps);
        insetPasses = std::make_shared<const std::vector<ig::RenderOptions>>(ig::insetPassOptions(
            *maps, std::vector<ig::RenderOptions>(maps->insets.size(), terrainOnly)));
    }
    // The moving layer is replaced before each render; the options hold its address.
    std::shared_ptr<ig::ObjectLayer> moving;
    ig::RenderOptions withObjects;
    if (scene) {
        moving =
            std::make_shared<ig::ObjectLayer>(motion->stamp(motion->startTime(), ground.get()));
        withObjects = options;
        withObjects.objects = {scene->staticLayer.get(), moving.get()};
    }
    std::shared_ptr<const ig::Caster> caster =
        nested ? ig::makeNestedCaster(ig::CasterKind::Fast, *nested, terrainOnly)
               : ig::makeCaster(ig::CasterKind::Fast, map, terrainOnly);
    auto objects = std::make_shared<std::vector<ExtraObject>>();
    return [caster, moving, objects, extra, &map, motion, geometry, stereo, terrainOnly,
            withObjects, maps, ground,
            insetPasses](const ig::Pose& pose, double time, std::uint64_t sequence) {
        if (moving) {
            if (extra) extra(time, *objects);
            *moving = motion->stamp(time, *objects, ground.get());
        }
        const RenderGeometry g = viewed(geometry, requestView());
        ig::Pose level = pose;
        level.roll = 0.0;  // the PRP applies roll
        const ig::Pose left = eyePoses(level, stereo.eyeSeparation).left;
        const ig::Intrinsics intr = renderIntrinsics(g, pose);
        // The view's near plane, both eyes (the right takes the left's).
        ig::RenderedFrame frame =
            maps ? ig::renderNestedFrame(*caster, *maps, left, intr, time, sequence, g.nearM)
                 : ig::renderFrame(*caster, map, left, intr, time, sequence, g.nearM);
        std::vector<ig::RightPixelSource> source;
        ig::StereoStats stats;
        auto right = std::make_shared<ig::RenderedFrame>(
            maps ? ig::reprojectRightEye(*maps, *insetPasses, frame, stereo, terrainOnly, source,
                                         stats, ig::nestedGlobalCaster(*caster))
                 : ig::reprojectRightEye(map, frame, stereo, terrainOnly, source, stats,
                                         caster.get()));
        const double objectsMs = moving ? ig::drawStereoObjects(withObjects, frame, *right) : 0.0;
        // The view's draw distance, both eyes.
        clipBeyondFar(frame, g.farM, terrainOnly.sky);
        clipBeyondFar(*right, g.farM, terrainOnly.sky);
        right->sequence = sequence;
        right->time = time;
        frame.stats.renderMs += stats.rightMs + objectsMs;
        frame.right = std::move(right);
        return frame;
    };
}

}  // namespace

FrameRenderer makeStereoRenderer(const ig::TerrainMap& map, const RenderGeometry& geometry,
                                 double separation, const ig::RenderOptions& options) {
    return stereoRenderer(map, nullptr, geometry, separation, options, nullptr, nullptr, {});
}

FrameRenderer makeStereoRenderer(const ig::NestedTerrain& terrain, const RenderGeometry& geometry,
                                 double separation, const ig::RenderOptions& options) {
    return stereoRenderer(terrain.global(), &terrain, geometry, separation, options, nullptr,
                          nullptr, {});
}

FrameRenderer makeStereoSceneRenderer(const ig::TerrainMap& map, const RenderGeometry& geometry,
                                      double separation, const ig::RenderOptions& options,
                                      const ig::Scene& scene, const SceneMotion& motion,
                                      ExtraObjects extra, const ig::NestedTerrain* nested) {
    return stereoRenderer(map, nested, geometry, separation, options, &scene, &motion,
                          std::move(extra));
}

namespace {

// Output row at which `warp` shows world point `world` in the eye at `eye`: its true output
// position moved by the fit's residual there (one Newton step). False when not visible.
bool warpedRow(const ig::RenderedFrame& frame, const prp::Quadratic& q, bool exact,
               const ig::Pose& eye, const prp::OutputGeometry& g, const glm::dvec3& world,
               double& row) {
    const auto p = ig::Camera(frame.pose, frame.intrinsics).project(world, 1.0);
    const auto w = ig::Camera(eye, g.fieldWindow()).project(world, 1.0);
    if (!p || !w) return false;
    const double sx = static_cast<double>(g.width) / g.windowWidth;
    const double sy = static_cast<double>(g.height) / g.windowHeight;
    const glm::dvec2 u{w->x * sx, w->y * sy};
    if (exact) {
        row = u.y;
        return std::isfinite(row);
    }
    const glm::dvec2 r = q(u) - *p;
    const auto& a = q.a;
    const auto& b = q.b;
    const double j00 = a[1] + a[3] * u.y + 2 * a[4] * u.x, j01 = a[2] + a[3] * u.x + 2 * a[5] * u.y;
    const double j10 = b[1] + b[3] * u.y + 2 * b[4] * u.x, j11 = b[2] + b[3] * u.x + 2 * b[5] * u.y;
    const double det = j00 * j11 - j01 * j10;
    if (!(std::abs(det) > 1e-12)) return false;
    // Delta = -J^-1 r; its y component.
    row = u.y - (-j10 * r.x + j00 * r.y) / det;
    return std::isfinite(row);
}

}  // namespace

double verticalDisparity(const ig::RenderedFrame& left, const ig::RenderedFrame& right,
                         const prp::WarpInfo& leftWarp, const prp::WarpInfo& rightWarp,
                         const EyePoses& eyes, const prp::OutputGeometry& geometry) {
    if (leftWarp.projective || rightWarp.projective) return -1.0;
    const prp::Quadratic ql = prp::quadraticOf(leftWarp), qr = prp::quadraticOf(rightWarp);
    const bool exactL = leftWarp.model == prp::WarpModel::Depth;
    const bool exactR = rightWarp.model == prp::WarpModel::Depth;
    double worst = -1.0;
    auto point = [&](const glm::dvec3& world) {
        double yl = 0, yr = 0;
        if (warpedRow(left, ql, exactL, eyes.left, geometry, world, yl) &&
            warpedRow(right, qr, exactR, eyes.right, geometry, world, yr)) {
            worst = std::max(worst, std::abs(yl - yr));
        }
    };
    for (const ig::RenderedFrame* f : {&left, &right}) {
        for (const ig::ControlPoint& cp : f->controlPoints) {
            if (cp.world.w == 1.0) point(glm::dvec3(cp.world));
        }
    }
    // The left frame's check points (the world point each grid pixel shows).
    const ig::Intrinsics& in = left.intrinsics;
    if (left.depth.size() == static_cast<std::size_t>(in.width) * in.height) {
        const ig::Camera cam(left.pose, in);
        for (int j = 0; j < prp::kCheckGrid; ++j) {
            for (int i = 0; i < prp::kCheckGrid; ++i) {
                const int x =
                    in.margin + static_cast<int>((i + 0.5) * in.windowWidth() / prp::kCheckGrid);
                const int y =
                    in.margin + static_cast<int>((j + 0.5) * in.windowHeight() / prp::kCheckGrid);
                const double d = left.depth[static_cast<std::size_t>(y) * in.width + x];
                if (!(std::isfinite(d) && d >= 0.0)) continue;
                point(left.pose.position + d * glm::normalize(cam.rayDirection(x + 0.5, y + 0.5)));
            }
        }
    }
    return worst;
}

prp::PixelFormat StereoComposer::eyeFormat() const {
    return layout_ == StereoLayout::Anaglyph ? prp::PixelFormat::Rgb8 : format_;
}

void StereoComposer::compose(const prp::Field& left, const prp::Field& right, prp::Field& out) {
    CHECK_EQ(left.index, right.index);
    CHECK_EQ(left.lines, right.lines);
    CHECK_EQ(left.stride, right.stride);
    out.index = left.index;
    out.parity = left.parity;
    out.time = left.time;
    out.frameSequence = left.frameSequence;
    out.frameTime = left.frameTime;
    out.frameAge = left.frameAge;
    out.format = format_;
    out.warp = left.warp;
    out.edgeSamples = left.edgeSamples + right.edgeSamples;
    out.holeSamples = left.holeSamples + right.holeSamples;
    out.warpMs = left.warpMs + right.warpMs;
    out.gain = left.gain;
    switch (layout_) {
        case StereoLayout::SideBySide:
            out.width = 2 * left.width;
            out.frameHeight = left.frameHeight;
            out.lines = left.lines;
            out.stride = 2 * left.stride;
            out.pixels.resize(out.stride * static_cast<std::size_t>(out.lines));
            for (int l = 0; l < out.lines; ++l) {
                std::uint8_t* row = out.pixels.data() + static_cast<std::size_t>(l) * out.stride;
                std::memcpy(row, left.line(l), left.stride);
                std::memcpy(row + left.stride, right.line(l), right.stride);
            }
            return;
        case StereoLayout::TopBottom:
            // Eye heights are even, so both halves' lines of this parity are the eyes' own.
            CHECK_EQ(left.frameHeight % 2, 0);
            out.width = left.width;
            out.frameHeight = 2 * left.frameHeight;
            out.lines = 2 * left.lines;
            out.stride = left.stride;
            out.pixels.resize(out.stride * static_cast<std::size_t>(out.lines));
            std::memcpy(out.pixels.data(), left.pixels.data(),
                        left.stride * static_cast<std::size_t>(left.lines));
            std::memcpy(out.pixels.data() + left.stride * static_cast<std::size_t>(left.lines),
                        right.pixels.data(), right.stride * static_cast<std::size_t>(right.lines));
            return;
        case StereoLayout::Anaglyph: {
            CHECK(left.format == prp::PixelFormat::Rgb8 && right.format == prp::PixelFormat::Rgb8);
            out.width = left.width;
            out.frameHeight = left.frameHeight;
            out.lines = left.lines;
            out.stride = static_cast<std::size_t>(out.width) * prp::bytesPerPixel(format_);
            out.pixels.resize(out.stride * static_cast<std::size_t>(out.lines));
            row_.resize(3 * static_cast<std::size_t>(out.width));
            std::uint64_t luma = 0;
            for (int l = 0; l < out.lines; ++l) {
                const std::uint8_t* a = left.line(l);
                const std::uint8_t* b = right.line(l);
                for (int x = 0; x < out.width; ++x) {
                    row_[3 * x] = a[3 * x];
                    row_[3 * x + 1] = b[3 * x + 1];
                    row_[3 * x + 2] = b[3 * x + 2];
                }
                prp::convertRow(row_.data(), out.width, format_, prp::kUnityGain, false,
                                out.pixels.data() + static_cast<std::size_t>(l) * out.stride, luma);
            }
            return;
        }
    }
}

}  // namespace sim
