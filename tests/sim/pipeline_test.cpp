#include "sim/pipeline.hpp"

#include "base/fork_gate.hpp"

#include "ig/error.hpp"
#include "ig/synthetic.hpp"
#include "io/field_clock.hpp"
#include "io/stick.hpp"
#include "sim/pose_source.hpp"
#include "sim/scenario.hpp"

#include <gtest/gtest.h>
#include <unistd.h>
#include <thread>

#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <memory>
#include <mutex>
#include <stdexcept>
#include <string>
#include <vector>

namespace {

constexpr double kPeriod = 1001.0 / 60000.0;

// Remembers what every field looked like when it reached the sink.
class RecordingSink final : public io::FrameSink {
  public:
    struct Seen {
        std::uint64_t index;
        io::FieldParity parity;
        double time;
        int lines;
        std::uint64_t checksum;
    };

    int open(const io::VideoFormat& format, std::string*) override {
        format_ = format;
        return 0;
    }
    int writeField(const io::FieldBuffer& field) override {
        if (failAt >= 0 && field.index == static_cast<std::uint64_t>(failAt)) return -28;  // ENOSPC
        std::uint64_t sum = 1469598103934665603ull;
        for (int l = 0; l < field.lines; ++l) {
            const std::uint8_t* row = field.data + l * field.stride;
            for (std::size_t i = 0; i < field.stride; ++i)
                sum = (sum ^ row[i]) * 1099511628211ull;
        }
        seen.push_back({field.index, field.parity, field.time, field.lines, sum});
        return 0;
    }
    int close(std::string*) override { return 0; }
    const io::VideoFormat& format() const override { return format_; }

    std::vector<Seen> seen;
    int failAt = -1;

  private:
    io::VideoFormat format_;
};

// Records the instants the field loop asks the simulation for.
class RecordingPoses final : public sim::PoseSource {
  public:
    explicit RecordingPoses(sim::PoseSource& inner) : inner_(inner) {}
    ig::Pose advanceTo(double t) override {
        fieldTimes.push_back(t);
        return inner_.advanceTo(t);
    }
    ig::Pose predict(double t) override { return inner_.predict(t); }
    double startTime() const override { return inner_.startTime(); }
    std::vector<double> fieldTimes;

  private:
    sim::PoseSource& inner_;
};

// A small map (3.8 km square) and a slow aircraft over its south-west, heading north-east.
struct World {
    ig::TerrainMap map = ig::makeSyntheticTerrain(128, 11, 30.0);
    sim::FlightLimits limits;
    sim::FlightState start;

    World() {
        limits.cruiseSpeed = 120.0;
        start = sim::startOverMap(map, limits);
    }

    std::unique_ptr<sim::StickFlight> flight(std::string_view script) {
        std::string error;
        auto stick = io::makeScriptedStick(script, "test.stick", &error);
        EXPECT_TRUE(stick) << error;
        return std::make_unique<sim::StickFlight>(std::move(stick), start, limits, &map);
    }

