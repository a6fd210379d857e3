// Speed against error of the warp models: warped fields against truly rendered ones.
#pragma once

#include "ig/caster.hpp"
#include "prp/depth_warp.hpp"
#include "prp/field.hpp"
#include "prp/warp_apply.hpp"

#include <array>
#include <functional>
#include <vector>

namespace prp {

struct EvalConfig {
    int width = 320, height = 240;  // output window = evaluation size
    int margin = 32;                // rendered margin on every side, pixels
    double hfov = 1.0471975511965976;
    std::vector<int> horizons{1, 2, 3, 4, 5, 6, 7, 8};  // fields ahead of the frame
    std::vector<WarpModel> models{WarpModel::Poly,  WarpModel::Affine, WarpModel::Homography,
                                  WarpModel::Depth, WarpModel::Auto,   WarpModel::Hold};
    int baseFrames = 4;     // base frames spread along the time range
    int timingRepeats = 3;  // each warp is timed this many times; the fastest counts
    bool useSky = true;
    double autoThresholdPx = 0.25;      // the auto model's threshold (PrpOptions::autoThresholdPx)
    EdgeFill edgeFill = EdgeFill::Sky;  // PrpOptions::edgeFill, with the casters' sky
    DepthMethod depthMethod = DepthMethod::Splat;  // PrpOptions::depthMethod
    ig::SkyModel sky;
};

// One model at one horizon, averaged over base frames.
struct EvalCell {
    WarpModel model = WarpModel::Poly;
    int horizon = 1;
    double psnrDb = 0.0;  // mean over base frames (identical fields count as 100 dB)
    double maePct = 0.0;  // mean absolute error, % of full scale
    double nsPerPixel = 0.0;
    double edgeFraction = 0.0;            // edge-repeated samples / output samples
    int fallbacks = 0;                    // fields whose fit fell back, over all base frames
    std::array<int, 4> fallbackCounts{};  // by Fallback value
    int depthFields = 0;                  // fields warped by the depth model (auto: its choice)
    int samples = 0;                      // base frames averaged
};

struct EvalResult {
    std::vector<EvalCell> cells;  // model-major, horizons in order
    int baseFrames = 0;
    int rolledTruths = 0;  // truths rendered by the roll-honouring caster
    double renderMs = 0.0;
};

// Pose of the flight at time t (seconds).
using PoseAt = std::function<ig::Pose(double)>;

// For base frames at times spread over [t0, t1 - max horizon]: renders a frame with margins
// (pose with roll 0) by `frameCaster`, warps it with each model to t + k * kFieldPeriod, and
// compares the field's lines with a true render at that pose without margins. Base frames
// whose truths have no roll use `frameCaster` throughout; otherwise `rollCaster` (which must
// honour roll) renders the base frame and its truths, so caster differences are not counted.
EvalResult evaluateWarps(const ig::TerrainMap& map, const ig::Caster& frameCaster,
                         const ig::Caster& rollCaster, const PoseAt& poseAt, double t0, double t1,
                         const EvalConfig& config);
// Sample-weighted average of several results with the same models and horizons.
EvalResult combine(const std::vector<EvalResult>& parts);

}  // namespace prp
