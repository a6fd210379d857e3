#include "prp/evaluation.hpp"

#include "ig/error.hpp"
#include "ig/image_compare.hpp"
#include "prp/processor.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>

namespace prp {

namespace {

constexpr double kIdenticalPsnr = 100.0;

}  // namespace

EvalResult evaluateWarps(const ig::TerrainMap& map, const ig::Caster& frameCaster,
                         const ig::Caster& rollCaster, const PoseAt& poseAt, double t0, double t1,
                         const EvalConfig& config) {
    if (config.horizons.empty() || config.models.empty() || config.baseFrames < 1) {
        throw ig::InputError("evaluation: need at least one horizon, model and base frame");
    }
    const int maxK = *std::max_element(config.horizons.begin(), config.horizons.end());
    const ig::Intrinsics framed =
        ig::Intrinsics::fromFov(config.width, config.height, config.hfov, config.margin);
    const ig::Intrinsics window = ig::Intrinsics::fromFov(config.width, config.height, config.hfov);
    const double span = std::max(0.0, t1 - t0 - maxK * kFieldPeriod);

    EvalResult result;
    for (const WarpModel m : config.models) {
        for (const int k : config.horizons) {
            EvalCell c;
            c.model = m;
            c.horizon = k;
            result.cells.push_back(c);
        }
    }
    const auto start = std::chrono::steady_clock::now();
    std::vector<ig::Rgb8> got, want;
    Field field;
    for (int b = 0; b < config.baseFrames; ++b) {
        const double tb = t0 + span * (b + 0.5) / config.baseFrames;
        ig::Pose base = poseAt(tb);
        base.roll = 0.0;
        // Where any truth of this base frame is rolled, the roll-honouring caster renders the
        // base frame and every truth, so caster differences do not count as warp error.
        bool anyRolled = false;
        for (const int k : config.horizons)
            anyRolled |= poseAt(tb + k * kFieldPeriod).roll != 0.0;
        const ig::Caster& caster = anyRolled ? rollCaster : frameCaster;
        const ig::RenderedFrame frame =
            ig::renderFrame(caster, map, base, framed, tb, static_cast<std::uint64_t>(b));
        ++result.baseFrames;
        std::vector<PostRenderingProcessor> prps;
        for (const WarpModel m : config.models) {
            PrpOptions o;
            o.outWidth = config.width;
            o.outHeight = config.height;
            o.format = PixelFormat::Rgb8;
            o.model = m;
            o.useSky = config.useSky;
            o.autoThresholdPx = config.autoThresholdPx;
            o.edgeFill = config.edgeFill;
            o.depthMethod = config.depthMethod;
            o.sky = config.sky;
            prps.emplace_back(o);
        }
        for (std::size_t hi = 0; hi < config.horizons.size(); ++hi) {
            const int k = config.horizons[hi];
            const double tf = tb + k * kFieldPeriod;
            const ig::Pose pose = poseAt(tf);
            const ig::RenderedFrame truth = ig::renderFrame(caster, map, pose, window, tf);
            result.rolledTruths += pose.roll != 0.0;
            for (std::size_t mi = 0; mi < config.models.size(); ++mi) {
                double best = 0.0;
                for (int r = 0; r < std::max(1, config.timingRepeats); ++r) {
                    prps[mi].process(frame, pose, tf, static_cast<std::uint64_t>(k), field);
                    best = r == 0 ? field.warpMs : std::min(best, field.warpMs);
                }
                got.resize(static_cast<std::size_t>(field.width) * field.lines);
                want.resize(got.size());
                for (int line = 0; line < field.lines; ++line) {
                    const std::uint8_t* p = field.line(line);
                    const ig::Rgb8* t =
                        truth.color.data() +
                        static_cast<std::size_t>(field.frameLine(line)) * truth.width();
                    for (int x = 0; x < field.width; ++x) {
                        got[static_cast<std::size_t>(line) * field.width + x] = {
                            p[3 * x], p[3 * x + 1], p[3 * x + 2]};
                        want[static_cast<std::size_t>(line) * field.width + x] = t[x];
                    }
                }
                EvalCell& c = result.cells[mi * config.horizons.size() + hi];
                const double psnr = ig::psnrDb(got, want);
                c.psnrDb += std::min(psnr, kIdenticalPsnr);
                c.maePct += ig::meanAbsErrorPct(got, want);
                const double pixels = static_cast<double>(field.width) * field.lines;
                c.nsPerPixel += best * 1e6 / pixels;
                c.edgeFraction += field.edgeSamples / pixels;
                c.fallbacks += field.warp.fallback != Fallback::None;
                c.depthFields += field.warp.model == WarpModel::Depth;
                ++c.fallbackCounts[static_cast<int>(field.warp.fallback)];
                ++c.samples;
            }
        }
    }
    for (EvalCell& c : result.cells) {
        if (c.samples == 0) continue;
        c.psnrDb /= c.samples;
        c.maePct /= c.samples;
        c.nsPerPixel /= c.samples;
        c.edgeFraction /= c.samples;
    }
    result.renderMs =
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
    return result;
}

EvalResult combine(const std::vector<EvalResult>& parts) {
    EvalResult out;
    if (parts.empty()) return out;
    out.cells = parts.front().cells;
    for (EvalCell& c : out.cells) {
        c.psnrDb = c.maePct = c.nsPerPixel = c.edgeFraction = 0.0;
        c.fallbacks = c.samples = c.depthFields = 0;
        c.fallbackCounts = {};
    }
    for (const EvalResult& p : parts) {
        out.baseFrames += p.baseFrames;
        out.rolledTruths += p.rolledTruths;
        out.renderMs += p.renderMs;
        for (std::size_t i = 0; i < out.cells.size() && i < p.cells.size(); ++i) {
            const EvalCell& s = p.cells[i];
            EvalCell& c = out.cells[i];
            c.psnrDb += s.psnrDb * s.samples;
            c.maePct += s.maePct * s.samples;
            c.nsPerPixel += s.nsPerPixel * s.samples;
            c.edgeFraction += s.edgeFraction * s.samples;
            c.fallbacks += s.fallbacks;
            c.depthFields += s.depthFields;
            for (int f = 0; f < 4; ++f)
                c.fallbackCounts[f] += s.fallbackCounts[f];
            c.samples += s.samples;
        }
    }
    for (EvalCell& c : out.cells) {
        if (c.samples == 0) continue;
        c.psnrDb /= c.samples;
        c.maePct /= c.samples;
        c.nsPerPixel /= c.samples;
        c.edgeFraction /= c.samples;
    }
    return out;
}

}  // namespace prp
