// The post-rendering processor: turns the latest rendered frame into the field due now.
#pragma once

#include "ig/camera.hpp"
#include "ig/caster.hpp"
#include "ig/frame.hpp"
#include "prp/depth_warp.hpp"
#include "prp/field.hpp"
#include "prp/object_restamp.hpp"
#include "prp/warp_apply.hpp"
#include "prp/warp_fit.hpp"

#include <cstdint>
#include <optional>
#include <span>
#include <vector>

namespace prp {

struct PrpOptions {
    int outWidth = 720, outHeight = 486;
    PixelFormat format = PixelFormat::Uyvy;
    WarpModel model = WarpModel::Poly;
    bool agc = false;          // automatic gain control toward agcTarget mean luminance
    double agcTarget = 0.45;   // target mean full-range luminance, 0..1
    double agcRate = 0.1;      // fraction of the way to the wanted gain per field, (0, 1]
    bool antiTwitter = false;  // vertical [1 2 1] / 4 filter against interlace twitter
    bool useSky = true;        // fit sky control points (directions) as well as terrain
    double minGain = 0.25, maxGain = 4.0;
    // Frame age (seconds) past which a field no longer extrapolates the frame's motion but
    // holds it (the Hold model: the frame as rendered, roll applied), as when the renderer has
    // stopped delivering; 0: never.
    double holdAfter = 0.0;
    // Auto: a field whose quadratic misses any check point by more than this (rendered pixels),
    // or whose fit fell back, is warped by the depth model...
    double autoThresholdPx = 0.25;
    // ... unless the depth model's recent fields took longer than this (seconds; 0: no limit,
    // as offline): then the quadratic, and the depth model again once in kDepthRetryFields
    // fields to measure it anew. The real-time pipeline sets it (flythrough: 10 ms, 60 % of an
    // NTSC field, the rest for the output and the loop). A depth field still unfinished at the
    // budget is abandoned for the quadratic (WarpInfo::depthAbandoned).
    double autoDepthBudget = 0.0;
    // Depth model: the projection kernel (DepthKernel::Auto: AVX2 where available), or the
    // double-precision per-pixel reference (tests and comparisons: tens of times slower).
    DepthKernel depthKernel = DepthKernel::Auto;
    // Depth model: the gather with the splat where it does not settle, or the splat throughout.
    DepthMethod depthMethod = DepthMethod::Splat;
    bool depthReference = false;
    // Output pixels whose source point lies outside the rendered frame (a pose change beyond
    // the margins): EdgeFill (prp/warp_apply.hpp) with the casters' `sky`. Every model but the
    // double-precision depth reference (which repeats edges). Counted in Field::edgeSamples.
    EdgeFill edgeFill = EdgeFill::Sky;
    ig::SkyModel sky;
};

// Auto over budget: one field in this many takes the depth model to measure its cost again;
// each retry that finds it over budget still doubles the wait, up to kDepthRetryFieldsMax (a
// retry is the one field with little slack left: its budget and then the quadratic), and one
// that finds it within budget brings the wait back to kDepthRetryFields.
inline constexpr std::uint64_t kDepthRetryFields = 300;
inline constexpr std::uint64_t kDepthRetryFieldsMax = 8 * kDepthRetryFields;

// Auto's time budget for the depth model on the wall clock (PrpOptions::autoDepthBudget): whether
// a field that wants the depth model may take it, when its warp must give up, and what the
// fields measured. Seconds throughout; a budget of 0: none (every field may, none gives up).
class DepthBudget {
  public:
    explicit DepthBudget(double budget = 0.0) : budget_(budget) {}