    sim::FrameRenderer renderer() {
        sim::RenderGeometry geometry;
        geometry.windowWidth = 128;
        geometry.windowHeight = 96;
        geometry.margin = 8;
        return sim::makeCasterRenderer(map, geometry);
    }
};

constexpr std::string_view kGentleScript =
    "0.5 axis roll 0.3 ramp 0.2\n"
    "1.0 axis roll 0 ramp 0.2\n"
    "2.0 axis pitch 0.3\n"
    "3.0 axis pitch 0\n";

struct PipelineRun {
    sim::PipelineResult result;
    std::vector<RecordingSink::Seen> seen;
    std::vector<double> fieldTimes;
    std::vector<sim::FieldRecord> records;
    std::vector<double> frameTimes;  // per field: the pose time of the frame it came from
};

PipelineRun runPipeline(World& world, sim::PipelineOptions options, std::string_view script,
                        const sim::FrameRenderer* renderer = nullptr) {
    auto flight = world.flight(script);
    RecordingPoses poses(*flight);
    RecordingSink sink;
    std::string error;
    sink.open({128, 96, io::PixelFormat::Uyvy}, &error);
    std::unique_ptr<io::FieldClock> clock =
        options.clock == sim::ClockMode::Simulated ? io::makeSimulatedClock() : io::makeWallClock();
    PipelineRun run;
    options.onField = [&](const prp::Field& field, const io::FieldBuffer&) {
        run.frameTimes.push_back(field.frameTime);
    };
    const sim::FrameRenderer own = renderer ? *renderer : world.renderer();
    sim::Pipeline pipeline(poses, own, sink, *clock, options);
    run.result = pipeline.run();
    run.seen = sink.seen;
    run.fieldTimes = poses.fieldTimes;
    run.records = pipeline.stats().records();
    return run;
}

TEST(Pipeline, SimulatedTenSecondsGivesEveryFieldAtItsInstant) {
    World world;
    sim::PipelineOptions options;
    options.clock = sim::ClockMode::Simulated;
    options.duration = 10.0;
    options.simulatedRenderHz = 6.0;  // few renders: this test is about the fields
    const PipelineRun run = runPipeline(world, options, kGentleScript);
    ASSERT_TRUE(run.result.ok()) << run.result.error;

    const std::size_t expected = static_cast<std::size_t>(std::lround(10.0 * 60000.0 / 1001.0));
    ASSERT_EQ(expected, 599u);
    ASSERT_EQ(run.seen.size(), expected);
    ASSERT_EQ(run.fieldTimes.size(), expected);
    EXPECT_EQ(run.result.stats.fields, expected);
    EXPECT_EQ(run.result.stats.missedDeadlines, 0u);
    const double t0 = world.start.time;
    const double renderPeriod = 1.0 / options.simulatedRenderHz;
    for (std::size_t n = 0; n < expected; ++n) {
        SCOPED_TRACE(n);
        EXPECT_EQ(run.seen[n].index, n);
        EXPECT_EQ(run.seen[n].parity, n % 2 == 0 ? io::FieldParity::Bottom : io::FieldParity::Top);
        EXPECT_EQ(run.seen[n].lines, 48);
        const double want = t0 + static_cast<double>(n) * kPeriod;
        EXPECT_NEAR(run.seen[n].time, want, 1e-9);
        EXPECT_NEAR(run.fieldTimes[n], want, 1e-9);  // the pose is the field's own instant
        // Each render aims at its completion, so a frame is never older than one render.
        const double age = run.seen[n].time - run.frameTimes[n];
        EXPECT_GE(age, -1e-9);
        EXPECT_LT(age, renderPeriod + 1e-9);
        EXPECT_NEAR(run.records[n].frameAge, age, 1e-9);
        // Simulated time: every field leaves exactly at its slot.
        EXPECT_NEAR(run.records[n].handoff - run.records[n].deadline, 0.0, 1e-12);
        EXPECT_EQ(run.records[n].offCpuMs, -1.0) << "no time off the processor, simulated";
        EXPECT_EQ(run.records[n].wakeLateMs, -1.0);
    }
    // Six renders a second, every one of them shown.
    EXPECT_NEAR(static_cast<double>(run.result.stats.framesRendered), 10.0 * 6.0, 1.0);
    EXPECT_GE(run.result.stats.framesShown, run.result.stats.framesRendered);
}

TEST(Pipeline, SimulatedRunsAreReproducible) {
    World world;
    sim::PipelineOptions options;
    options.clock = sim::ClockMode::Simulated;
    options.duration = 1.5;
    options.renderHz = 20.0;
    const PipelineRun a = runPipeline(world, options, kGentleScript);
    const PipelineRun b = runPipeline(world, options, kGentleScript);
    ASSERT_EQ(a.seen.size(), b.seen.size());
    for (std::size_t n = 0; n < a.seen.size(); ++n) {
        EXPECT_EQ(a.seen[n].checksum, b.seen[n].checksum) << n;
        EXPECT_EQ(a.records[n].frameSequence, b.records[n].frameSequence) << n;
        EXPECT_EQ(a.records[n].frameAge, b.records[n].frameAge) << n;
    }
    // Capped at 20 Hz: frames are never older than 1/20 s.
    for (const sim::FieldRecord& r : a.records)
        EXPECT_LT(r.frameAge, 0.05 + 1e-9);
}

TEST(Pipeline, StalledRendererNeverDelaysAField) {
    World world;
    sim::PipelineOptions options;
    options.clock = sim::ClockMode::Simulated;
    options.duration = 4.0;
    const std::uint64_t stalled = 20;  // starts at 19/12 s, about 1.6 s in
    options.renderStall = [&](std::uint64_t sequence) { return sequence == stalled ? 0.5 : 0.0; };
    const PipelineRun run = runPipeline(world, options, kGentleScript);
    ASSERT_TRUE(run.result.ok()) << run.result.error;
    const std::size_t expected = static_cast<std::size_t>(std::lround(4.0 / kPeriod));
    ASSERT_EQ(run.seen.size(), expected);
    EXPECT_EQ(run.result.stats.missedDeadlines, 0u);

    const double renderPeriod = 1.0 / options.simulatedRenderHz;
    double maxAge = 0.0;
    std::size_t staleFields = 0;
    for (std::size_t n = 0; n < run.records.size(); ++n) {
        const sim::FieldRecord& r = run.records[n];
        EXPECT_NEAR(r.handoff, r.deadline, 1e-12) << n;  // on time, stall or not
        EXPECT_NEAR(run.seen[n].time, static_cast<double>(n) * kPeriod, 1e-9);
        maxAge = std::max(maxAge, r.frameAge);
        if (r.frameAge > renderPeriod + 1e-9) ++staleFields;
    }
    // The stall shows as old frames: up to the stall plus one render, for as long (the stalled
    // frame itself arrives 0.5 s after the instant it was aimed at).
    EXPECT_GE(maxAge, 0.5);
    EXPECT_LT(maxAge, 0.5 + renderPeriod + 1e-9);
    EXPECT_NEAR(static_cast<double>(staleFields) * kPeriod, 0.5 + renderPeriod, 2 * kPeriod);
    EXPECT_NEAR(run.result.stats.frameAgeMs.max, maxAge * 1e3, 1e-6);
}

TEST(Pipeline, WallClockRendererStallShowsInFrameAge) {
    // Same loop on the wall clock with a real renderer thread. Only structure is asserted (the
    // machine may be busy): every field out in order, and the stall visible in the frame age.
    World world;
    sim::PipelineOptions options;
    options.clock = sim::ClockMode::Wall;
    options.duration = 0.6;
    options.renderThreads = 1;
    options.renderStall = [](std::uint64_t sequence) { return sequence == 3 ? 0.3 : 0.0; };
    const PipelineRun run = runPipeline(world, options, kGentleScript);
    ASSERT_TRUE(run.result.ok()) << run.result.error;
    const std::size_t expected = static_cast<std::size_t>(std::lround(0.6 / kPeriod));
    ASSERT_EQ(run.seen.size(), expected);
    for (std::size_t n = 0; n < expected; ++n) {
        EXPECT_EQ(run.seen[n].index, n);
        EXPECT_NEAR(run.fieldTimes[n], static_cast<double>(n) * kPeriod, 1e-9);
        if (n > 0) {
            EXPECT_GE(run.records[n].handoff, run.records[n - 1].handoff);
        }
        EXPECT_GE(run.records[n].handoff, run.records[n].deadline);
        EXPECT_GE(run.records[n].offCpuMs, 0.0) << "the time off the processor, measured";
        EXPECT_GE(run.records[n].wakeLateMs, 0.0) << "the wake's lateness, measured";
    }
    EXPECT_GE(run.result.stats.frameAgeMs.max, 250.0);
    EXPECT_GE(run.result.stats.framesRendered, 3u);
}

// A first frame that waits a second longer than its render (a renderer process's start, a
// paged map's tiles), then renders of 50 ms: the next frames are aimed their own render time
// ahead, not the first frame's second, so no field is warped from a frame of a pose far after
// its own.
TEST(Pipeline, ASlowFirstFrameDoesNotAimTheNextOnesAhead) {
    World world;
    sim::PipelineOptions options;
    options.clock = sim::ClockMode::Wall;
    options.duration = 1.0;
    options.renderThreads = 1;
    const sim::FrameRenderer inner = world.renderer();
    const sim::FrameRenderer waitsFirst = [inner](const ig::Pose& pose, double time,
                                                  std::uint64_t sequence) {
        std::this_thread::sleep_for(std::chrono::milliseconds(sequence == 0 ? 1000 : 50));
        return inner(pose, time, sequence);
    };
    const PipelineRun run = runPipeline(world, options, kGentleScript, &waitsFirst);
    ASSERT_TRUE(run.result.ok()) << run.result.error;
    ASSERT_EQ(run.frameTimes.size(), run.fieldTimes.size());
    double ahead = 0.0;
    for (std::size_t n = 0; n < run.frameTimes.size(); ++n)
        ahead = std::max(ahead, run.frameTimes[n] - run.fieldTimes[n]);
    std::printf("the most a field's frame was ahead of it: %.3f s\n", ahead);
    EXPECT_LT(ahead, 0.5) << "a field warped from a frame this many seconds after it";
    EXPECT_GE(run.result.stats.framesRendered, 3u);
}

TEST(Pipeline, SinkErrorStopsTheRun) {
    World world;
    auto flight = world.flight("");
    RecordingSink sink;
    std::string error;
    sink.open({128, 96, io::PixelFormat::Y8}, &error);
    sink.failAt = 10;
    auto clock = io::makeSimulatedClock();
    sim::PipelineOptions options;
    options.clock = sim::ClockMode::Simulated;
    options.duration = 1.0;
    sim::Pipeline pipeline(*flight, world.renderer(), sink, *clock, options);
    const sim::PipelineResult result = pipeline.run();
    EXPECT_FALSE(result.ok());
    EXPECT_EQ(result.sinkError, -28);
    EXPECT_NE(result.error.find("field 10"), std::string::npos) << result.error;
    EXPECT_EQ(sink.seen.size(), 10u);
}

TEST(Pipeline, RenderFailureIsReported) {
    World world;
    auto flight = world.flight("");
    RecordingSink sink;
    std::string error;
    sink.open({128, 96, io::PixelFormat::Uyvy}, &error);
    auto clock = io::makeSimulatedClock();
    sim::PipelineOptions options;
    options.clock = sim::ClockMode::Simulated;
    options.duration = 1.0;
    sim::FrameRenderer inner = world.renderer();
    sim::FrameRenderer failing = [&](const ig::Pose& pose, double t, std::uint64_t sequence) {
        if (sequence == 4) throw ig::InputError("test renderer: frame 4 refused");
        return inner(pose, t, sequence);
    };
    sim::Pipeline pipeline(*flight, failing, sink, *clock, options);
    EXPECT_THROW(pipeline.run(), ig::InputError);
}

TEST(Pipeline, BadFrameFromTheRendererThreadStopsTheRunCleanly) {
    // The PRP refuses a frame whose buffers do not match its intrinsics; with a live renderer
    // thread the run must still stop, join it and report (not terminate).
    World world;
    auto flight = world.flight("");
    RecordingSink sink;
    std::string error;
    sink.open({128, 96, io::PixelFormat::Uyvy}, &error);
    auto clock = io::makeWallClock();
    sim::PipelineOptions options;
    options.duration = 0.5;
    options.raiseFieldPriority = false;
    sim::FrameRenderer inner = world.renderer();
    sim::FrameRenderer broken = [&](const ig::Pose& pose, double t, std::uint64_t sequence) {
        ig::RenderedFrame frame = inner(pose, t, sequence);
        if (sequence >= 1) frame.color.resize(frame.color.size() / 2);
        return frame;
    };
    sim::Pipeline pipeline(*flight, broken, sink, *clock, options);
    EXPECT_THROW(pipeline.run(), ig::InputError);
}

TEST(FieldConversion, BuffersMatch) {
    prp::Field field;
    field.index = 7;
    field.parity = base::FieldParity::Top;
    field.time = 1.25;
    field.lines = 3;
    field.stride = 10;
    field.pixels.resize(30);
    const io::FieldBuffer b = sim::toFieldBuffer(field);
    EXPECT_EQ(b.index, 7u);
    EXPECT_EQ(b.parity, io::FieldParity::Top);
    EXPECT_EQ(b.time, 1.25);
    EXPECT_EQ(b.lines, 3);
    EXPECT_EQ(b.stride, 10u);
    EXPECT_EQ(b.data, field.pixels.data());
}

}  // namespace

