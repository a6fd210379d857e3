// The field process allocates nothing per field once it has warmed up: every allocation in this
// test program goes through the counting operator new (tests/common/counting_new.cpp), and a
// wall-clock run with the renderer process must not move the count between its 60th field and
// its last (field thread, supervisor thread and everything they call).
#include "sim/pipeline.hpp"

#include "ig/synthetic.hpp"
#include "io/field_clock.hpp"
#include "io/frame_sink.hpp"
#include "sim/scenario.hpp"

#include <gtest/gtest.h>

#include "common/counting_new.hpp"

#include <cstdint>
#include <string>

namespace {

class CountingSink final : public io::FrameSink {
  public:
    int open(const io::VideoFormat& format, std::string*) override {
        format_ = format;
        return 0;
    }
    int writeField(const io::FieldBuffer& field) override {
        if (field.index == 60) {
            atWarm = gAllocations.load();
            threadAtWarm = tThreadAllocations;
        }
        atLast = gAllocations.load();
        threadAtLast = tThreadAllocations;
        ++fields;
        return 0;
    }
    int close(std::string*) override { return 0; }
    const io::VideoFormat& format() const override { return format_; }

    std::size_t atWarm = 0, atLast = 0;
    std::size_t threadAtWarm = 0, threadAtLast = 0;  // the field thread's own
    std::uint64_t fields = 0;

  private:
    io::VideoFormat format_;
};

TEST(FieldProcessAllocation, NoneAfterWarmUpWithTheRendererProcess) {
    const ig::TerrainMap map = ig::makeSyntheticTerrain(128, 11, 30.0);
    sim::FlightLimits limits;
    limits.cruiseSpeed = 120.0;
    std::string error;
    auto stick = io::makeScriptedStick("0.5 axis roll 0.3 ramp 0.2\n", "test.stick", &error);
    ASSERT_TRUE(stick) << error;
    sim::StickFlight flight(std::move(stick), sim::startOverMap(map, limits), limits, &map);
    sim::RenderGeometry geometry;
    geometry.windowWidth = 128;
    geometry.windowHeight = 96;
    geometry.margin = 8;
    CountingSink sink;
    ASSERT_EQ(sink.open({128, 96, io::PixelFormat::Uyvy}, &error), 0);
    auto clock = io::makeWallClock();
    sim::PipelineOptions options;
    options.duration = 2.0;
    options.rendererMode = sim::RendererMode::Process;
    options.maxFramePixels = sim::maxFramePixels(geometry);
    options.renderThreads = 1;
    sim::Pipeline pipeline(flight, sim::makeCasterRenderer(map, geometry), sink, *clock, options);
    const sim::PipelineResult result = pipeline.run();
    ASSERT_TRUE(result.ok()) << result.error;
    ASSERT_EQ(sink.fields, pipeline.fieldCount());
    EXPECT_GT(result.stats.framesRendered, 10u);
    EXPECT_TRUE(result.stats.restarts.empty());
    EXPECT_EQ(sink.atLast, sink.atWarm) << "allocations during the run after field 60";
}

// Stereo (renderer thread, which allocates its frames): the field thread itself allocates
// nothing after warming up while it warps both eyes and puts them side by side.
TEST(FieldProcessAllocation, NoneOnTheFieldThreadInStereo) {
    const ig::TerrainMap map = ig::makeSyntheticTerrain(128, 11, 30.0);
    sim::FlightLimits limits;
    limits.cruiseSpeed = 120.0;
    std::string error;
    auto stick = io::makeScriptedStick("0.5 axis roll 0.3 ramp 0.2\n", "test.stick", &error);
    ASSERT_TRUE(stick) << error;
    sim::StickFlight flight(std::move(stick), sim::startOverMap(map, limits), limits, &map);
    sim::RenderGeometry geometry;
    geometry.windowWidth = 128;
    geometry.windowHeight = 96;
    geometry.margin = 8;
    for (const sim::StereoLayout layout :
         {sim::StereoLayout::SideBySide, sim::StereoLayout::Anaglyph}) {
        CountingSink sink;
        io::VideoFormat format{0, 0, io::PixelFormat::Uyvy};
        sim::stereoOutputSize(layout, 128, 96, format.width, format.height);
        ASSERT_EQ(sink.open(format, &error), 0);
        auto clock = io::makeWallClock();
        sim::PipelineOptions options;
        options.duration = 1.5;
        options.rendererMode = sim::RendererMode::Thread;
        options.renderThreads = 1;
        options.stereo = sim::StereoOutput{1.0, layout};
        options.prp.model = prp::WarpModel::Auto;
        sim::Pipeline pipeline(flight, sim::makeStereoRenderer(map, geometry, 1.0), sink, *clock,
                               options);
        const sim::PipelineResult result = pipeline.run();
        ASSERT_TRUE(result.ok()) << result.error;
        ASSERT_EQ(sink.fields, pipeline.fieldCount());
        EXPECT_EQ(sink.threadAtLast, sink.threadAtWarm)
            << "field thread allocations after field 60, " << sim::stereoLayoutName(layout);
    }
}

}  // namespace
