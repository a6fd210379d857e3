#include "sim/stats.hpp"

#include <nlohmann/json.hpp>

#include <gtest/gtest.h>

#include <algorithm>
#include <random>
#include <string>

namespace {

TEST(Percentiles, NearestRankOnKnownSets) {
    for (int n : {1, 2, 10, 100, 1000}) {
        std::vector<double> v;
        for (int i = 1; i <= n; ++i)
            v.push_back(i);
        std::shuffle(v.begin(), v.end(), std::mt19937(n));
        const sim::Percentiles p = sim::percentiles(v);
        EXPECT_EQ(p.max, n);
        EXPECT_EQ(p.p50, std::ceil(0.5 * n));
        EXPECT_EQ(p.p99, std::ceil(0.99 * n));
        EXPECT_EQ(p.p999, std::ceil(0.999 * n));
        EXPECT_LE(p.p50, p.p99);
        EXPECT_LE(p.p99, p.p999);
    }
    const sim::Percentiles empty = sim::percentiles({});
    EXPECT_EQ(empty.max, 0.0);
}

TEST(StatsCollector, CountsMissesFramesAndFallbacks) {
    sim::StatsCollector c;
    const double T = prp::kFieldPeriod;
    const int n = 200;
    for (int i = 0; i < n; ++i) {
        sim::FieldRecord r;
        r.deadline = i * T;
        // Every 50th field is handed over 1.5 periods late (a miss); others 1 ms after the slot.
        r.handoff = r.deadline + (i % 50 == 49 ? 1.5 * T : 0.001);
        r.frameAge = 0.01 * (i % 5);
        r.warpMs = 2.0;
        r.offCpuMs = i % 50 == 49 ? 12.0 : 0.5;  // the late fields were preempted
        r.wakeLateMs = 0.25;
        r.frameSequence = static_cast<std::uint64_t>(i / 5);
        r.fallback = i % 40 == 0 ? prp::Fallback::Affine : prp::Fallback::None;
        c.addField(r);
    }
    for (int i = 0; i < 10; ++i)
        c.addFrame(50.0);
    const sim::StatsSummary s = c.summarize(2.0, true);
    EXPECT_EQ(s.fields, static_cast<std::uint64_t>(n));
    EXPECT_EQ(s.missedDeadlines, static_cast<std::uint64_t>(n / 50));
    EXPECT_EQ(s.framesShown, static_cast<std::uint64_t>(n / 5));
    EXPECT_EQ(s.fallbacks, static_cast<std::uint64_t>(n / 40));
    EXPECT_EQ(s.fallbacksByKind[static_cast<int>(prp::Fallback::Affine)], s.fallbacks);
    EXPECT_NEAR(s.fieldIntervalMs.p50, T * 1e3, 1e-9);
    EXPECT_NEAR(s.fieldIntervalMs.max, (T + 1.5 * T - 0.001) * 1e3, 1e-9);
    EXPECT_NEAR(s.frameAgeMs.max, 40.0, 1e-9);
    EXPECT_NEAR(s.renderFps, 5.0, 1e-12);
    EXPECT_NEAR(s.renderMsMean, 50.0, 1e-9);

    const nlohmann::json j = sim::toJson(s);
    for (const char* key : {"fields", "missed_deadlines", "field_interval_ms", "frame_age_ms",
                            "render_fps", "fallbacks"}) {
        EXPECT_TRUE(j.contains(key)) << key;
    }
    EXPECT_EQ(j["fields"].get<int>(), n);
    EXPECT_EQ(j["missed_deadlines"].get<int>(), n / 50);
    // Each missed field listed: which, when, how late.
    ASSERT_EQ(j["missed_fields"].size(), static_cast<std::size_t>(n / 50));
    for (std::size_t k = 0; k < j["missed_fields"].size(); ++k) {
        const nlohmann::json& m = j["missed_fields"][k];
        EXPECT_EQ(m["field"].get<int>(), 50 * static_cast<int>(k) + 49);
        EXPECT_NEAR(m["slot_s"].get<double>(), (50 * static_cast<double>(k) + 49) * T, 1e-9);
        EXPECT_NEAR(m["lateness_ms"].get<double>(), 1.5 * T * 1e3, 1e-9);
        EXPECT_EQ(m["warp_ms"].get<double>(), 2.0);
        EXPECT_EQ(m["warp"].get<std::string>(), "poly");
        EXPECT_EQ(m["off_cpu_ms"].get<double>(), 12.0);
        EXPECT_EQ(m["wake_late_ms"].get<double>(), 0.25);
    }
    EXPECT_EQ(j["field_off_cpu_ms"]["p50"].get<double>(), 0.5);
    EXPECT_EQ(j["field_off_cpu_ms"]["max"].get<double>(), 12.0);
    for (const char* key : {"p50", "p99", "p99.9", "max"})
        EXPECT_TRUE(j["field_interval_ms"].contains(key));
    EXPECT_TRUE(j["renderer_restarts"].is_array());
    for (const char* key : {"p50", "p99"})
        EXPECT_TRUE(j["frame_age_ms"].contains(key));
    EXPECT_FALSE(sim::formatSummary(s).empty());
}

// A restart is reported with its gap; one whose renderer showed no frame (restarted again, or
// the run ended first) says so, with no gap made of the "none" sentinel.
TEST(Stats, RestartsAreReportedWithTheirGapOrItsAbsence) {
    sim::StatsSummary s;
    sim::RendererRestart shown;
    shown.detected = 1.0;
    shown.cause = "killed by signal 9 (Killed)";
    shown.gapSeconds = 0.4;
    shown.recoverySeconds = 0.3;
    shown.fieldsExtrapolated = 20;
    sim::RendererRestart none;
    none.detected = 2.0;
    none.cause = "silent for 512 ms";
    s.restarts = {shown, none};
    const std::string text = sim::formatSummary(s);
    EXPECT_NE(text.find("renderer restart at 1.000 s: killed by signal 9 (Killed); gap 400.0 ms "
                        "(300.0 ms after it was noticed), 20 fields extrapolated, 0 held"),
              std::string::npos)
        << text;
    EXPECT_NE(text.find("renderer restart at 2.000 s: silent for 512 ms; no frame of the "
                        "restarted renderer was shown"),
              std::string::npos)
        << text;
    EXPECT_EQ(text.find("-1000"), std::string::npos) << text;
    const nlohmann::json j = sim::toJson(s);
    ASSERT_EQ(j["renderer_restarts"].size(), 2u);
    EXPECT_EQ(j["renderer_restarts"][0]["gap_ms"].get<double>(), 400.0);
    EXPECT_TRUE(j["renderer_restarts"][1]["gap_ms"].is_null());
}

}  // namespace
