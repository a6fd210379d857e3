#include "sim/stats.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace sim {

Percentiles percentiles(std::vector<double> values) {
    Percentiles p;
    if (values.empty()) return p;
    std::sort(values.begin(), values.end());
    const auto rank = [&](double q) {
        const double r = std::ceil(q * static_cast<double>(values.size()));
        const std::size_t i = static_cast<std::size_t>(std::max(r, 1.0)) - 1;
        return values[std::min(i, values.size() - 1)];
    };
    p.p50 = rank(0.50);
    p.p99 = rank(0.99);
    p.p999 = rank(0.999);
    p.max = values.back();
    return p;
}

void StatsCollector::addFrame(double renderMs) {
    frames_.fetch_add(1, std::memory_order_relaxed);
    const double us = std::max(renderMs, 0.0) * 1000.0;
    renderMicros_.fetch_add(static_cast<std::uint64_t>(us + 0.5), std::memory_order_relaxed);
}

StatsSummary StatsCollector::summarize(double renderSeconds, bool simulatedClock) const {
    StatsSummary s;
    s.simulatedClock = simulatedClock;
    s.fields = records_.size();
    s.framesRendered = frames_.load();
    if (s.framesRendered > 0) {
        s.renderMsMean = static_cast<double>(renderMicros_.load()) / 1000.0 /
                         static_cast<double>(s.framesRendered);
    }
    if (renderSeconds > 0.0) s.renderFps = static_cast<double>(s.framesRendered) / renderSeconds;

    std::vector<double> intervals, jitter, lateness, ages, warps, offCpu, rightWarps, disparities,
        fitDisparities;
    intervals.reserve(records_.size());
    jitter.reserve(records_.size());
    lateness.reserve(records_.size());
    ages.reserve(records_.size());
    warps.reserve(records_.size());
    std::uint64_t lastSequence = ~std::uint64_t{0};
    for (std::size_t i = 0; i < records_.size(); ++i) {
        const FieldRecord& r = records_[i];
        if (i > 0) {
            const double interval = r.handoff - records_[i - 1].handoff;
            intervals.push_back(interval * 1e3);
            jitter.push_back(std::abs(interval - prp::kFieldPeriod) * 1e3);
        }
        lateness.push_back((r.handoff - r.deadline) * 1e3);
        if (r.handoff > r.deadline + prp::kFieldPeriod) {
            ++s.missedDeadlines;
            if (s.missed.size() < StatsSummary::kMaxMissedListed) {
                s.missed.push_back(MissedField{i, r.deadline - records_.front().deadline,
                                               (r.handoff - r.deadline) * 1e3, r.warpMs, r.model,
                                               r.offCpuMs, r.wakeLateMs});
            }
        }
        ages.push_back(r.frameAge * 1e3);
        warps.push_back(r.warpMs);
        if (r.offCpuMs >= 0.0) offCpu.push_back(r.offCpuMs);
        if (r.fallback != prp::Fallback::None) {
            ++s.fallbacks;
        }
        ++s.fallbacksByKind[static_cast<std::size_t>(r.fallback)];
        ++s.fieldsByModel[static_cast<std::size_t>(r.model)];
        s.depthOverBudget += r.depthOverBudget;
        s.depthAbandoned += r.depthAbandoned;
        if (r.rightWarpMs >= 0.0) {
            s.stereo = true;
            rightWarps.push_back(r.rightWarpMs);
            s.rightFallbacks += r.rightFallback != prp::Fallback::None;
            ++s.rightFieldsByModel[static_cast<std::size_t>(r.rightModel)];
            if (r.verticalDisparityPx >= 0.0) disparities.push_back(r.verticalDisparityPx);
            if (r.fitVerticalDisparityPx >= 0.0) fitDisparities.push_back(r.fitVerticalDisparityPx);
        }
        if (r.frameSequence != lastSequence) {
            ++s.framesShown;
            lastSequence = r.frameSequence;
        }
    }
    if (!records_.empty()) s.elapsedSeconds = records_.back().handoff - records_.front().deadline;
    s.fieldIntervalMs = percentiles(std::move(intervals));
    s.jitterMs = percentiles(std::move(jitter));
    s.latenessMs = percentiles(std::move(lateness));
    s.frameAgeMs = percentiles(std::move(ages));
    s.warpMs = percentiles(std::move(warps));
    s.offCpuMs = percentiles(std::move(offCpu));
    s.rightWarpMs = percentiles(std::move(rightWarps));
    s.verticalDisparityPx = percentiles(std::move(disparities));
    s.fitVerticalDisparityPx = percentiles(std::move(fitDisparities));
    s.restarts = restarts_;
    return s;
}