namespace {

// SIGINT/SIGTERM reach the loop as PipelineOptions::stop: the field in hand is the last one, and
// the run is a good one (its outputs are finished), marked stopped.
TEST(Pipeline, AStopEndsTheRunAfterTheFieldInHand) {
    World world;
    std::atomic<bool> stop{false};
    sim::PipelineOptions options;
    options.clock = sim::ClockMode::Simulated;
    options.duration = 5.0;
    options.stop = &stop;
    auto flight = world.flight(kGentleScript);
    RecordingSink sink;
    std::string error;
    sink.open({128, 96, io::PixelFormat::Uyvy}, &error);
    auto clock = io::makeSimulatedClock();
    options.onField = [&](const prp::Field& field, const io::FieldBuffer&) {
        if (field.index == 30) stop = true;
    };
    sim::Pipeline pipeline(*flight, world.renderer(), sink, *clock, options);
    const sim::PipelineResult result = pipeline.run();
    EXPECT_TRUE(result.ok()) << result.error;
    EXPECT_TRUE(result.stopped);
    EXPECT_EQ(sink.seen.size(), 31u);
    EXPECT_EQ(result.stats.fields, 31u);
}

// A render rate far below the field rate: the run still ends on time. Wall clock: the
// renderer's wait for its next slot (20 s away) must end with the run; simulated: a render that
// could only complete after the run is never started (at 1e-6 Hz the pose source would
// otherwise be flown a million seconds ahead).
TEST(Pipeline, ASlowRenderRateNeverOutlastsTheRun) {
    World world;
    sim::PipelineOptions options;
    options.duration = 0.3;
    options.renderHz = 0.05;
    const auto start = std::chrono::steady_clock::now();
    const PipelineRun wall = runPipeline(world, options, kGentleScript);
    const double seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    EXPECT_TRUE(wall.result.ok());
    EXPECT_LT(seconds, 5.0) << "the renderer's rate-limit wait held the run";
    EXPECT_GE(wall.result.stats.framesRendered, wall.result.stats.framesShown);

    options.clock = sim::ClockMode::Simulated;
    options.renderHz = 1e-6;
    options.duration = 1.0;
    const PipelineRun simulated = runPipeline(world, options, kGentleScript);
    EXPECT_TRUE(simulated.result.ok());
    EXPECT_EQ(simulated.seen.size(), 60u);
    EXPECT_EQ(simulated.result.stats.framesRendered, 1u);  // frame 0 only
}

}  // namespace

