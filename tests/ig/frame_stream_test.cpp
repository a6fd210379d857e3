// Consecutive frames over one worker pool, the next frame started while the last finishes:
// every frame must be the one renderFrame gives.
#include "ig/frame_stream.hpp"

#include "ig/caster.hpp"
#include "ig/error.hpp"
#include "ig/synthetic.hpp"

#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <cstring>
#include <stdexcept>
#include <thread>
#include <utility>
#include <vector>

namespace {

using ig::CasterKind;
using ig::Intrinsics;
using ig::Pose;
using ig::RenderedFrame;
using ig::TerrainMap;

const TerrainMap& terrain() {
    static const TerrainMap map = ig::makeSyntheticTerrain(512, 11, 10.0);
    return map;
}

// A slow straight flight over the map, 300 m above the ground at the start.
std::vector<Pose> flight(int frames) {
    const TerrainMap& map = terrain();
    std::vector<Pose> poses;
    for (int i = 0; i < frames; ++i) {
        Pose p;
        p.position = {1500.0 + 40.0 * i, 1200.0 + 30.0 * i, 0.0};
        p.position.z = map.surfaceHeight(1500.0, 1200.0) + 300.0;
        p.yaw = ig::degToRad(40.0 + i);
        p.pitch = ig::degToRad(-8.0);
        poses.push_back(p);
    }
    return poses;
}

void expectSame(const RenderedFrame& a, const RenderedFrame& b) {
    ASSERT_EQ(a.sequence, b.sequence);
    ASSERT_TRUE(a.color == b.color) << "frame " << a.sequence;
    ASSERT_EQ(0, std::memcmp(a.depth.data(), b.depth.data(), a.depth.size() * sizeof(float)));
    EXPECT_EQ(a.stats.steps, b.stats.steps);
    EXPECT_EQ(a.stats.restarts, b.stats.restarts);
    for (int i = 0; i < ig::kControlPointCount; ++i) {
        EXPECT_EQ(a.controlPoints[i].world, b.controlPoints[i].world);
        EXPECT_EQ(a.controlPoints[i].pixel, b.controlPoints[i].pixel);
    }
}

TEST(FrameStream, OverlappedFramesAreTheFramesRenderFrameGives) {
    const TerrainMap& map = terrain();
    const Intrinsics in = Intrinsics::fromFov(203, 120, ig::degToRad(60), 4);
    const std::vector<Pose> poses = flight(6);
    for (int levels : {0, ig::kLevelsAuto}) {
        ig::RenderOptions options;
        options.levels = levels;
        const auto caster = ig::makeCaster(CasterKind::Fast, map, options);
        for (int threads : {1, 2, 4}) {
            ig::FrameStream stream(*caster, map, threads);
            stream.submit(poses[0], in, 0.0, 0);
            for (std::size_t i = 0; i < poses.size(); ++i) {
                stream.help();
                if (i + 1 < poses.size()) stream.submit(poses[i + 1], in, 0.1 * (i + 1), i + 1);
                const RenderedFrame got = stream.take();
                const RenderedFrame want = ig::renderFrame(*caster, map, poses[i], in, 0.1 * i, i);
                expectSame(got, want);
                EXPECT_EQ(got.time, want.time);
            }
            EXPECT_EQ(stream.inFlight(), 0);
        }
    }
}

TEST(FrameStream, ManyFramesInFlightComeOutInOrder) {
    const TerrainMap& map = terrain();
    const Intrinsics in = Intrinsics::fromFov(96, 64, ig::degToRad(60), 4);
    const auto caster = ig::makeCaster(CasterKind::Naive, map);  // rows as work units
    const std::vector<Pose> poses = flight(5);
    ig::FrameStream stream(*caster, map, 3);
    for (std::size_t i = 0; i < poses.size(); ++i)
        stream.submit(poses[i], in, 0.0, i);
    EXPECT_EQ(stream.inFlight(), 5);
    for (std::size_t i = 0; i < poses.size(); ++i) {
        expectSame(stream.take(), ig::renderFrame(*caster, map, poses[i], in, 0.0, i));
    }
}

// Taking a frame when none is in flight is a caller's bug: CHECKed.
TEST(FrameStream, TakingWithNothingInFlightIsABug) {
    GTEST_FLAG_SET(death_test_style, "threadsafe");
    const TerrainMap& map = terrain();
    const auto caster = ig::makeCaster(CasterKind::Fast, map);
    EXPECT_DEATH(
        {
            ig::FrameStream stream(*caster, map, 2);
            (void)stream.take();
        },
        "no frame in flight");
}

TEST(FrameStream, BadInputIsRefusedAndTheStreamGoesOn) {
    const TerrainMap& map = terrain();
    const Intrinsics in = Intrinsics::fromFov(64, 48, ig::degToRad(60), 4);
    const auto caster = ig::makeCaster(CasterKind::Fast, map);
    ig::FrameStream stream(*caster, map, 2);
    Pose below = flight(1)[0];
    below.position.z = map.surfaceHeight(below.position.x, below.position.y) - 5.0;
    EXPECT_THROW(stream.submit(below, in), ig::InputError);
    Pose nan = flight(1)[0];
    nan.pitch = std::nan("");
    EXPECT_THROW(stream.submit(nan, in), ig::InputError);
    EXPECT_EQ(stream.inFlight(), 0);
    // The fast caster refuses roll, as bad input, before the frame is in flight.
    Pose rolled = flight(1)[0];
    rolled.roll = 0.2;
    EXPECT_THROW(stream.submit(rolled, in), ig::InputError);
    EXPECT_EQ(stream.inFlight(), 0);
    stream.submit(flight(1)[0], in, 0.0, 7);
    expectSame(stream.take(), ig::renderFrame(*caster, map, flight(1)[0], in, 0.0, 7));
}

// A caster that counts the work units it renders, each taking a little while, so frames are
// still in flight when the stream is destroyed.
class CountingCaster final : public ig::Caster {
  public:
    explicit CountingCaster(const ig::Caster& inner) : inner_(inner) {}
    CasterKind kind() const override { return inner_.kind(); }
    void render(const ig::Camera& camera, RenderedFrame& frame) const override {
        inner_.render(camera, frame);
    }
    int workUnits(const ig::Camera& camera) const override { return inner_.workUnits(camera); }
    void renderUnit(const ig::Camera& camera, RenderedFrame& frame, int unit,
                    ig::UnitCounters& counters) const override {
        std::this_thread::sleep_for(std::chrono::microseconds(200));
        inner_.renderUnit(camera, frame, unit, counters);
        units.fetch_add(1, std::memory_order_relaxed);
    }
    std::pair<int, int> unitColumns(const ig::Camera& camera, int unit) const override {
        return inner_.unitColumns(camera, unit);
    }
    mutable std::atomic<int> units{0};