namespace {
nlohmann::json toJson(const Percentiles& p) {
    return {{"p50", p.p50}, {"p99", p.p99}, {"p99.9", p.p999}, {"max", p.max}};
}
nlohmann::json restartsJson(const std::vector<RendererRestart>& restarts) {
    nlohmann::json list = nlohmann::json::array();
    for (const RendererRestart& r : restarts) {
        list.push_back(
            {{"detected_s", r.detected},
             {"cause", r.cause},
             {"gap_ms",
              r.gapSeconds >= 0.0 ? nlohmann::json(r.gapSeconds * 1e3) : nlohmann::json(nullptr)},
             {"recovery_ms", r.recoverySeconds >= 0.0 ? nlohmann::json(r.recoverySeconds * 1e3)
                                                      : nlohmann::json(nullptr)},
             {"detected_monotonic_s", r.detectedMonotonic},
             {"first_frame_monotonic_s", r.firstFrameMonotonic},
             {"fields_extrapolated", r.fieldsExtrapolated},
             {"fields_held", r.fieldsHeld}});
    }
    return list;
}
}  // namespace

static nlohmann::json modelsJson(const std::array<std::uint64_t, 6>& counts) {
    nlohmann::json byModel = nlohmann::json::object();
    for (std::size_t m = 0; m < counts.size(); ++m) {
        if (counts[m] > 0) {
            byModel[std::string(prp::warpModelName(static_cast<prp::WarpModel>(m)))] = counts[m];
        }
    }
    return byModel;
}

namespace {

nlohmann::json missedJson(const std::vector<MissedField>& missed) {
    nlohmann::json out = nlohmann::json::array();
    for (const MissedField& m : missed) {
        out.push_back({{"field", m.index},
                       {"slot_s", m.slot},
                       {"lateness_ms", m.latenessMs},
                       {"warp_ms", m.warpMs},
                       {"off_cpu_ms",
                        m.offCpuMs >= 0.0 ? nlohmann::json(m.offCpuMs) : nlohmann::json(nullptr)},
                       {"wake_late_ms", m.wakeLateMs >= 0.0 ? nlohmann::json(m.wakeLateMs)
                                                            : nlohmann::json(nullptr)},
                       {"warp", std::string(prp::warpModelName(m.model))}});
    }
    return out;
}

}  // namespace

nlohmann::json toJson(const StatsSummary& s) {
    nlohmann::json byKind = nlohmann::json::object();
    for (prp::Fallback f : {prp::Fallback::Affine, prp::Fallback::Rotation, prp::Fallback::Hold}) {
        byKind[std::string(prp::fallbackName(f))] = s.fallbacksByKind[static_cast<std::size_t>(f)];
    }
    nlohmann::json j = {
        {"fields", s.fields},
        {"fields_by_warp", modelsJson(s.fieldsByModel)},
        {"fields_depth_over_budget", s.depthOverBudget},
        {"fields_depth_abandoned", s.depthAbandoned},
        {"missed_deadlines", s.missedDeadlines},
        {"missed_fields", missedJson(s.missed)},
        {"field_interval_ms", toJson(s.fieldIntervalMs)},
        {"field_jitter_ms", toJson(s.jitterMs)},
        {"field_lateness_ms", toJson(s.latenessMs)},
        {"frame_age_ms", toJson(s.frameAgeMs)},
        {"warp_ms", toJson(s.warpMs)},
        {"field_off_cpu_ms", toJson(s.offCpuMs)},
        {"render_fps", s.renderFps},
        {"render_ms_mean", s.renderMsMean},
        {"frames_rendered", s.framesRendered},
        {"frames_shown", s.framesShown},
        {"fallbacks", s.fallbacks},
        {"fallbacks_by_kind", byKind},
        {"elapsed_s", s.elapsedSeconds},
        {"clock", s.simulatedClock ? "simulated" : "wall"},
        {"renderer_restarts", restartsJson(s.restarts)},
    };
    if (s.stereo) {
        j["right_eye"] = {{"warp_ms", toJson(s.rightWarpMs)},
                          {"fallbacks", s.rightFallbacks},
                          {"fields_by_warp", modelsJson(s.rightFieldsByModel)}};
        j["vertical_disparity_px"] = toJson(s.verticalDisparityPx);
        j["fit_vertical_disparity_px"] = toJson(s.fitVerticalDisparityPx);
        j["fields_depth_for_rows"] = s.depthForRows;
    }
    return j;
}

