// Stereo through the PRP: each eye warped to its own pose, the layouts, zero separation, the
// vertical disparity of the two fits, and each eye's error against its own true render.
#include "sim/pipeline.hpp"
#include "sim/render_process.hpp"
#include "sim/stereo_output.hpp"

#include "ig/cli.hpp"
#include "ig/image_compare.hpp"
#include "io/field_clock.hpp"
#include "io/frame_sink.hpp"
#include "sim/trajectory.hpp"
#include "sim/trajectory_poses.hpp"

#include <gtest/gtest.h>

#include <glm/geometric.hpp>

#include <cstring>
#include <string>
#include <utility>
#include <vector>

namespace {

const ig::TerrainMap& pugetSound() {
    static const ig::TerrainMap map = ig::loadTerrainFromOptions(ig::TerrainOptions{});
    return map;
}

// 160 x 120 windows with 16 pixels of margin, not widened for roll.
sim::RenderGeometry smallGeometry() {
    sim::RenderGeometry geometry;
    geometry.windowWidth = 160;
    geometry.windowHeight = 120;
    geometry.margin = 16;
    geometry.coverRoll = false;
    return geometry;
}

sim::Trajectory trajectory(const std::string& name) {
    return sim::Trajectory::loadCsv(std::string(VIG_DATA_DIR) + "/trajectories/" + name);
}

// The eyes are half the separation either side of the head along its rolled right vector,
// with its orientation: a rolled head tilts the baseline.
TEST(StereoEyes, RollIsAboutTheHead) {
    ig::Pose head;
    head.position = {100.0, 200.0, 300.0};
    head.yaw = 0.4;
    head.pitch = -0.3;
    for (const double roll : {0.0, 0.5, -1.0}) {
        head.roll = roll;
        const sim::EyePoses e = sim::eyePoses(head, 2.0);
        const ig::CameraBasis b = ig::CameraBasis::fromPose(head);
        EXPECT_NEAR(glm::length(e.right.position - e.left.position - 2.0 * b.right), 0.0, 1e-12);
        EXPECT_NEAR(glm::length(0.5 * (e.left.position + e.right.position) - head.position), 0.0,
                    1e-12);
        for (const ig::Pose& p : {e.left, e.right}) {
            EXPECT_EQ(p.yaw, head.yaw);
            EXPECT_EQ(p.pitch, head.pitch);
            EXPECT_EQ(p.roll, head.roll);
        }
    }
}

prp::Field rgbField(int width, int frameHeight, std::uint64_t index, std::uint8_t base) {
    prp::Field f;
    f.index = index;
    f.parity = prp::fieldParity(index);
    f.width = width;
    f.frameHeight = frameHeight;
    f.lines = prp::fieldLines(frameHeight, f.parity);
    f.format = prp::PixelFormat::Rgb8;
    f.stride = static_cast<std::size_t>(width) * 3;
    f.pixels.resize(f.stride * f.lines);
    for (std::size_t i = 0; i < f.pixels.size(); ++i)
        f.pixels[i] = static_cast<std::uint8_t>(base + i % 97);
    return f;
}

// Side by side puts the left eye's line before the right's; top-bottom the left eye's lines
// before the right's; the anaglyph takes red from the left eye, green and blue from the right.
TEST(StereoComposer, Layouts) {
    const prp::Field l = rgbField(6, 8, 3, 10), r = rgbField(6, 8, 3, 100);
    prp::Field out;
    sim::StereoComposer(sim::StereoLayout::SideBySide, prp::PixelFormat::Rgb8).compose(l, r, out);
    ASSERT_EQ(out.width, 12);
    ASSERT_EQ(out.lines, l.lines);
    for (int y = 0; y < out.lines; ++y) {
        EXPECT_EQ(std::memcmp(out.line(y), l.line(y), l.stride), 0);
        EXPECT_EQ(std::memcmp(out.line(y) + l.stride, r.line(y), r.stride), 0);
    }
    sim::StereoComposer(sim::StereoLayout::TopBottom, prp::PixelFormat::Rgb8).compose(l, r, out);
    ASSERT_EQ(out.frameHeight, 16);
    ASSERT_EQ(out.lines, 2 * l.lines);
    EXPECT_EQ(out.lines, prp::fieldLines(16, out.parity));
    for (int y = 0; y < l.lines; ++y) {
        EXPECT_EQ(std::memcmp(out.line(y), l.line(y), l.stride), 0);
        EXPECT_EQ(std::memcmp(out.line(l.lines + y), r.line(y), r.stride), 0);
    }
    sim::StereoComposer(sim::StereoLayout::Anaglyph, prp::PixelFormat::Rgb8).compose(l, r, out);
    ASSERT_EQ(out.width, 6);
    for (int y = 0; y < out.lines; ++y) {
        for (int x = 0; x < out.width; ++x) {
            EXPECT_EQ(out.line(y)[3 * x], l.line(y)[3 * x]);
            EXPECT_EQ(out.line(y)[3 * x + 1], r.line(y)[3 * x + 1]);
            EXPECT_EQ(out.line(y)[3 * x + 2], r.line(y)[3 * x + 2]);
        }
    }
}

// Keeps every field's bytes.
class KeepingSink final : public io::FrameSink {
  public:
    int open(const io::VideoFormat& format, std::string*) override {
        format_ = format;
        return 0;
    }
    int writeField(const io::FieldBuffer& field) override {
        std::vector<std::uint8_t> bytes;
        for (int l = 0; l < field.lines; ++l)
            bytes.insert(bytes.end(), field.data + l * field.stride,
                         field.data + l * field.stride + field.stride);
        fields.push_back(std::move(bytes));
        strides.push_back(field.stride);
        return 0;
    }
    int close(std::string*) override { return 0; }
    const io::VideoFormat& format() const override { return format_; }
    std::vector<std::vector<std::uint8_t>> fields;
    std::vector<std::size_t> strides;