  private:
    const ig::Caster& inner_;
};

TEST(FrameStream, FramesLeftInFlightAreFinishedOnDestruction) {
    const TerrainMap& map = terrain();
    const Intrinsics in = Intrinsics::fromFov(64, 48, ig::degToRad(60), 4);
    const auto inner = ig::makeCaster(CasterKind::Fast, map);
    const std::vector<Pose> poses = flight(3);
    int unitsPerFlight = 0;
    for (const Pose& p : poses)
        unitsPerFlight += inner->workUnits(ig::Camera(p, in));
    ASSERT_GT(unitsPerFlight, 3);
    for (int threads : {1, 2}) {
        CountingCaster caster(*inner);
        {
            ig::FrameStream stream(caster, map, threads);
            for (const Pose& p : poses)
                stream.submit(p, in);
            EXPECT_EQ(stream.inFlight(), 3);
            EXPECT_LT(caster.units.load(), unitsPerFlight) << "nothing left in flight to test";
        }  // the destructor waits for every unit of every frame (and frees nothing in use:
           // ASan, TSan)
        EXPECT_EQ(caster.units.load(), unitsPerFlight) << threads << " threads";
        std::this_thread::sleep_for(std::chrono::milliseconds(20));
        EXPECT_EQ(caster.units.load(), unitsPerFlight) << "a worker outlived the stream";
    }
}

}  // namespace
