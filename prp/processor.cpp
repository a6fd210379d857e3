#include "prp/processor.hpp"

#include "base/text.hpp"

#include "ig/error.hpp"
#include "prp/id_warp.hpp"
#include "prp/warp_apply.hpp"

#include <glm/geometric.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <string>

namespace prp {

namespace {

constexpr float kEmpty = std::numeric_limits<float>::max();

void checkFrame(const ig::RenderedFrame& frame, bool needDepth) {
    const ig::Intrinsics& in = frame.intrinsics;
    // Built only for a message: a field's work allocates nothing.
    const auto what = [&] { return "rendered frame " + std::to_string(frame.sequence); };
    if (in.width < 2 || in.height < 2 || in.margin < 0 || in.windowWidth() < 1 ||
        in.windowHeight() < 1 || !(in.focal > 0.0) || !std::isfinite(in.focal)) {
        throw ig::InputError(what() + ": unusable intrinsics " + std::to_string(in.width) + "x" +
                             std::to_string(in.height) + " margin " + std::to_string(in.margin));
    }
    const std::size_t n = static_cast<std::size_t>(in.width) * static_cast<std::size_t>(in.height);
    if (frame.color.size() != n) {
        throw ig::InputError(what() + ": colour has " + std::to_string(frame.color.size()) +
                             " pixels, intrinsics say " + std::to_string(n));
    }
    if (!frame.objectId.empty() && frame.objectId.size() != n) {
        throw ig::InputError(what() + ": object ids have " + std::to_string(frame.objectId.size()) +
                             " pixels, intrinsics say " + std::to_string(n));
    }
    if (needDepth && frame.depth.size() != n) {
        throw ig::InputError(what() + ": depth has " + std::to_string(frame.depth.size()) +
                             " pixels, intrinsics say " + std::to_string(n));
    }
}

}  // namespace

bool DepthBudget::mayTry(std::uint64_t index) const {
    if (budget_ <= 0.0 || fields_ == 0) return true;
    return !overBudget() || index - lastField_ >= retryFields_;
}

bool DepthBudget::overBudget() const {
    return budget_ > 0.0 && (abandonedLast_ || (measured_ && depthSeconds_ > budget_));
}

double DepthBudget::allowance() const {
    if (budget_ <= 0.0) return std::numeric_limits<double>::infinity();
    return std::max(0.0, budget_ - std::max(tailSeconds_, quadraticSeconds_));
}

void DepthBudget::depthField(std::uint64_t index, double seconds, bool abandoned,
                             double tailSeconds) {
    const bool retry = fields_ > 0 && overBudget();
    abandonedLast_ = abandoned;
    if (!abandoned) {
        depthSeconds_ = measured_ ? 0.75 * depthSeconds_ + 0.25 * seconds : seconds;
        tailSeconds_ = measured_ ? 0.75 * tailSeconds_ + 0.25 * tailSeconds : tailSeconds;
        measured_ = true;
    }
    if (budget_ > 0.0) {
        if (!abandoned && seconds <= budget_) {
            retryFields_ = kDepthRetryFields;
        } else if (retry) {
            retryFields_ = std::min(2 * retryFields_, kDepthRetryFieldsMax);
        }
    }
    ++fields_;
    lastField_ = index;
}

void DepthBudget::quadraticField(double seconds) {
    quadraticSeconds_ =
        quadraticSeconds_ == 0.0 ? seconds : 0.75 * quadraticSeconds_ + 0.25 * seconds;
}

PostRenderingProcessor::PostRenderingProcessor(const PrpOptions& options)
    : options_(options), depthBudget_(options.autoDepthBudget) {
    if (options.outWidth < 2 || options.outHeight < 2 || options.outWidth > 16384 ||
        options.outHeight > 16384) {
        throw ig::InputError("output size " + std::to_string(options.outWidth) + "x" +
                             std::to_string(options.outHeight) +
                             ": must be between 2x2 and 16384x16384");
    }
    if (options.format == PixelFormat::Uyvy && options.outWidth % 2 != 0) {
        throw ig::InputError("output width " + std::to_string(options.outWidth) +
                             ": UYVY needs an even width");
    }
    if (!(options.agcTarget > 0.0 && options.agcTarget < 1.0)) {
        throw ig::InputError("AGC target " + std::to_string(options.agcTarget) +
                             ": must be in (0, 1)");
    }
    if (!(options.agcRate > 0.0 && options.agcRate <= 1.0)) {
        throw ig::InputError("AGC rate " + std::to_string(options.agcRate) + ": must be in (0, 1]");
    }
    if (!(options.minGain > 0.0 && options.minGain <= 1.0 && options.maxGain >= 1.0 &&
          options.maxGain <= 16.0)) {
        throw ig::InputError("AGC gain limits: need 0 < min <= 1 <= max <= 16");
    }
    if (!(options.autoThresholdPx > 0.0 && options.autoThresholdPx <= 1e6)) {
        throw ig::InputError("auto threshold " + base::number(options.autoThresholdPx) +
                             " px: must be positive");
    }
    if (!(options.autoDepthBudget >= 0.0 && options.autoDepthBudget <= 3600.0)) {
        throw ig::InputError("auto depth budget " + base::number(options.autoDepthBudget) +
                             " s: must be 0 (no limit) or positive");
    }
    if (!(options.holdAfter >= 0.0 && options.holdAfter <= 3600.0)) {
        throw ig::InputError("hold after " + base::number(options.holdAfter) +
                             " s: must be from 0 (never) to 3600 s");
    }
}

void PostRenderingProcessor::reset() {
    hasPrevious_ = false;
    gain_ = 1.0;
    filteredFrom_ = nullptr;
}

void PostRenderingProcessor::reserveDepthWarp(const ig::RenderedFrame& frame) {
    depthWarp_.reserve(frame.width(), frame.height(),
                       static_cast<std::size_t>(options_.outWidth) *
                           static_cast<std::size_t>((options_.outHeight + 1) / 2));
}

void PostRenderingProcessor::warmUp(const ig::RenderedFrame& frame) {
    const bool depthModel = options_.model == WarpModel::Depth || options_.model == WarpModel::Auto;
    checkFrame(frame, depthModel);  // as the first field would (an InputError for a bad one)
    if (depthModel && !options_.depthReference) {
        reserveDepthWarp(frame);
        depthWarp_.prepareFrame(frame, options_.depthKernel);
    }
    sourcePixels(frame);
    touchRoom(filtered_);  // the filter's room for wider frames
}

const ig::Rgb8* PostRenderingProcessor::sourcePixels(const ig::RenderedFrame& frame) {
    if (!options_.antiTwitter) return frame.color.data();
    if (filteredFrom_ == frame.color.data() && filteredSequence_ == frame.sequence &&
        filtered_.size() == frame.color.size()) {
        return filtered_.data();
    }
    // Vertical [1 2 1] / 4 on the rendered frame, once per frame: the warp is close to a
    // translation, so this is the output's vertical filter without computing the other field.
    // Room for the frames of the same window widened for any roll, so banking allocates nothing.
    if (frame.color.size() > filtered_.capacity()) {
        filtered_.reserve(
            std::max(frame.color.size(), rolledFrameRoomPixels(frame.width(), frame.height())));
    }
    filtered_.resize(frame.color.size());
    const int w = frame.width(), h = frame.height();
    for (int y = 0; y < h; ++y) {
        const ig::Rgb8* up = frame.color.data() + static_cast<std::size_t>(std::max(y - 1, 0)) * w;
        const ig::Rgb8* mid = frame.color.data() + static_cast<std::size_t>(y) * w;
        const ig::Rgb8* dn =
            frame.color.data() + static_cast<std::size_t>(std::min(y + 1, h - 1)) * w;
        ig::Rgb8* out = filtered_.data() + static_cast<std::size_t>(y) * w;
        for (int x = 0; x < w; ++x) {
            out[x].r = static_cast<std::uint8_t>((up[x].r + 2 * mid[x].r + dn[x].r + 2) >> 2);
            out[x].g = static_cast<std::uint8_t>((up[x].g + 2 * mid[x].g + dn[x].g + 2) >> 2);
            out[x].b = static_cast<std::uint8_t>((up[x].b + 2 * mid[x].b + dn[x].b + 2) >> 2);
        }
    }
    filteredFrom_ = frame.color.data();
    filteredSequence_ = frame.sequence;
    return filtered_.data();
}

void PostRenderingProcessor::process(const ig::RenderedFrame& frame, const ig::Pose& poseAtField,
                                     double time, std::uint64_t fieldIndex, Field& out,
                                     std::optional<WarpModel> forced, double fieldFocal,
                                     std::span<const ObjectMotion> motions) {
    const auto start = std::chrono::steady_clock::now();
    const bool stale = options_.holdAfter > 0.0 && time - frame.time > options_.holdAfter;
    const WarpModel chosen = forced.value_or(options_.model);
    const WarpModel model = stale ? WarpModel::Hold : chosen;
    const bool depthModel = model == WarpModel::Depth || model == WarpModel::Auto;
    checkFrame(frame, chosen == WarpModel::Depth || chosen == WarpModel::Auto);
    // The depth warp's buffers from the first field that may take it, not the first that does.
    if (depthModel && !options_.depthReference) reserveDepthWarp(frame);

    out.index = fieldIndex;
    out.parity = fieldParity(fieldIndex);
    out.time = time;
    out.frameSequence = frame.sequence;
    out.frameTime = frame.time;
    out.frameAge = time - frame.time;
    out.width = options_.outWidth;
    out.frameHeight = options_.outHeight;
    out.lines = fieldLines(options_.outHeight, out.parity);
    out.format = options_.format;
    out.stride = static_cast<std::size_t>(out.width) * bytesPerPixel(out.format);
    out.pixels.resize(out.stride * static_cast<std::size_t>(out.lines));
    out.holeSamples = 0;
    out.restampedObjects = 0;
    out.restampedPixels = 0;

    const OutputGeometry geometry =
        OutputGeometry::of(frame.intrinsics, options_.outWidth, options_.outHeight, fieldFocal);
    const int gainQ8 =
        options_.agc ? static_cast<int>(std::lround(gain_ * kUnityGain)) : kUnityGain;
    std::uint64_t lumaSum = 0;

    const bool poseOk = poseAtField.isFinite() && frame.pose.isFinite();
    FitOptions fit;
    fit.model = depthModel ? WarpModel::Poly : model;
    fit.useSky = options_.useSky;
    out.warp = fitWarp(frame, poseAtField, geometry, fit, hasPrevious_ ? &previous_ : nullptr);
    previous_ = out.warp;
    hasPrevious_ = true;
    bool useDepth = depthModel && poseOk;
    if (useDepth && model == WarpModel::Auto) {
        // The quadratic where it is good enough: its error on the check points, and no fallback.
        std::array<Correspondence, kCheckPointCount> check;
        const std::size_t n = checkCorrespondences(frame, poseAtField, geometry, check);
        out.warp.checkErrorPx = warpCheckError(out.warp, {check.data(), n});
        useDepth = out.warp.fallback != Fallback::None ||
                   !(out.warp.checkErrorPx <= options_.autoThresholdPx);
        // Never a field late for the depth model: over its budget, the quadratic (now and then
        // a field measures the depth model again: DepthBudget::mayTry).
        if (useDepth && !depthBudget_.mayTry(fieldIndex)) {
            useDepth = false;
            out.warp.depthOverBudget = true;
        }
    }
    const FieldView view{out.pixels.data(),          out.stride, out.width,
                         fieldFirstLine(out.parity), out.lines,  out.format};
    // Object ids: warped through the colour's own sample points.
    const bool ids = !frame.objectId.empty();
    if (ids) {
        out.objectId.resize(static_cast<std::size_t>(out.width) *
                            static_cast<std::size_t>(out.lines));
    } else {
        out.objectId.clear();
    }
    const IdSource idSource{frame.objectId.data(), frame.width(), frame.height()};
    const IdFieldView idView{out.objectId.data(), static_cast<std::size_t>(out.width), out.width,
                             view.firstLine, out.lines};
    if (useDepth) {
        const auto depthStart = std::chrono::steady_clock::now();
        // Auto on a deadline: a depth field still unfinished at the budget (another process
        // taking the core, a page fault storm) is abandoned for the quadratic, so no field is
        // late for it. The budget is the whole field's, either way it ends: the deadline leaves
        // room for the part past the warp's last look at the clock, or for the quadratic that
        // follows an abandoned one, as long as recent fields took for them.
        const bool mayAbandon = model == WarpModel::Auto && options_.autoDepthBudget > 0.0;
        const auto giveUpAt =
            mayAbandon ? depthStart + std::chrono::duration_cast<std::chrono::nanoseconds>(
                                          std::chrono::duration<double>(depthBudget_.allowance()))
                       : std::chrono::steady_clock::time_point::max();
        double tail = 0.0;  // of a depth field that completes
        if (options_.depthReference) {
            const WarpInfo fitted = out.warp;
            warpDepth(frame, poseAtField, geometry, out, gainQ8, lumaSum);  // ids too
            out.warp = fitted;
        } else {
            const DepthWarpResult r = depthWarp_.apply(
                frame, sourcePixels(frame), poseAtField, geometry, quadraticOf(out.warp), view,
                gainQ8, options_.agc, options_.depthKernel, options_.depthMethod, giveUpAt);
            const auto returned = std::chrono::steady_clock::now();
            if (r.abandoned) {
                useDepth = false;
                out.warp.depthAbandoned = true;
            } else {
                out.edgeSamples = r.edgeSamples;
                out.holeSamples = r.holes;
                lumaSum = r.lumaSum;
                if (options_.edgeFill != EdgeFill::Repeat && r.edgeSamples > 0) {
                    // Beyond the rendered frame as the quadratic: through the points it sampled.
                    OutsideFill fill =
                        OutsideFill::of(options_.sky, frame.intrinsics, geometry, poseAtField);
                    fill.hazeBelow = options_.edgeFill == EdgeFill::SkyHaze;
                    ApplyResult applied{r.edgeSamples, r.lumaSum};
                    fillOutside({sourcePixels(frame), frame.width(), frame.height()},
                                depthWarp_.pointsX(), depthWarp_.pointsY(),
                                static_cast<std::size_t>(out.width), view, gainQ8, options_.agc,
                                fill, applied);
                    lumaSum = applied.lumaSum;
                }
                if (ids) {
                    warpIdsPoints(idSource, depthWarp_.pointsX(), depthWarp_.pointsY(),
                                  static_cast<std::size_t>(out.width), idView);
                }
                tail = r.tailSeconds +
                       std::chrono::duration<double>(std::chrono::steady_clock::now() - returned)
                           .count();
            }
        }
        if (useDepth) out.warp.model = WarpModel::Depth;
        depthBudget_.depthField(
            fieldIndex,
            std::chrono::duration<double>(std::chrono::steady_clock::now() - depthStart).count(),
            out.warp.depthAbandoned, tail);
    }
    if (!useDepth) {
        const auto quadraticStart = std::chrono::steady_clock::now();
        if (depthModel) out.warp.model = model == WarpModel::Auto ? WarpModel::Poly : model;
        const SourceView source{sourcePixels(frame), frame.width(), frame.height()};
        ApplyResult r =
            out.warp.projective
                ? applyHomography(source, Homography{out.warp.h}, view, gainQ8, options_.agc)
                : applyQuadratic(source, quadraticOf(out.warp), view, gainQ8, options_.agc);
        if (options_.edgeFill != EdgeFill::Repeat && r.edgeSamples > 0) {
            // The camera the field shows: the frame's own when it holds it.
            const bool held = out.warp.model == WarpModel::Hold || !poseOk;
            OutsideFill fill = OutsideFill::of(options_.sky, frame.intrinsics, geometry,
                                               held ? frame.pose : poseAtField);
            fill.hazeBelow = options_.edgeFill == EdgeFill::SkyHaze;
            if (out.warp.projective) {
                fillOutside(source, Homography{out.warp.h}, view, gainQ8, options_.agc, fill, r);
            } else {
                fillOutside(source, quadraticOf(out.warp), view, gainQ8, options_.agc, fill, r);
            }
        }
        out.edgeSamples = r.edgeSamples;
        lumaSum = r.lumaSum;
        if (ids && out.warp.projective) {
            warpIdsHomography(idSource, Homography{out.warp.h}, idView);
        } else if (ids) {
            warpIdsQuadratic(idSource, quadraticOf(out.warp), idView);
        }
        if (depthModel) {
            const double q =
                std::chrono::duration<double>(std::chrono::steady_clock::now() - quadraticStart)
                    .count();
            depthBudget_.quadraticField(q);
        }
    }

    if (ids && !motions.empty() && poseOk && out.warp.model != WarpModel::Hold) {
        // Moving objects where they are at the field's instant, sampled through the field's own
        // source points.
        FieldSourceMap map;
        if (out.warp.model == WarpModel::Depth && !options_.depthReference) {
            map.kind = FieldSourceMap::Kind::Points;
            map.xs = depthWarp_.pointsX();
            map.ys = depthWarp_.pointsY();
            map.stride = static_cast<std::size_t>(out.width);
            map.windowPerOutputX =
                geometry.zoom() * static_cast<double>(geometry.windowWidth) / geometry.width;
            map.windowPerOutputY =
                geometry.zoom() * static_cast<double>(geometry.windowHeight) / geometry.height;
        } else if (out.warp.projective) {
            map.kind = FieldSourceMap::Kind::Homography;
            map.homography = Homography{out.warp.h};
        } else {
            map.quadratic = quadraticOf(out.warp);
        }
        const RestampStats r =
            restampMovingObjects(frame, sourcePixels(frame), poseAtField, geometry, map, motions,
                                 view, idView, gainQ8, restamp_);
        out.restampedObjects = r.objects;
        out.restampedPixels = r.pixels;
    }

    out.gain = options_.agc ? gainQ8 / static_cast<double>(kUnityGain) : 1.0;
    if (options_.agc) {
        // Like a camera's AGC: measure this field, move the gain part of the way toward the
        // gain that would have hit the target, for the next field.
        const double pixels = static_cast<double>(out.width) * out.lines;
        const double mean = std::max(lumaSum / (255.0 * pixels), 1.0 / 255.0);
        const double wanted =
            std::clamp(gain_ * options_.agcTarget / mean, options_.minGain, options_.maxGain);
        gain_ += options_.agcRate * (wanted - gain_);
    }
    out.warpMs =
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
}

void PostRenderingProcessor::warpDepth(const ig::RenderedFrame& frame, const ig::Pose& poseAtField,
                                       const OutputGeometry& geometry, Field& out, int gainQ8,
                                       std::uint64_t& lumaSum) {
    const int ow = geometry.width, oh = geometry.height;
    const std::size_t n = static_cast<std::size_t>(ow) * static_cast<std::size_t>(oh);
    splatSource_.resize(2 * n);
    splatDepth_.assign(n, kEmpty);
    rowRgb_.resize(3 * static_cast<std::size_t>(ow));

    // Forward 3D warp: every rendered pixel to its world point, into the field's camera (roll
    // included), z-buffered onto the nearest output pixel. Each output pixel keeps the source
    // point that lands on its centre, assuming the local warp is the output scaling (exact for
    // the pixel's own offset to first order), so sampling stays bilinear.
    const ig::Camera src(frame.pose, frame.intrinsics);
    const ig::CameraBasis dst = ig::CameraBasis::fromPose(poseAtField);
    const glm::dvec3 offset = frame.pose.position - poseAtField.position;
    // Projected at the field's focal length; an output pixel spans zoom / s rendered pixels.
    const double f = geometry.fieldWindow().focal;
    const double zoom = geometry.zoom();
    const double sx = static_cast<double>(ow) / geometry.windowWidth;
    const double sy = static_cast<double>(oh) / geometry.windowHeight;
    const double cx = 0.5 * geometry.windowWidth, cy = 0.5 * geometry.windowHeight;
    const int w = frame.width(), h = frame.height();
    for (int y = 0; y < h; ++y) {
        for (int x = 0; x < w; ++x) {
            const std::size_t i = static_cast<std::size_t>(y) * w + x;
            const float d = frame.depth[i];
            const glm::dvec3 dir = glm::normalize(src.rayDirection(x + 0.5, y + 0.5));
            glm::dvec3 v;
            float z;
            if (std::isfinite(d)) {
                v = offset + static_cast<double>(d) * dir;
                z = 0.0f;
            } else if (d > 0.0f) {
                v = dir;  // sky: a direction, seen by rotation only
                z = kSkySplat;
            } else {
                continue;
            }
            const double zf = glm::dot(v, dst.forward);
            if (!(zf > 1e-6)) continue;
            const double qx = (cx + f * glm::dot(v, dst.right) / zf) * sx;
            const double qy = (cy - f * glm::dot(v, dst.up) / zf) * sy;
            if (!(qx >= 0.0 && qy >= 0.0 && qx < ow && qy < oh)) continue;
            const std::size_t o = static_cast<std::size_t>(qy) * ow + static_cast<std::size_t>(qx);
            if (z == 0.0f) z = static_cast<float>(zf);
            if (z < splatDepth_[o]) {
                splatDepth_[o] = z;
                splatSource_[2 * o] =
                    static_cast<float>(x + 0.5 + zoom * (std::floor(qx) + 0.5 - qx) / sx);
                splatSource_[2 * o + 1] =
                    static_cast<float>(y + 0.5 + zoom * (std::floor(qy) + 0.5 - qy) / sy);
            }
        }
    }

    // Holes: the farthest filled 4-neighbour (background first), else the nearest filled pixel
    // of the row (counted as edge samples), each shifted by the pixel offset; else the frame as
    // it is.
    const Quadratic hold = Quadratic::fromAffine(geometry.sourceFromOutputHold());
    const ig::Rgb8* color = sourcePixels(frame);
    std::uint64_t edge = 0;
    const int first = fieldFirstLine(out.parity);
    for (int line = 0; line < out.lines; ++line) {
        const int y = first + 2 * line;
        const std::size_t rowStart = static_cast<std::size_t>(y) * ow;
        std::uint8_t* row = rowRgb_.data();
        for (int x = 0; x < ow; ++x) {
            const std::size_t o = rowStart + x;
            std::size_t from = o;
            if (splatDepth_[o] == kEmpty) {
                float best = -1.0f;
                from = n;
                const std::size_t nb[4] = {x > 0 ? o - 1 : n, x + 1 < ow ? o + 1 : n,
                                           y > 0 ? o - ow : n, y + 1 < oh ? o + ow : n};
                for (const std::size_t k : nb) {
                    if (k < n && splatDepth_[k] != kEmpty && splatDepth_[k] > best) {
                        best = splatDepth_[k];
                        from = k;
                    }
                }
                if (from == n) {
                    ++edge;
                    for (int step = 1; step < ow && from == n; ++step) {
                        if (x - step >= 0 && splatDepth_[rowStart + x - step] != kEmpty) {
                            from = rowStart + x - step;
                        } else if (x + step < ow && splatDepth_[rowStart + x + step] != kEmpty) {
                            from = rowStart + x + step;
                        }
                    }
                }
            }
            glm::dvec2 p;
            if (from < n) {
                const double fx = static_cast<double>(from % ow),
                             fy = static_cast<double>(from / ow);
                p = {splatSource_[2 * from] + zoom * (x - fx) / sx,
                     splatSource_[2 * from + 1] + zoom * (y - fy) / sy};
            } else {
                p = hold({x + 0.5, y + 0.5});
            }
            // Bilinear, edge repeated.
            const double px = std::clamp(p.x - 0.5, 0.0, w - 1.0);
            const double py = std::clamp(p.y - 0.5, 0.0, h - 1.0);
            const int x0 = std::min(static_cast<int>(px), w - 2);
            const int y0 = std::min(static_cast<int>(py), h - 2);
            const double ax = px - x0, ay = py - y0;
            const ig::Rgb8* c0 = color + static_cast<std::size_t>(y0) * w + x0;
            const ig::Rgb8* c1 = c0 + w;
            auto lerp = [&](std::uint8_t ig::Rgb8::*ch) {
                const double top = c0[0].*ch + ax * (c0[1].*ch - c0[0].*ch);
                const double bot = c1[0].*ch + ax * (c1[1].*ch - c1[0].*ch);
                return static_cast<std::uint8_t>(top + ay * (bot - top) + 0.5);
            };
            if (!frame.objectId.empty()) {
                // The nearer tap along each axis (ties right and down), as the fast path.
                out.objectId[static_cast<std::size_t>(line) * ow + x] =
                    frame.objectId[static_cast<std::size_t>(y0 + (ay >= 0.5)) * w + x0 +
                                   (ax >= 0.5)];
            }
            row[3 * x] = lerp(&ig::Rgb8::r);
            row[3 * x + 1] = lerp(&ig::Rgb8::g);
            row[3 * x + 2] = lerp(&ig::Rgb8::b);
        }
        convertRow(row, ow, out.format, gainQ8, options_.agc,
                   out.pixels.data() + static_cast<std::size_t>(line) * out.stride, lumaSum);
    }
    out.edgeSamples = edge;
}

}  // namespace prp
