// Ray caster benchmark: naive vs fast on Puget Sound at 720x486 and 1920x1080, one thread.
// Counters: ns per pixel, steps per pixel, and the error against the reference caster (mean
// absolute colour error in % of full scale, computed once per case outside the timing).
#include "ig/caster.hpp"
#include "ig/image_compare.hpp"
#include "ig/pose_sweep.hpp"
#include "ig/terrain_io.hpp"

#include <benchmark/benchmark.h>

#include <map>
#include <memory>
#include <string>

namespace {

const ig::TerrainMap& puget() {
    static const ig::TerrainMap map = ig::loadPugetSound();
    return map;
}

// A flight view: 300 m above the ground, heading north-east, 5 degrees down.
ig::Pose flightPose() {
    ig::Pose p;
    p.position = {30000.0, 20000.0, 0.0};
    p.position.z = puget().surfaceHeight(p.position.x, p.position.y) + 300.0;
    p.yaw = ig::degToRad(45.0);
    p.pitch = ig::degToRad(-5.0);
    return p;
}

double errorAgainstReference(const ig::RenderedFrame& frame, const ig::Intrinsics& in) {
    static std::map<std::pair<int, int>, ig::RenderedFrame> cache;
    auto key = std::make_pair(in.width, in.height);
    auto it = cache.find(key);
    if (it == cache.end()) {
        const auto reference = ig::makeCaster(ig::CasterKind::Reference, puget());
        it = cache.emplace(key, ig::renderFrame(*reference, puget(), flightPose(), in)).first;
    }
    return ig::meanAbsErrorPct(frame.color, it->second.color);
}

void BM_Caster(benchmark::State& state, ig::CasterKind kind) {
    const int w = static_cast<int>(state.range(0)), h = static_cast<int>(state.range(1));
    const ig::Intrinsics in = ig::Intrinsics::fromFov(w, h, ig::degToRad(60.0));
    ig::RenderOptions options;
    options.threads = 1;
    const auto caster = ig::makeCaster(kind, puget(), options);
    ig::RenderedFrame frame;
    for (auto _ : state) {
        frame = ig::renderFrame(*caster, puget(), flightPose(), in);
        benchmark::DoNotOptimize(frame.color.data());
    }
    const double pixels = static_cast<double>(w) * h;
    // Seconds per pixel (shown with an SI prefix, e.g. "65n" = 65 ns).
    state.counters["s_per_pixel"] = benchmark::Counter(
        pixels, benchmark::Counter::kIsIterationInvariantRate | benchmark::Counter::kInvert);
    state.counters["steps_per_pixel"] = static_cast<double>(frame.stats.steps) / pixels;
    state.counters["restarts_per_pixel"] = static_cast<double>(frame.stats.restarts) / pixels;
    state.counters["mae_pct_vs_reference"] = errorAgainstReference(frame, in);
}

// The whole 50-pose accuracy sweep (5 m .. 20 km above ground, pitch +10 .. -85 degrees).
void BM_CasterSweep(benchmark::State& state, ig::CasterKind kind) {
    const int w = static_cast<int>(state.range(0)), h = static_cast<int>(state.range(1));
    const ig::Intrinsics in = ig::Intrinsics::fromFov(w, h, ig::degToRad(60.0));
    ig::RenderOptions options;
    options.threads = 1;
    const auto caster = ig::makeCaster(kind, puget(), options);
    const auto poses = ig::sweepPoses(puget(), 50);
    std::uint64_t steps = 0;
    for (auto _ : state) {
        steps = 0;
        for (const ig::Pose& pose : poses) {
            const auto frame = ig::renderFrame(*caster, puget(), pose, in);
            steps += frame.stats.steps;
            benchmark::DoNotOptimize(frame.color.data());
        }
    }
    const double pixels = static_cast<double>(w) * h * poses.size();
    state.counters["s_per_pixel"] = benchmark::Counter(
        pixels, benchmark::Counter::kIsIterationInvariantRate | benchmark::Counter::kInvert);
    state.counters["steps_per_pixel"] = static_cast<double>(steps) / pixels;
}

BENCHMARK_CAPTURE(BM_CasterSweep, naive, ig::CasterKind::Naive)
    ->Args({720, 486})
    ->Unit(benchmark::kMillisecond)
    ->Iterations(1);
BENCHMARK_CAPTURE(BM_CasterSweep, fast, ig::CasterKind::Fast)
    ->Args({720, 486})
    ->Unit(benchmark::kMillisecond)
    ->Iterations(3);

BENCHMARK_CAPTURE(BM_Caster, naive, ig::CasterKind::Naive)
    ->Args({720, 486})
    ->Args({1920, 1080})
    ->Unit(benchmark::kMillisecond)
    ->MinTime(1.0);
BENCHMARK_CAPTURE(BM_Caster, fast, ig::CasterKind::Fast)
    ->Args({720, 486})
    ->Args({1920, 1080})
    ->Unit(benchmark::kMillisecond)
    ->MinTime(1.0);

}  // namespace

BENCHMARK_MAIN();