std::string formatSummary(const StatsSummary& s) {
    char buf[1024];
    std::snprintf(buf, sizeof buf,
                  "fields          %llu in %.2f s (%s clock), missed deadlines %llu\n"
                  "field interval  p50 %.3f  p99 %.3f  max %.3f ms (jitter p99 %.3f  p99.9 %.3f  "
                  "max %.3f ms)\n"
                  "frame age       p50 %.1f  p99 %.1f  max %.1f ms\n"
                  "renderer        %.1f fps, %.1f ms per frame, %llu frames (%llu shown)\n"
                  "warp            p50 %.2f  p99 %.2f  max %.2f ms, fallbacks %llu "
                  "(affine %llu, rotation %llu, hold %llu)\n",
                  static_cast<unsigned long long>(s.fields), s.elapsedSeconds,
                  s.simulatedClock ? "simulated" : "wall",
                  static_cast<unsigned long long>(s.missedDeadlines), s.fieldIntervalMs.p50,
                  s.fieldIntervalMs.p99, s.fieldIntervalMs.max, s.jitterMs.p99, s.jitterMs.p999,
                  s.jitterMs.max, s.frameAgeMs.p50, s.frameAgeMs.p99, s.frameAgeMs.max, s.renderFps,
                  s.renderMsMean, static_cast<unsigned long long>(s.framesRendered),
                  static_cast<unsigned long long>(s.framesShown), s.warpMs.p50, s.warpMs.p99,
                  s.warpMs.max, static_cast<unsigned long long>(s.fallbacks),
                  static_cast<unsigned long long>(s.fallbacksByKind[1]),
                  static_cast<unsigned long long>(s.fallbacksByKind[2]),
                  static_cast<unsigned long long>(s.fallbacksByKind[3]));
    std::string text = buf;
    std::string models;
    for (std::size_t m = 0; m < s.fieldsByModel.size(); ++m) {
        if (s.fieldsByModel[m] == 0) continue;
        models += (models.empty() ? "" : ", ") +
                  std::string(prp::warpModelName(static_cast<prp::WarpModel>(m))) + " " +
                  std::to_string(s.fieldsByModel[m]);
    }
    if (!models.empty()) {
        text += "warp models     " + models + " fields";
        if (s.depthOverBudget > 0) {
            text += " (auto: " + std::to_string(s.depthOverBudget) +
                    " by the quadratic, the depth model over its time budget)";
        }
        if (s.depthAbandoned > 0) {
            text += " (auto: " + std::to_string(s.depthAbandoned) +
                    " depth fields abandoned at the budget for the quadratic)";
        }
        text += "\n";
    }
    if (s.stereo) {
        std::snprintf(buf, sizeof buf,
                      "right eye warp  p50 %.2f  p99 %.2f  max %.2f ms, fallbacks %llu\n"
                      "vertical disparity  p50 %.3f  p99 %.3f  max %.3f rows (of the fits: max "
                      "%.3f; %llu fields took the depth model for it)\n",
                      s.rightWarpMs.p50, s.rightWarpMs.p99, s.rightWarpMs.max,
                      static_cast<unsigned long long>(s.rightFallbacks), s.verticalDisparityPx.p50,
                      s.verticalDisparityPx.p99, s.verticalDisparityPx.max,
                      s.fitVerticalDisparityPx.max,
                      static_cast<unsigned long long>(s.depthForRows));
        text += buf;
    }
    for (const RendererRestart& r : s.restarts) {
        // A renderer that showed no frame (restarted again, or the run ended first) has no gap.
        if (r.gapSeconds < 0.0) {
            std::snprintf(buf, sizeof buf,
                          "renderer restart at %.3f s: %s; no frame of the restarted renderer "
                          "was shown\n",
                          r.detected, r.cause.c_str());
        } else {
            std::snprintf(buf, sizeof buf,
                          "renderer restart at %.3f s: %s; gap %.1f ms (%.1f ms after it was "
                          "noticed), %llu fields extrapolated, %llu held\n",
                          r.detected, r.cause.c_str(), r.gapSeconds * 1e3, r.recoverySeconds * 1e3,
                          static_cast<unsigned long long>(r.fieldsExtrapolated),
                          static_cast<unsigned long long>(r.fieldsHeld));
        }
        text += buf;
    }
    return text;
}

}  // namespace sim
