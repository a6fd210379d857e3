// The automatic warp choice on the shipped low, fast trajectory near terrain.
#include "ig/caster.hpp"
#include "ig/cli.hpp"
#include "io/field_clock.hpp"
#include "io/frame_sink.hpp"
#include "prp/evaluation.hpp"
#include "sim/pipeline.hpp"
#include "sim/trajectory.hpp"
#include "sim/trajectory_poses.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <string>
#include <vector>

namespace {

const std::string kLow = std::string(VIG_DATA_DIR) + "/trajectories/low.csv";

const ig::TerrainMap& pugetSound() {
    static const ig::TerrainMap map = ig::loadTerrainFromOptions(ig::TerrainOptions{});
    return map;
}

// At every horizon auto is no worse than the better of the quadratic and the depth warp alone,
// within 0.25 dB (it picks one of the two per field, by the quadratic's error on check points,
// not by the truth), and far better than the quadratic where parallax is large; twice the same
// evaluation gives the same figures and choices.
TEST(AutoWarp, NoWorseThanTheBetterModelLowOverTerrain) {
    const sim::Trajectory low = sim::Trajectory::loadCsv(kLow);
    const auto fast = ig::makeCaster(ig::CasterKind::Fast, pugetSound());
    const auto reference = ig::makeCaster(ig::CasterKind::Reference, pugetSound());
    prp::EvalConfig config;
    config.width = 160;
    config.height = 120;
    config.margin = 16;
    config.horizons = {1, 2, 4, 8};
    config.models = {prp::WarpModel::Poly, prp::WarpModel::Depth, prp::WarpModel::Auto};
    config.baseFrames = 2;
    config.timingRepeats = 1;
    auto run = [&] {
        return prp::evaluateWarps(
            pugetSound(), *fast, *reference, [&](double t) { return low.poseAt(t); },
            low.startTime(), low.endTime(), config);
    };
    const prp::EvalResult r = run();
    const std::size_t nk = config.horizons.size();
    ASSERT_EQ(r.cells.size(), 3 * nk);
    for (std::size_t k = 0; k < nk; ++k) {
        const prp::EvalCell& poly = r.cells[k];
        const prp::EvalCell& depth = r.cells[nk + k];
        const prp::EvalCell& autoCell = r.cells[2 * nk + k];
        EXPECT_GE(autoCell.psnrDb, std::max(poly.psnrDb, depth.psnrDb) - 0.25)
            << "k " << config.horizons[k] << ": poly " << poly.psnrDb << " depth " << depth.psnrDb
            << " auto " << autoCell.psnrDb;
    }
    EXPECT_GT(r.cells[3 * nk - 1].psnrDb, r.cells[nk - 1].psnrDb + 3.0);  // k = 8 vs poly
    const prp::EvalResult again = run();
    for (std::size_t i = 0; i < r.cells.size(); ++i) {
        EXPECT_EQ(again.cells[i].psnrDb, r.cells[i].psnrDb);
        EXPECT_EQ(again.cells[i].depthFields, r.cells[i].depthFields);
    }
}

// Under the simulated clock the pipeline's per-field choices (and fields) are the same run to
// run, and are recorded in the statistics.
TEST(AutoWarp, ChoiceIsDeterministicUnderTheSimulatedClock) {
    sim::RenderGeometry geometry;
    geometry.windowWidth = 160;
    geometry.windowHeight = 120;
    geometry.margin = 16;
    auto once = [&](std::vector<prp::WarpModel>& models, std::vector<std::uint64_t>& sums) {
        sim::TrajectoryPoses poses(sim::Trajectory::loadCsv(kLow));
        std::string error;
        auto sink = io::makeSink("null", &error);
        if (!sink) return sim::StatsSummary{};
        io::VideoFormat format;
        format.width = 160;
        format.height = 120;
        sink->open(format, &error);
        auto clock = io::makeSimulatedClock();
        sim::PipelineOptions options;
        options.clock = sim::ClockMode::Simulated;
        options.duration = 0.5;
        options.prp.outWidth = 160;
        options.prp.outHeight = 120;
        options.prp.model = prp::WarpModel::Auto;
        options.onField = [&](const prp::Field& field, const io::FieldBuffer&) {
            models.push_back(field.warp.model);
            std::uint64_t sum = 1469598103934665603ull;
            for (const std::uint8_t b : field.pixels)
                sum = (sum ^ b) * 1099511628211ull;
            sums.push_back(sum);
        };
        sim::Pipeline pipeline(poses, sim::makeCasterRenderer(pugetSound(), geometry), *sink,
                               *clock, options);
        return pipeline.run().stats;
    };
    std::vector<prp::WarpModel> m1, m2;
    std::vector<std::uint64_t> s1, s2;
    const sim::StatsSummary a = once(m1, s1);
    once(m2, s2);
    ASSERT_FALSE(m1.empty());
    EXPECT_EQ(m1, m2);
    EXPECT_EQ(s1, s2);
    const auto depth = static_cast<std::size_t>(prp::WarpModel::Depth);
    const auto poly = static_cast<std::size_t>(prp::WarpModel::Poly);
    EXPECT_EQ(a.fieldsByModel[depth] + a.fieldsByModel[poly], a.fields);
    EXPECT_EQ(a.fieldsByModel[depth],
              static_cast<std::uint64_t>(std::count(m1.begin(), m1.end(), prp::WarpModel::Depth)));
}

}  // namespace