  private:
    io::VideoFormat format_;
};

// `fault` (a renderer process only): a fault the renderer injects into itself once.
sim::PipelineResult runStereo(const sim::Trajectory& tr, double separation, int eyeWidth,
                              int eyeHeight, double seconds, KeepingSink& sink,
                              sim::StereoLayout layout = sim::StereoLayout::SideBySide,
                              sim::RendererMode mode = sim::RendererMode::Thread,
                              const std::string& fault = "") {
    sim::TrajectoryPoses poses(tr);
    sim::RenderGeometry geometry;
    geometry.windowWidth = eyeWidth;
    geometry.windowHeight = eyeHeight;
    geometry.margin = 16;
    io::VideoFormat format;
    format.format = prp::PixelFormat::Rgb8;
    sim::stereoOutputSize(layout, eyeWidth, eyeHeight, format.width, format.height);
    std::string error;
    sink.open(format, &error);
    auto clock = io::makeSimulatedClock();
    sim::PipelineOptions options;
    options.clock = sim::ClockMode::Simulated;
    options.duration = seconds;
    options.stereo = sim::StereoOutput{separation, layout};
    options.rendererMode = mode;
    options.maxFramePixels = sim::maxFramePixels(geometry);
    if (!fault.empty()) {
        options.fault = sim::parseRendererFault(fault, "fault");
        options.renderTimeout = 1.0;
    }
    sim::Pipeline pipeline(poses, sim::makeStereoRenderer(pugetSound(), geometry, separation), sink,
                           *clock, options);
    return pipeline.run();
}

// With no separation both eyes are the same frame warped to the same pose: every field's two
// halves are the same bytes.
TEST(StereoPipeline, ZeroSeparationGivesIdenticalEyes) {
    KeepingSink sink;
    const sim::PipelineResult r = runStereo(trajectory("low.csv"), 0.0, 96, 72, 0.3, sink);
    ASSERT_TRUE(r.ok()) << r.error;
    ASSERT_FALSE(sink.fields.empty());
    for (std::size_t f = 0; f < sink.fields.size(); ++f) {
        const std::size_t stride = sink.strides[f];
        const std::size_t half = stride / 2;
        for (std::size_t at = 0; at < sink.fields[f].size(); at += stride) {
            ASSERT_EQ(
                std::memcmp(sink.fields[f].data() + at, sink.fields[f].data() + at + half, half), 0)
                << "field " << f;
        }
    }
    EXPECT_TRUE(r.stats.stereo);
    EXPECT_LT(r.stats.verticalDisparityPx.max, 1e-9);
}

// The renderer process carries both eyes in its ring: the same fields, byte for byte, as the
// renderer thread.
TEST(StereoPipeline, RendererProcessGivesTheThreadsFields) {
    KeepingSink thread, process;
    const sim::PipelineResult a = runStereo(trajectory("low.csv"), 2.0, 64, 48, 0.5, thread);
    const sim::PipelineResult b =
        runStereo(trajectory("low.csv"), 2.0, 64, 48, 0.5, process, sim::StereoLayout::SideBySide,
                  sim::RendererMode::Process);
    ASSERT_TRUE(a.ok() && b.ok()) << a.error << b.error;
    ASSERT_EQ(thread.fields.size(), 30u);
    ASSERT_EQ(process.fields.size(), thread.fields.size());
    for (std::size_t f = 0; f < thread.fields.size(); ++f)
        ASSERT_EQ(thread.fields[f], process.fields[f]) << "field " << f;
    EXPECT_TRUE(b.stats.restarts.empty());
    EXPECT_EQ(a.stats.framesRendered, b.stats.framesRendered);
}

// A stereo renderer process that crashes is restarted as a mono one is: every field goes out,
// each pair whole (the eyes of one frame: no field took a frame without its right eye).
TEST(StereoPipeline, RendererProcessSurvivesACrash) {
    KeepingSink sink;
    const sim::PipelineResult r =
        runStereo(trajectory("low.csv"), 2.0, 64, 48, 1.5, sink, sim::StereoLayout::SideBySide,
                  sim::RendererMode::Process, "crash@0.5");
    ASSERT_TRUE(r.ok()) << r.error;
    EXPECT_EQ(sink.fields.size(), 90u);
    ASSERT_EQ(r.stats.restarts.size(), 1u);
    EXPECT_NE(r.stats.restarts[0].cause.find("killed by signal 9"), std::string::npos)
        << r.stats.restarts[0].cause;
    EXPECT_GT(r.stats.framesShown, 2u);
}

// The eyes show the same world point on rows at most a quarter of an output row apart, low and
// fast over terrain (40 m up) with a head-sized separation and with metres of it: where the
// two independent quadratic fits disagree by more, the field's eyes take the depth model. At
// 6.5 cm the fits alone stay within the bound.
TEST(StereoPipeline, VerticalDisparityIsBounded) {
    for (const double separation : {0.065, 2.0}) {
        KeepingSink sink;
        const sim::PipelineResult r =
            runStereo(trajectory("low.csv"), separation, 320, 240, 0.5, sink);
        ASSERT_TRUE(r.ok()) << r.error;
        EXPECT_TRUE(r.stats.stereo);
        EXPECT_GE(r.stats.verticalDisparityPx.max, 0.0);  // measured on every field
        EXPECT_LE(r.stats.verticalDisparityPx.max, sim::kMaxVerticalDisparityRows)
            << "separation " << separation;
        if (separation < 0.1) {
            EXPECT_LE(r.stats.fitVerticalDisparityPx.max, sim::kMaxVerticalDisparityRows);
            EXPECT_EQ(r.stats.depthForRows, 0u);
        }
        EXPECT_GT(r.stats.rightWarpMs.p50, 0.0);
    }
}

// Mean absolute error (% of full scale) of an RGB8 field against the lines of a true render.
double fieldMae(const prp::Field& field, const ig::RenderedFrame& truth) {
    std::vector<ig::Rgb8> got, want;
    for (int line = 0; line < field.lines; ++line) {
        const std::uint8_t* p = field.line(line);
        const ig::Rgb8* t =
            truth.color.data() + static_cast<std::size_t>(field.frameLine(line)) * truth.width();
        for (int x = 0; x < field.width; ++x) {
            got.push_back({p[3 * x], p[3 * x + 1], p[3 * x + 2]});
            want.push_back(t[x]);
        }
    }
    return ig::meanAbsErrorPct(got, want);
}

// Each eye's field, warped from the pair's frame to that eye at the field instant, against that
// eye truly rendered there, by horizon: within 0.1 % (of full scale, mean absolute error) of
// the mono pipeline's field against the head's true render. Low and fast near terrain and
// straight and level higher up, 2 m between the eyes, the default (auto) warp.
TEST(StereoPipeline, EachEyeWithinMonoOfItsOwnTruth) {
    const ig::TerrainMap& map = pugetSound();
    const sim::RenderGeometry geometry = smallGeometry();
    constexpr double kSeparation = 2.0;
    const sim::FrameRenderer stereo = sim::makeStereoRenderer(map, geometry, kSeparation);
    const sim::FrameRenderer mono = sim::makeCasterRenderer(map, geometry);
    const auto caster = ig::makeCaster(ig::CasterKind::Fast, map);
    const ig::Intrinsics window = ig::Intrinsics::fromFov(160, 120, geometry.hfov);
    prp::PrpOptions o;
    o.outWidth = 160;
    o.outHeight = 120;
    o.format = prp::PixelFormat::Rgb8;
    o.model = prp::WarpModel::Auto;
    const std::vector<int> horizons{1, 2, 4, 8};
    for (const char* name : {"low.csv", "straight.csv"}) {
        const sim::Trajectory tr = trajectory(name);
        // Roll 0: the truths come from the same (un-rolling) caster as the frames.
        auto poseAt = [&](double t) {
            ig::Pose p = tr.poseAt(t);
            p.roll = 0.0;
            return p;
        };
        std::vector<double> left(horizons.size()), right(horizons.size()), head(horizons.size());
        constexpr int kBase = 2;
        for (int b = 0; b < kBase; ++b) {
            const double tb =
                tr.startTime() + (tr.endTime() - tr.startTime() - 0.2) * (b + 0.5) / kBase;
            const ig::RenderedFrame pair = stereo(poseAt(tb), tb, 1);
            const ig::RenderedFrame single = mono(poseAt(tb), tb, 1);
            ASSERT_TRUE(pair.right);
            for (std::size_t h = 0; h < horizons.size(); ++h) {
                const double tf = tb + horizons[h] * prp::kFieldPeriod;
                const ig::Pose pose = poseAt(tf);
                const sim::EyePoses eyes = sim::eyePoses(pose, kSeparation);
                prp::Field field;
                const auto n = static_cast<std::uint64_t>(horizons[h]);
                prp::PostRenderingProcessor(o).process(pair, eyes.left, tf, n, field);
                left[h] += fieldMae(field, ig::renderFrame(*caster, map, eyes.left, window, tf));
                prp::PostRenderingProcessor(o).process(*pair.right, eyes.right, tf, n, field);
                right[h] += fieldMae(field, ig::renderFrame(*caster, map, eyes.right, window, tf));
                prp::PostRenderingProcessor(o).process(single, pose, tf, n, field);
                head[h] += fieldMae(field, ig::renderFrame(*caster, map, pose, window, tf));
            }
        }
        for (std::size_t h = 0; h < horizons.size(); ++h) {
            const double l = left[h] / kBase, r = right[h] / kBase, m = head[h] / kBase;
            EXPECT_LE(l, m + 0.1) << name << " k " << horizons[h] << " mono " << m;
            EXPECT_LE(r, m + 0.1) << name << " k " << horizons[h] << " mono " << m;
        }
    }
}

}  // namespace