// The renderer in a process of its own.

namespace renderer_process {

sim::PipelineOptions processOptions(double duration) {
    sim::PipelineOptions o;
    o.clock = sim::ClockMode::Simulated;
    o.duration = duration;
    o.simulatedRenderHz = 10.0;
    o.rendererMode = sim::RendererMode::Process;
    sim::RenderGeometry geometry;
    geometry.windowWidth = 128;
    geometry.windowHeight = 96;
    geometry.margin = 8;
    o.maxFramePixels = sim::maxFramePixels(geometry);
    o.prp.holdAfter = 0.3;
    return o;
}

TEST(RendererProcess, GivesTheFieldsTheThreadRendererGives) {
    World world;
    sim::PipelineOptions thread = processOptions(2.0);
    thread.rendererMode = sim::RendererMode::Thread;
    const PipelineRun a = runPipeline(world, thread, kGentleScript);
    const PipelineRun b = runPipeline(world, processOptions(2.0), kGentleScript);
    ASSERT_TRUE(a.result.ok() && b.result.ok()) << a.result.error << b.result.error;
    ASSERT_EQ(a.seen.size(), b.seen.size());
    for (std::size_t n = 0; n < a.seen.size(); ++n) {
        ASSERT_EQ(a.seen[n].checksum, b.seen[n].checksum) << "field " << n;
        ASSERT_EQ(a.frameTimes[n], b.frameTimes[n]) << "field " << n;
    }
    EXPECT_TRUE(b.result.stats.restarts.empty());
    EXPECT_EQ(a.result.stats.framesRendered, b.result.stats.framesRendered);
}

TEST(RendererProcess, FieldsGoOnThroughEveryFault) {
    struct Case {
        const char* fault;
        const char* cause;  // what the restart's cause must say
    };
    const Case cases[] = {
        {"crash@1", "killed by signal 9"},
        {"segv@1", ""},  // signal 11, or a sanitizer's report and exit
        {"exception@1", "injected renderer exception"},
        {"hang@1", "silent for"},
        {"stall@1:3000", "silent for"},
        {"garbage@1", "bad frame"},
    };
    World world;
    const double duration = 3.0;
    const std::size_t expected = static_cast<std::size_t>(std::lround(duration / kPeriod));
    for (const Case& c : cases) {
        SCOPED_TRACE(c.fault);
        sim::PipelineOptions o = processOptions(duration);
        o.fault = sim::parseRendererFault(c.fault, "--inject-renderer-fault");
        // Long enough that no render is taken for a hang on a loaded machine (a few renders of
        // a 144 x 112 frame), short enough to keep the test quick.
        o.renderTimeout = 1.0;
        const PipelineRun run = runPipeline(world, o, kGentleScript);
        ASSERT_TRUE(run.result.ok()) << run.result.error;
        // Every field, each at its own instant: none missing, none late.
        ASSERT_EQ(run.seen.size(), expected);
        for (std::size_t n = 0; n < expected; ++n) {
            ASSERT_EQ(run.seen[n].index, n);
            ASSERT_NEAR(run.seen[n].time, world.start.time + static_cast<double>(n) * kPeriod,
                        1e-9);
        }
        EXPECT_EQ(run.result.stats.missedDeadlines, 0u);
        // One restart, its cause and its gap reported.
        ASSERT_EQ(run.result.stats.restarts.size(), 1u);
        const sim::RendererRestart& r = run.result.stats.restarts[0];
        EXPECT_NE(r.cause.find(c.cause), std::string::npos) << r.cause;
        EXPECT_NEAR(r.detected - world.start.time, 1.0, 0.2);
        // The lost frame, the modelled restart and the next render: 0.1 + 0.25 + 0.1 s.
        EXPECT_GT(r.gapSeconds, 0.3);
        EXPECT_LT(r.gapSeconds, 0.6);
        EXPECT_GT(r.recoverySeconds, 0.0);
        EXPECT_GT(r.fieldsExtrapolated + r.fieldsHeld, 15u);
        // Fresh frames again after the restart, to the end of the run.
        EXPECT_GT(run.frameTimes.back(), world.start.time + duration - 0.25);
    }
}

// The run's first renderer may take longer than a restart's allowance for frame 0 (a loaded
// host, a cold start): no field waits on it yet, so it is awaited, not taken for a hang.
TEST(RendererProcess, TheRunsFirstStartIsAwaitedPastARestartsAllowance) {
    World world;
    const sim::FrameRenderer inner = world.renderer();
    const sim::FrameRenderer slowFrameZero = [inner](const ig::Pose& pose, double time,
                                                     std::uint64_t sequence) {
        if (sequence == 0) std::this_thread::sleep_for(std::chrono::milliseconds(1500));
        return inner(pose, time, sequence);
    };
    sim::PipelineOptions o = processOptions(1.0);
    o.renderTimeout = 0.1;  // a restart's allowance: ten of them, 1 s
    const PipelineRun run = runPipeline(world, o, kGentleScript, &slowFrameZero);
    ASSERT_TRUE(run.result.ok()) << run.result.error;
    ASSERT_FALSE(run.frameTimes.empty());
    EXPECT_EQ(run.frameTimes.front(), world.start.time);
}

// On the simulated clock no field waits on a render: one slowed by a loaded host (here 1 s,
// twice the wall clock's 500 ms floor) is awaited with the default timeout, not taken for a
// hang that would cost a modelled restart and change the run's fields.
TEST(RendererProcess, ASlowRenderOnTheSimulatedClockIsNotARestart) {
    World world;
    const sim::FrameRenderer inner = world.renderer();
    const sim::FrameRenderer slowFrame = [inner](const ig::Pose& pose, double time,
                                                 std::uint64_t sequence) {
        if (sequence == 3) std::this_thread::sleep_for(std::chrono::milliseconds(1000));
        return inner(pose, time, sequence);
    };
    const sim::PipelineOptions o = processOptions(1.0);
    ASSERT_EQ(o.renderTimeout, 0.0);  // the default
    const PipelineRun run = runPipeline(world, o, kGentleScript, &slowFrame);
    ASSERT_TRUE(run.result.ok()) << run.result.error;
    EXPECT_TRUE(run.result.stats.restarts.empty()) << run.result.stats.restarts[0].cause;
}

// A render that takes far longer than the render timeout but shows signs of life as it goes
// (sim::noteRendererAlive: a paged map placing a frame's tiles for seconds) is awaited; the
// same render silent throughout is taken for a hang and restarted.
TEST(RendererProcess, ASlowRenderThatShowsSignsOfLifeIsNotAHang) {
    World world;
    const sim::FrameRenderer inner = world.renderer();
    const auto slowFrame = [inner](bool alive) -> sim::FrameRenderer {
        return [inner, alive](const ig::Pose& pose, double time, std::uint64_t sequence) {
            if (sequence == 3) {
                for (int i = 0; i < 75; ++i) {
                    std::this_thread::sleep_for(std::chrono::milliseconds(20));
                    if (alive) sim::noteRendererAlive(sim::RenderStep::Written);
                }
            }
            return inner(pose, time, sequence);
        };
    };
    // The simulated clock waits for each frame; the wall clock's supervisor watches the ring.
    for (const sim::ClockMode clock : {sim::ClockMode::Simulated, sim::ClockMode::Wall}) {
        SCOPED_TRACE(clock == sim::ClockMode::Wall ? "wall clock" : "simulated clock");
        sim::PipelineOptions o = processOptions(2.0);
        o.clock = clock;
        o.renderTimeout = 0.4;  // the 1.5 s render is nearly four of them
        const sim::FrameRenderer alive = slowFrame(true);
        const PipelineRun awaited = runPipeline(world, o, kGentleScript, &alive);
        ASSERT_TRUE(awaited.result.ok()) << awaited.result.error;
        EXPECT_TRUE(awaited.result.stats.restarts.empty())
            << awaited.result.stats.restarts[0].cause;
        const sim::FrameRenderer silent = slowFrame(false);
        const PipelineRun restarted = runPipeline(world, o, kGentleScript, &silent);
        ASSERT_TRUE(restarted.result.ok()) << restarted.result.error;
        ASSERT_FALSE(restarted.result.stats.restarts.empty());
        EXPECT_NE(restarted.result.stats.restarts[0].cause.find("silent for"), std::string::npos)
            << restarted.result.stats.restarts[0].cause;
    }
    // In the field process (no renderer process) a sign of life is nothing.
    sim::noteRendererAlive(sim::RenderStep::Written);
}

// A renderer that shows signs of life for a while and then falls silent is restarted, and the
// cause says after which step it fell silent.
TEST(RendererProcess, TheRestartSaysAfterWhichStepTheRendererFellSilent) {
    World world;
    const sim::FrameRenderer inner = world.renderer();
    const sim::FrameRenderer stuck = [inner](const ig::Pose& pose, double time,
                                             std::uint64_t sequence) {
        if (sequence == 3) {
            for (int i = 0; i < 5; ++i) {
                std::this_thread::sleep_for(std::chrono::milliseconds(20));
                sim::noteRendererAlive(sim::RenderStep::Backed);
            }
            std::this_thread::sleep_for(std::chrono::milliseconds(1500));
        }
        return inner(pose, time, sequence);
    };
    for (const sim::ClockMode clock : {sim::ClockMode::Simulated, sim::ClockMode::Wall}) {
        SCOPED_TRACE(clock == sim::ClockMode::Wall ? "wall clock" : "simulated clock");
        sim::PipelineOptions o = processOptions(2.0);
        o.clock = clock;
        o.renderTimeout = 0.4;
        const PipelineRun run = runPipeline(world, o, kGentleScript, &stuck);
        ASSERT_TRUE(run.result.ok()) << run.result.error;
        ASSERT_FALSE(run.result.stats.restarts.empty());
        EXPECT_NE(run.result.stats.restarts[0].cause.find("silent for"), std::string::npos)
            << run.result.stats.restarts[0].cause;
        EXPECT_NE(run.result.stats.restarts[0].cause.find("after pages backed"), std::string::npos)
            << run.result.stats.restarts[0].cause;
    }
}

// The supervisor counts the renderer's silence only while it watched: a look long after the one
// before (the supervising thread itself not run: a loaded or paused host) counts at most
// kMaxLookGapNs of the gap; looks a few milliseconds apart count a hang in full; a sign of life
// starts a new silence.
TEST(RendererProcess, TheSilenceWatchedLeavesOutTheTimeTheSupervisorDidNotRun) {
    constexpr std::int64_t ms = 1'000'000;
    const std::int64_t maxGap = sim::SilenceWatch::kMaxLookGapNs;
    sim::SilenceWatch hang;
    std::int64_t silent = 0;
    for (std::int64_t t = 2 * ms; t <= 600 * ms; t += 2 * ms)
        silent = hang.look(t, 0);
    EXPECT_EQ(silent, 600 * ms);
    EXPECT_EQ(hang.unwatchedNs(), 0);
    sim::SilenceWatch paused;
    EXPECT_EQ(paused.look(10 * ms, 0), 10 * ms);
    EXPECT_EQ(paused.look(12 * ms, 0), 12 * ms);
    // The supervisor away 600 ms: all but kMaxLookGapNs of it unwatched.
    EXPECT_EQ(paused.look(612 * ms, 0), 12 * ms + maxGap);
    EXPECT_EQ(paused.unwatchedNs(), 600 * ms - maxGap);
    EXPECT_EQ(paused.look(614 * ms, 0), 14 * ms + maxGap);
    // A sign of life came while the supervisor was away again: only the part after it counts.
    EXPECT_EQ(paused.look(1000 * ms, 900 * ms), maxGap);
    EXPECT_EQ(paused.look(1002 * ms, 900 * ms), maxGap + 2 * ms);
    // One just before the look: counted in full.
    EXPECT_EQ(paused.look(1010 * ms, 1005 * ms), 5 * ms);
    EXPECT_EQ(paused.unwatchedNs(), 0);
}

// The renderer's longest silence between two signs of life, with the steps it lay between; the
// next measure starts over.
TEST(RendererProcess, TheLongestSilenceIsMeasuredBetweenSteps) {
    (void)sim::takeRendererSilence();
    sim::noteRendererAlive(sim::RenderStep::Request);
    (void)sim::takeRendererSilence();
    sim::noteRendererAlive(sim::RenderStep::Footprint);
    sim::noteRendererAlive(sim::RenderStep::Requested);
    std::this_thread::sleep_for(std::chrono::milliseconds(300));
    sim::noteRendererAlive(sim::RenderStep::Released);
    sim::noteRendererAlive(sim::RenderStep::Cast);
    const sim::RendererSilence s = sim::takeRendererSilence();
    EXPECT_GE(s.ms, 300.0);
    EXPECT_EQ(s.after, sim::RenderStep::Requested);
    EXPECT_EQ(s.until, sim::RenderStep::Released);
    EXPECT_STREQ(sim::renderStepName(s.after), "tiles requested");
    const sim::RendererSilence none = sim::takeRendererSilence();
    EXPECT_EQ(none.ms, 0.0);
}

// A renderer whose first frame in each process is slow (a paged map reads its first view's
// tiles, waiting) is given its start allowance after a restart too, not the render timeout:
// one restart, not one per timeout until a start happens to be quick enough.
TEST(RendererProcess, ARestartedRendererGetsItsStartAllowance) {
    World world;
    const sim::FrameRenderer inner = world.renderer();
    auto started = std::make_shared<pid_t>(-1);
    const sim::FrameRenderer slowStart = [inner, started](const ig::Pose& pose, double time,
                                                          std::uint64_t sequence) {
        if (*started != ::getpid()) {
            *started = ::getpid();
            std::this_thread::sleep_for(std::chrono::milliseconds(1200));
        }
        return inner(pose, time, sequence);
    };
    sim::PipelineOptions o = processOptions(3.0);
    o.fault = sim::parseRendererFault("crash@1", "--inject-renderer-fault");
    o.renderTimeout = 0.4;  // the start allowance: ten of them
    const PipelineRun run = runPipeline(world, o, kGentleScript, &slowStart);
    ASSERT_TRUE(run.result.ok()) << run.result.error;
    ASSERT_EQ(run.result.stats.restarts.size(), 1u) << run.result.stats.restarts.back().cause;
    EXPECT_NE(run.result.stats.restarts[0].cause.find("killed by signal 9"), std::string::npos);
    EXPECT_EQ(run.result.stats.missedDeadlines, 0u);
    EXPECT_GT(run.frameTimes.back(), world.start.time + 3.0 - 0.25);
    // A renderer silent past the allowance is still restarted: a hang at its first frame.
    o.startTimeout = 0.8;
    try {
        runPipeline(world, o, kGentleScript, &slowStart);
        ADD_FAILURE() << "a first frame past the start allowance was awaited";
    } catch (const std::runtime_error& e) {
        EXPECT_NE(std::string(e.what()).find("gave no first frame"), std::string::npos) << e.what();
    }
}

// The renderer process is forked while the field process's background threads work (tile
// loaders, the ground's pager, the truth writer): none is in the middle of its work at the fork,
// so the child never finds a lock of theirs held (base/fork_gate.hpp). Here a background thread
// holds, for nearly all of its time, a lock the renderer also takes, and allocates as a tile
// loader does: a child forked while it worked would wait on that lock for ever.
TEST(RendererProcess, IsNeverForkedWhileABackgroundThreadWorks) {
    World world;
    const sim::FrameRenderer inner = world.renderer();
    auto shared = std::make_shared<std::mutex>();
    // Stopped and joined on every way out of the test.
    struct Busy {
        std::atomic<bool> stop{false};
        std::atomic<int> pieces{0};
        std::thread thread;
        ~Busy() {
            stop = true;
            if (thread.joinable()) thread.join();
        }
    } busy;
    busy.thread = std::thread([&busy, shared] {
        while (!busy.stop.load()) {
            const base::ForkGate::Working working;
            const std::lock_guard lock(*shared);
            std::vector<unsigned char> tile(7493, 1);
            std::this_thread::sleep_for(std::chrono::milliseconds(2));
            busy.pieces.fetch_add(tile[0]);
        }
    });
    const sim::FrameRenderer locking = [inner, shared](const ig::Pose& pose, double time,
                                                       std::uint64_t sequence) {
        { const std::lock_guard lock(*shared); }
        return inner(pose, time, sequence);
    };
    sim::PipelineOptions o = processOptions(1.0);
    o.fault = sim::parseRendererFault("crash@0.5", "--inject-renderer-fault");
    o.renderTimeout = 0.3;
    o.startTimeout = 3.0;
    for (int run = 0; run < 4; ++run) {  // eight forks
        const PipelineRun r = runPipeline(world, o, kGentleScript, &locking);
        ASSERT_TRUE(r.result.ok()) << "run " << run << ": " << r.result.error;
        ASSERT_EQ(r.result.stats.restarts.size(), 1u)
            << "run " << run << ": " << r.result.stats.restarts.back().cause;
        EXPECT_EQ(r.result.stats.missedDeadlines, 0u);
    }
    EXPECT_GT(busy.pieces.load(), 0);
}

TEST(RendererProcess, FaultSpecificationsAreCheckedAndDescribed) {
    const sim::RendererFault f = sim::parseRendererFault("stall@2.5:500", "--f");
    EXPECT_EQ(f.kind, sim::RendererFault::Kind::Stall);
    EXPECT_EQ(f.at, 2.5);
    EXPECT_EQ(f.stallSeconds, 0.5);
    EXPECT_EQ(sim::describeRendererFault(f), "stall@2.5:500");
    EXPECT_EQ(sim::parseRendererFault("hang@0", "--f").kind, sim::RendererFault::Kind::Hang);
    for (const char* bad : {"", "crash", "crash@", "crash@-1", "crash@nan", "boom@1", "stall@1",
                            "stall@1:x", "segv@1e20"}) {
        try {
            sim::parseRendererFault(bad, "--inject-renderer-fault");
            ADD_FAILURE() << "accepted " << bad;
        } catch (const ig::InputError& e) {
            EXPECT_NE(std::string(e.what()).find("--inject-renderer-fault"), std::string::npos);
        }
    }
}

}  // namespace renderer_process