    // Whether field `index`, which wants the depth model, may take it: not while the model is
    // over budget (its recent completed fields' running mean above it, or its last field
    // abandoned), except one field once retryFields() have passed since the last it took.
    bool mayTry(std::uint64_t index) const;
    // Seconds from the depth warp's start at which to give it up: the budget less the larger
    // of the part of a depth field past its warp's last look at the clock and the quadratic
    // that follows an abandoned one (their running means), so the field ends within the
    // budget either way; +inf without a budget.
    double allowance() const;
    // A depth field `index` ended after `seconds`: abandoned at its deadline (its time is the
    // deadline's, not the model's: the running mean is left alone), or complete, `tailSeconds`
    // of it past the warp's last look at the clock.
    void depthField(std::uint64_t index, double seconds, bool abandoned, double tailSeconds);
    // A quadratic field of the same processor took `seconds`.
    void quadraticField(double seconds);

    bool overBudget() const;
    std::uint64_t retryFields() const { return retryFields_; }

  private:
    double budget_ = 0.0;
    double depthSeconds_ = 0.0, tailSeconds_ = 0.0, quadraticSeconds_ = 0.0;
    bool measured_ = false, abandonedLast_ = false;
    std::uint64_t fields_ = 0, lastField_ = 0;
    std::uint64_t retryFields_ = kDepthRetryFields;
};

class PostRenderingProcessor {
  public:
    // Throws ig::InputError naming the option when the options are unusable (size below 2 x 2,
    // odd width for UYVY, AGC target or rate out of range, auto threshold not positive).
    explicit PostRenderingProcessor(const PrpOptions& options);

    // Sizes the scratch buffers for `frame` and makes its per-frame data (the depth model's
    // scaled depths), as the first field from it would: before a field clock starts, so that
    // its first fields do not pay for them.
    void warmUp(const ig::RenderedFrame& frame);

    // Warps `frame` (rendered at frame.pose with roll 0, with margins) to `poseAtField` (roll
    // included), writing only the lines of fieldParity(fieldIndex) into `out`. Allocates only
    // when `out` or a scratch buffer is first sized. Throws ig::InputError for a frame whose
    // buffers do not match its intrinsics; a non-finite pose holds the previous warp.
    // `model`, when given, replaces options().model for this field (stereo forces the depth
    // model on a field whose two quadratic fits disagree on rows). `fieldFocal`, when positive,
    // is the field's own focal length in window pixels (its field of view over the frame's
    // window): every model warps the frame, whatever focal length it was rendered with, to a
    // field seen at this one; 0: the field shows the frame's field of view.
    // `motions`: the moving objects' own motion from the frame's instant to the field's; each
    // one the field shows is re-stamped where it is at the field's instant
    // (prp/object_restamp.hpp; not on a field that holds the frame).
    void process(const ig::RenderedFrame& frame, const ig::Pose& poseAtField, double fieldTime,
                 std::uint64_t fieldIndex, Field& out,
                 std::optional<WarpModel> model = std::nullopt, double fieldFocal = 0.0,
                 std::span<const ObjectMotion> motions = {});

    const PrpOptions& options() const { return options_; }
    // AGC gain the next field will use.
    double gain() const { return gain_; }
    // Forgets the previous warp and the AGC state.
    void reset();

  private:
    void warpDepth(const ig::RenderedFrame& frame, const ig::Pose& poseAtField,
                   const OutputGeometry& geometry, Field& out, int gainQ8, std::uint64_t& lumaSum);
    const ig::Rgb8* sourcePixels(const ig::RenderedFrame& frame);
    // The depth warp's buffers for frames like `frame` and fields of this output.
    void reserveDepthWarp(const ig::RenderedFrame& frame);

    PrpOptions options_;
    WarpInfo previous_;
    bool hasPrevious_ = false;
    double gain_ = 1.0;
    // Anti-twitter: the vertically filtered copy of the last frame.
    std::vector<ig::Rgb8> filtered_;
    const ig::Rgb8* filteredFrom_ = nullptr;
    std::uint64_t filteredSequence_ = 0;
    // Depth model scratch, full output frame: source point per pixel and splat depth.
    std::vector<float> splatSource_;
    std::vector<float> splatDepth_;
    std::vector<std::uint8_t> rowRgb_;
    // Auto's budget for the depth model, and what its fields measured.
    DepthBudget depthBudget_;
    DepthWarp depthWarp_;
    RestampScratch restamp_;
};

}  // namespace prp