// The view's planes (a CIGI host's View Definition, through sim::requestView) clip both eyes of
// a pair as they clip a mono frame: nothing nearer than the near plane, the sky beyond the draw
// distance; the right eye takes the left's plane.
TEST(StereoPipeline, TheViewsPlanesClipBothEyes) {
    const ig::TerrainMap& map = pugetSound();
    const sim::FrameRenderer stereo = sim::makeStereoRenderer(map, smallGeometry(), 2.0);
    ig::Pose pose;
    pose.position = {0.5 * map.extentX(), 0.45 * map.extentY(), 0.0};
    pose.position.z = map.surfaceHeight(pose.position.x, pose.position.y) + 10.0;
    pose.yaw = 0.6;
    pose.pitch = -0.1;
    const ig::RenderedFrame open = stereo(pose, 0.0, 1);
    sim::RenderView view;
    view.farM = 800.0;
    view.nearM = 40.0;
    sim::setRequestView(view);
    const ig::RenderedFrame cut = stereo(pose, 0.0, 2);
    sim::setRequestView(sim::RenderView{});
    ASSERT_TRUE(open.right && cut.right);
    const std::pair<const ig::RenderedFrame*, const ig::RenderedFrame*> eyes[] = {
        {&open, &cut}, {open.right.get(), cut.right.get()}};
    for (const auto& [before, after] : eyes) {
        const char* eye = before == &open ? "left" : "right";
        EXPECT_EQ(after->nearM, 40.0) << eye;
        const ig::Camera camera(after->pose, after->intrinsics);
        const int w = after->width();
        std::size_t beyond = 0, nearer = 0;
        for (std::size_t i = 0; i < after->depth.size(); ++i) {
            const int x = static_cast<int>(i % static_cast<std::size_t>(w));
            const int y = static_cast<int>(i / static_cast<std::size_t>(w));
            const double forward = glm::dot(glm::normalize(camera.rayDirection(x + 0.5, y + 0.5)),
                                            camera.basis().forward);
            if (before->depth[i] != ig::kSkyDepth && before->depth[i] > 800.0) {
                ++beyond;
                EXPECT_EQ(after->depth[i], ig::kSkyDepth) << eye << " pixel " << i;
            }
            if (before->depth[i] * forward < 40.0 * (1.0 - 1e-6)) ++nearer;
            if (after->depth[i] != ig::kSkyDepth) {
                ASSERT_LE(after->depth[i], 800.0) << eye << " pixel " << i;
                ASSERT_GE(after->depth[i] * forward, 40.0 * (1.0 - 1e-6)) << eye << " pixel " << i;
            }
        }
        EXPECT_GT(beyond, 100u) << eye;
        EXPECT_GT(nearer, 100u) << eye;
    }
}
