// The flythrough's renderer and ig-render give the same image for the same appearance flags at
// the same pose: haze, sun-lit ramp and supersampling reach the real-time loop unchanged.
#include "ig/caster.hpp"
#include "ig/cli.hpp"
#include "ig/synthetic.hpp"
#include "io/field_clock.hpp"
#include "io/file_sinks.hpp"
#include "io/frame_sink.hpp"
#include "io/video_format.hpp"
#include "sim/pipeline.hpp"
#include "sim/trajectory.hpp"
#include "sim/trajectory_poses.hpp"

#include <gtest/gtest.h>

#include <mutex>
#include <string>
#include <vector>

namespace {

// A map lit and hazed as a program does it from its flags (each program loads its own).
struct Lit {
    ig::TerrainMap map = ig::makeSyntheticTerrain(256, 4, 20.0);
    ig::RenderOptions options;
    explicit Lit(const ig::AppearanceOptions& look) {
        ig::TerrainOptions terrain;
        terrain.synthetic = "256:4";
        ig::applyAppearance(ig::parseAppearance(look, terrain, map), map, options);
    }
};

// Runs the pipeline on the simulated clock with `look`'s flags and renders each of its frames
// again as ig-render does: equal to the byte.
void expectFlythroughEqualsIgRender(const ig::AppearanceOptions& look) {
    Lit flythrough(look), igRender(look);
    ASSERT_GT(flythrough.options.sky.hazeDistance, 0.0);

    // A slow, gently descending flight at shallow pitch (auto supersampling casts 2+ rays).
    const double e = flythrough.map.extentX();
    std::vector<sim::TrajectorySample> samples;
    for (int k = 0; k <= 4; ++k) {
        sim::TrajectorySample s;
        s.t = 0.25 * k;
        s.pose.position = {0.3 * e + 40.0 * k, 0.3 * e + 40.0 * k,
                           flythrough.map.maxHeight() + 200.0};
        s.pose.yaw = 0.8;
        s.pose.pitch = -0.12 - 0.02 * k;
        samples.push_back(s);
    }
    sim::TrajectoryPoses poses(sim::Trajectory::fromSamples(samples, "test"));

    sim::RenderGeometry geometry;
    geometry.windowWidth = 128;
    geometry.windowHeight = 96;
    geometry.margin = 8;
    const sim::FrameRenderer inner =
        sim::makeCasterRenderer(flythrough.map, geometry, ig::CasterKind::Fast, flythrough.options);
    std::mutex mutex;
    std::vector<ig::RenderedFrame> frames;
    const sim::FrameRenderer recording = [&](const ig::Pose& pose, double t, std::uint64_t seq) {
        ig::RenderedFrame f = inner(pose, t, seq);
        const std::lock_guard lock(mutex);
        frames.push_back(f);
        return f;
    };
    io::NullSink sink;
    std::string error;
    sink.open({128, 96, io::PixelFormat::Uyvy}, &error);
    auto clock = io::makeSimulatedClock();
    sim::PipelineOptions options;
    options.clock = sim::ClockMode::Simulated;
    options.duration = 0.5;
    sim::Pipeline pipeline(poses, recording, sink, *clock, options);
    const sim::PipelineResult result = pipeline.run();
    ASSERT_TRUE(result.ok()) << result.error;
    ASSERT_GE(frames.size(), 3u);

    // ig-render's path: its own map and options from the same flags, one frame at each pose.
    const auto caster = ig::makeCaster(ig::CasterKind::Fast, igRender.map, igRender.options);
    for (const ig::RenderedFrame& f : frames) {
        const ig::RenderedFrame again =
            ig::renderFrame(*caster, igRender.map, f.pose, f.intrinsics);
        EXPECT_EQ(again.color, f.color) << "frame " << f.sequence;
        EXPECT_EQ(again.stats.rays, f.stats.rays);
        EXPECT_GT(f.stats.rays, static_cast<std::uint64_t>(f.color.size()));  // supersampled
    }
    // And the flags did change the image: without them the frame differs.
    if (look.hazeFalloff != "0") {
        ig::AppearanceOptions noFalloff = look;
        noFalloff.hazeFalloff = "0";
        Lit flat(noFalloff);
        const auto flatCaster = ig::makeCaster(ig::CasterKind::Fast, flat.map, flat.options);
        EXPECT_NE(
            ig::renderFrame(*flatCaster, flat.map, frames[0].pose, frames[0].intrinsics).color,
            frames[0].color);
    }
    ig::AppearanceOptions plain;
    Lit bare(plain);
    const auto bareCaster = ig::makeCaster(ig::CasterKind::Fast, bare.map, bare.options);
    EXPECT_NE(ig::renderFrame(*bareCaster, bare.map, frames[0].pose, frames[0].intrinsics).color,
              frames[0].color);
}

TEST(AppearancePipeline, FlythroughFramesEqualIgRenderAtTheSamePose) {
    ig::AppearanceOptions look;
    look.haze = "auto";
    look.colors = "auto";
    look.sun = "120,25";
    look.supersample = "auto";
    expectFlythroughEqualsIgRender(look);
}

TEST(AppearancePipeline, HazeFalloffIsTheSameInFlythroughAndIgRender) {
    ig::AppearanceOptions look;
    look.haze = "auto";
    look.hazeFalloff = "150";
    look.colors = "auto";
    look.sun = "120,25";
    look.supersample = "auto";
    expectFlythroughEqualsIgRender(look);
}

}  // namespace
