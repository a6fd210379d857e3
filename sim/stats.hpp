// Pipeline statistics: per-field records, percentiles, the end-of-run summary, progress and JSON.
#pragma once

#include "prp/field.hpp"

#include <nlohmann/json_fwd.hpp>

#include <array>
#include <atomic>
#include <cstdint>
#include <string>
#include <vector>

namespace sim {

struct Percentiles {
    double p50 = 0.0;
    double p99 = 0.0;
    double p999 = 0.0;
    double max = 0.0;
};
// Nearest-rank percentiles of `values` (all zero when empty).
Percentiles percentiles(std::vector<double> values);

// What the field loop records for one field. Times in clock seconds.
struct FieldRecord {
    double deadline = 0.0;  // when the field's slot began (the loop woke for it)
    double handoff = 0.0;   // when the sink had it
    double frameAge = 0.0;  // field time - frame pose time, seconds
    double warpMs = 0.0;
    prp::Fallback fallback = prp::Fallback::None;
    std::uint64_t frameSequence = 0;
    prp::WarpModel model = prp::WarpModel::Poly;  // the warp the field used (auto: its choice)
    bool depthOverBudget = false;  // auto: the quadratic, the depth model being over budget
    bool depthAbandoned = false;   // auto: the quadratic, the depth model unfinished at its budget
    // Stereo (the fields above are the left eye's): the right eye's warp time (-1: mono),
    // fallback and model, and the vertical disparity of the two quadratic fits in output rows
    // (-1: not measured).
    double rightWarpMs = -1.0;
    prp::Fallback rightFallback = prp::Fallback::None;
    prp::WarpModel rightModel = prp::WarpModel::Poly;
    double verticalDisparityPx = -1.0;
    // The same before any eye was switched to the depth model for it (kMaxVerticalDisparityRows).
    double fitVerticalDisparityPx = -1.0;
    // Wall clock: of the field's work (wake to hand-off), the time its thread was not running
    // (wall time less the thread's CPU time), ms; -1 on the simulated clock. A late field with
    // little of it was slow on the processor (or the host stopped it unseen: a guest whose host
    // reports no steal time counts a host's stall as run); with much of it, it was preempted.
    double offCpuMs = -1.0;
    // Wall clock: how late the loop woke for the field (wake - slot start), ms; -1 simulated.
    double wakeLateMs = -1.0;
};

// One renderer process that ended and was replaced (process renderer only).
struct RendererRestart {
    double detected = 0.0;  // clock seconds when the field process noticed
    std::string cause;      // "killed by signal 9 (Killed)", "silent for 512 ms", ...
    // Clock seconds from the last new frame before to the first new frame after, and from the
    // detection to that first frame; -1 when none came before the run ended.
    double gapSeconds = -1.0;
    double recoverySeconds = -1.0;
    double startSeconds = 0.0;  // wall seconds the new renderer's start (the fork) took
    // CLOCK_MONOTONIC seconds (io::monotonicNs) of the detection and of the first new frame
    // shown, so the gap can be set against an instant measured by another process; -1: none.
    double detectedMonotonic = -1.0, firstFrameMonotonic = -1.0;
    std::uint64_t fieldsExtrapolated = 0;  // fields of the gap warped from the last frame
    std::uint64_t fieldsHeld = 0;          // fields of the gap past the hold horizon
};

// A field handed over after its slot ended: when, how late, and what its warp cost.
struct MissedField {
    std::uint64_t index = 0;  // the field's number in the run
    double slot = 0.0;        // clock seconds from the run's first slot to this field's
    double latenessMs = 0.0;  // hand-off - slot start
    double warpMs = 0.0;
    prp::WarpModel model = prp::WarpModel::Poly;
    double offCpuMs = -1.0;    // FieldRecord::offCpuMs
    double wakeLateMs = -1.0;  // FieldRecord::wakeLateMs
};

struct StatsSummary {
    std::uint64_t fields = 0;
    std::uint64_t missedDeadlines = 0;  // fields handed over after their slot ended
    // The first kMaxMissedListed of them.
    static constexpr std::size_t kMaxMissedListed = 100;
    std::vector<MissedField> missed;
    std::uint64_t framesRendered = 0;
    std::uint64_t framesShown = 0;                   // distinct frames the fields came from
    std::uint64_t fallbacks = 0;                     // fields whose warp fell back
    std::array<std::uint64_t, 4> fallbacksByKind{};  // indexed by prp::Fallback
    std::array<std::uint64_t, 6> fieldsByModel{};    // indexed by prp::WarpModel
    std::uint64_t depthOverBudget = 0;  // auto: fields the quadratic took for the depth model
    std::uint64_t depthAbandoned = 0;   // auto: of the depth model's, abandoned at its budget
    // Stereo: the right eye's, and the vertical disparity of the two fits (output rows).
    bool stereo = false;
    Percentiles rightWarpMs;
    std::uint64_t rightFallbacks = 0;
    std::array<std::uint64_t, 6> rightFieldsByModel{};
    Percentiles verticalDisparityPx;     // as shown
    Percentiles fitVerticalDisparityPx;  // of the fits, before the depth model took over
    std::uint64_t depthForRows = 0;      // fields whose eyes took the depth model for rows
    Percentiles fieldIntervalMs;         // between successive hand-offs
    Percentiles jitterMs;                // |interval - field period|
    Percentiles latenessMs;              // hand-off - slot start
    Percentiles frameAgeMs;
    Percentiles warpMs;
    Percentiles offCpuMs;  // FieldRecord::offCpuMs, over the fields that measured it
    double renderFps = 0.0;
    double renderMsMean = 0.0;
    double elapsedSeconds = 0.0;  // clock seconds from the first slot to the last hand-off
    bool simulatedClock = false;
    std::vector<RendererRestart> restarts;
};

// Collects field records (field thread) and frame counts (renderer thread).
class StatsCollector {
  public:
    void reserve(std::size_t fields) { records_.reserve(fields); }
    // Field thread; allocation-free while within the reserved size.
    void addField(const FieldRecord& record) { records_.push_back(record); }
    // Renderer thread.
    void addFrame(double renderMs);

    const std::vector<FieldRecord>& records() const { return records_; }
    std::uint64_t framesRendered() const { return frames_.load(std::memory_order_relaxed); }

    // Field thread (or the thread that supervises the renderer process, under the pipeline's
    // lock): a renderer restart, and later what its gap cost.
    std::vector<RendererRestart>& restarts() { return restarts_; }
    const std::vector<RendererRestart>& restarts() const { return restarts_; }

    // renderSeconds: clock seconds over which frames were rendered (for the frame rate).
    StatsSummary summarize(double renderSeconds, bool simulatedClock) const;

  private:
    std::vector<FieldRecord> records_;
    std::vector<RendererRestart> restarts_;
    std::atomic<std::uint64_t> frames_{0};
    std::atomic<std::uint64_t> renderMicros_{0};
};

// `{"fields": n, "missed_deadlines": n, "field_interval_ms": {...}, "frame_age_ms": {...},
//   "render_fps": x, "fallbacks": n, ...}`.
nlohmann::json toJson(const StatsSummary& summary);
// Several human-readable lines.
std::string formatSummary(const StatsSummary& summary);

}  // namespace sim
