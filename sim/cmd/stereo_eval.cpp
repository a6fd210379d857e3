// stereo-eval: over a pose sweep, the reprojected right eye's time (as a share of the left eye's)
// and its error against a full ray cast of the right eye, per reprojection configuration.
#include "base/text.hpp"
#include "ig/caster.hpp"
#include "ig/cli.hpp"
#include "ig/error.hpp"
#include "ig/image_compare.hpp"
#include "ig/pose_sweep.hpp"
#include "ig/stereo.hpp"
#include "io/output_file.hpp"
#include "io/stop_signals.hpp"
#include "io/text_file.hpp"

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <iostream>
#include <limits>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

namespace {

constexpr const char* kNotes = R"(What it measures:
  For every pose the left eye is cast by the fast caster (with depth) and the right eye both
  fully cast (the reference) and reprojected from the left by each configuration:
    abuffer          Wan: right-to-left hidden-reprojection removal, 1x8 A-buffer, gaps up to
                     --gap-threshold pixels interpolated, wider ones ray cast
    abuffer-sweep    the same by the sweep with one running pixel (the twin of the rows on
                     vector lanes: the same image, the number of pixels that differ printed)
    integer          the same with integer placement (no A-buffer)
    abuffer-gapT     the A-buffer with gap threshold T (one per --extra-gaps value)
    adelson-hodges   left-to-right overwrite at integer positions, gaps cleared and ray cast
    raycast          the full cast of the right eye itself (time reference, zero error)
  right_over_left = sum of right-eye times / sum of left-eye times over the poses (each time the
  least of --repeat runs); pass1_ms and pass2_ms: the reprojection's and the second pass's
  time per frame (mean over the poses). mae_pct = mean absolute colour error in % of full scale against the
  full cast, averaged over poses; psnr_db from the mean squared error over all poses.
  Eye separation: --stereo M metres, or --stereo-agl K times the eye's height above the terrain
  under it (the default, K = 0.02, keeps the disparity a few pixels at any altitude).
  --poses FILE: one x,y,z,yaw,pitch,roll per line (metres, degrees; z may be +H above the
  terrain; roll must be 0); '#' starts a comment.)";

struct Config {
    std::string name;
    ig::StereoOptions options;
    bool fullCast = false;
};

struct Totals {
    double rightMs = 0.0, maePct = 0.0, mse = 0.0;
    double reprojectMs = 0.0, castMs = 0.0;  // the right eye's two passes (summed over poses)
    double reprojected = 0.0, interpolated = 0.0, rayCast = 0.0;
    std::uint64_t differ = 0;  // abuffer-sweep: pixels whose colour or depth differ from abuffer's
};

double mseOf(const std::vector<ig::Rgb8>& a, const std::vector<ig::Rgb8>& b) {
    const double psnr = ig::psnrDb(a, b);
    return std::isinf(psnr) ? 0.0 : 255.0 * 255.0 / std::pow(10.0, psnr / 10.0);
}

std::vector<ig::Pose> readPoses(const std::string& path, const ig::TerrainMap& map) {
    std::string text, why;
    if (io::readTextFile(path, text, &why) != 0)
        throw ig::InputError("--poses " + path + ": " + why);
    std::vector<int> lines;
    std::vector<ig::Pose> poses = ig::parsePoseList(text, map, "--poses " + path, &lines);
    for (std::size_t k = 0; k < poses.size(); ++k) {
        if (poses[k].roll != 0.0) {
            throw ig::InputError("--poses " + path + " line " + std::to_string(lines[k]) +
                                 ": stereo renders roll = 0");
        }
    }
    return poses;
}

std::vector<double> parseList(const std::string& text, const std::string& what) {
    std::vector<double> values;
    std::stringstream ss(text);
    std::string part;
    while (std::getline(ss, part, ',')) {
        if (part.empty()) continue;
        std::size_t used = 0;
        double v = -1.0;
        try {
            v = std::stod(part, &used);
        } catch (const std::exception&) {
            used = 0;
        }
        if (used != part.size() || !std::isfinite(v) || v < 0.0) {
            throw ig::InputError(what + ": '" + part + "' is not a number >= 0");
        }
        values.push_back(v);
    }
    return values;
}

}  // namespace

int main(int argc, char** argv) {
    CLI::App app{"Stereo: reprojected right eye against a full ray cast, over a pose sweep."};
    app.footer(kNotes);
    ig::TerrainOptions terrain;
    ig::addTerrainOptions(app, terrain);
    ig::AppearanceOptions look;
    ig::addAppearanceOptions(app, look);
    std::string sizeText = "720x486", posesPath, jsonPath, extraGaps = "1,4";
    double fovDeg = 60.0, gapThreshold = 2.0, aglFactor = 0.02;
    std::optional<double> separation;
    int sweep = 20, repeat = 1, threads = 1;
    app.add_option("--size", sizeText, "Image size WxH")->capture_default_str();
    app.add_option("--fov", fovDeg, "Horizontal field of view, degrees")->capture_default_str();
    auto* stereoOpt = app.add_option("--stereo", separation, "Eye separation, metres");
    app.add_option("--stereo-agl", aglFactor,
                   "Eye separation as a multiple of the height above the terrain")
        ->capture_default_str()
        ->excludes(stereoOpt);
    app.add_option("--poses", posesPath, "File of x,y,z,yaw,pitch,roll lines (else a sweep)");
    app.add_option("--sweep", sweep, "Poses in the built-in sweep")->capture_default_str();
    app.add_option("--gap-threshold", gapThreshold, "Gap threshold of abuffer/integer, pixels")
        ->capture_default_str();
    app.add_option("--extra-gaps", extraGaps, "More A-buffer gap thresholds to compare (list)")
        ->capture_default_str();
    app.add_option("--repeat", repeat, "Runs per timing (the least is kept)")
        ->capture_default_str();
    app.add_option("--threads", threads, "Worker threads (0: all cores)")->capture_default_str();
    std::string clockText = "auto";
    app.add_option("--clock", clockText,
                   "Times: cpu (the calling thread's CPU time; needs --threads 1) | wall | auto "
                   "(cpu with one thread, else wall)")
        ->capture_default_str();
    app.add_option("--json", jsonPath, "Results as JSON ('-': standard output)");
    std::string kernelText = "auto";
    app.add_option("--kernel", kernelText,
                   "Fast caster's kernel: auto | scalar | avx2 | avx512 | rows4-portable | "
                   "rows8-portable (docs/design/ray_casting.md)")
        ->capture_default_str();
    CLI11_PARSE(app, argc, argv);

    return ig::runProgram("stereo-eval", [&]() -> int {
        // A signal ends the run at once (its one file is written at the end).
        io::installStopSignals(true);
        io::checkRunPaths({{"--height", terrain.height, io::PathRole::Input},
                           {"--color", terrain.color, io::PathRole::Input},
                           {"--poses", posesPath, io::PathRole::Input},
                           {"--json", jsonPath, io::PathRole::Output}});
        if (!(fovDeg > 0.0 && fovDeg < 179.0)) {
            throw ig::InputError("--fov: must be between 0 and 179 degrees");
        }
        if (sweep < 2 || sweep > 100000) throw ig::InputError("--sweep: must be 2..100000");
        if (repeat < 1 || repeat > 100) throw ig::InputError("--repeat: must be 1..100");
        if (threads < 0 || threads > 1024) throw ig::InputError("--threads: must be 0..1024");
        if (!std::isfinite(aglFactor) || aglFactor < 0.0) {
            throw ig::InputError("--stereo-agl: must be a finite number >= 0");
        }
        const bool fixedSeparation = separation.has_value();
        if (fixedSeparation &&
            !(std::isfinite(*separation) && *separation >= 0.0 && *separation <= 1e4)) {
            throw ig::InputError("--stereo: the eye separation must be 0 .. 10000 metres");
        }
        if (clockText != "auto" && clockText != "cpu" && clockText != "wall") {
            throw ig::InputError("--clock '" + clockText + "': expected cpu, wall or auto");
        }
        if (clockText == "cpu" && threads != 1) {
            throw ig::InputError("--clock cpu: measures one thread; give --threads 1");
        }
        const bool useCpu = clockText == "cpu" || (clockText == "auto" && threads == 1);
        const auto [w, h] = ig::parseSize(sizeText);
        ig::TerrainMap map = ig::loadTerrainFromOptions(terrain);
        const ig::Appearance appearance = ig::parseAppearance(look, terrain, map);
        const std::vector<ig::Pose> poses =
            posesPath.empty() ? ig::sweepPoses(map, sweep) : readPoses(posesPath, map);
        // A pose far off the map is a mistake of coordinates; say so rather than skip it.
        for (std::size_t k = 0; k < poses.size(); ++k) {
            const glm::dvec3 p = poses[k].position;
            if (!ig::nearMap(map, p.x, p.y)) {
                char buf[320];
                std::snprintf(buf, sizeof buf,
                              "pose %zu at (%s, %s) lies far off the map (which spans x 0..%.1f, "
                              "y 0..%.1f m): x and y are metres east and north of the map's "
                              "south-west sample",
                              k + 1, base::number(p.x).c_str(), base::number(p.y).c_str(),
                              map.extentX(), map.extentY());
                throw ig::InputError("--poses " + posesPath + ": " + buf);
            }
        }
        const ig::Intrinsics intr = ig::Intrinsics::fromFov(w, h, ig::degToRad(fovDeg));
        ig::RenderOptions renderOptions;
        renderOptions.threads = threads;
        ig::applyAppearance(appearance, map, renderOptions);
        renderOptions.kernel = ig::parseCasterKernel(kernelText);

        std::vector<Config> configs;
        ig::StereoOptions base;
        base.gapThreshold = gapThreshold;
        configs.push_back({"abuffer", base});
        // The A-buffer by the sweep with one running pixel: the twin of the rows on vector
        // lanes (same image), for their time.
        ig::StereoOptions twin = base;
        twin.referenceSweep = true;
        configs.push_back({"abuffer-sweep", twin});
        base.abuffer = false;
        configs.push_back({"integer", base});
        for (const double t : parseList(extraGaps, "--extra-gaps")) {
            if (t == gapThreshold) continue;
            ig::StereoOptions o;
            o.gapThreshold = t;
            char name[64];
            std::snprintf(name, sizeof name, "abuffer-gap%g", t);
            configs.push_back({name, o});
        }
        ig::StereoOptions ah;
        ah.variant = ig::ReprojectVariant::AdelsonHodges;
        ah.abuffer = false;
        configs.push_back({"adelson-hodges", ah});
        configs.push_back({"raycast", {}, true});
        for (Config& c : configs)
            ig::validateStereoOptions(c.options);

        const auto caster = ig::makeCaster(ig::CasterKind::Fast, map, renderOptions);
        std::vector<Totals> totals(configs.size());
        double leftMs = 0.0;
        int used = 0, skipped = 0;
        nlohmann::json perPose = nlohmann::json::array();
        for (std::size_t k = 0; k < poses.size(); ++k) {
            const ig::Pose& pose = poses[k];
            const double agl =
                pose.position.z - map.surfaceHeight(pose.position.x, pose.position.y);
            const double e = fixedSeparation ? *separation : aglFactor * std::max(agl, 0.0);
            const ig::Pose rightPose = ig::rightEyePose(pose, e);
            if (rightPose.position.z <=
                map.surfaceHeight(rightPose.position.x, rightPose.position.y)) {
                ++skipped;  // the right eye would be inside the terrain
                continue;
            }
            // Left eye and the reference (the right eye fully cast): each the least time of
            // --repeat renders by the caster itself.
            auto timeRender = [&](const ig::Pose& p, ig::RenderedFrame& frame) {
                frame = ig::renderFrame(*caster, map, p, intr);
                double best = std::numeric_limits<double>::infinity();
                const ig::Camera camera(p, intr);
                for (int r = 0; r < repeat; ++r) {
                    const double cpu0 = ig::threadCpuMs();
                    const auto wall0 = std::chrono::steady_clock::now();
                    caster->render(camera, frame);
                    const double ms = useCpu ? ig::threadCpuMs() - cpu0
                                             : std::chrono::duration<double, std::milli>(
                                                   std::chrono::steady_clock::now() - wall0)
                                                   .count();
                    best = std::min(best, ms);
                }
                return best;
            };
            ig::RenderedFrame left, full, abufferRight;
            const double poseLeftMs = timeRender(pose, left);
            leftMs += poseLeftMs;
            const double fullMs = timeRender(rightPose, full);
            const double n = static_cast<double>(full.color.size());
            nlohmann::json pj = {{"pose", k},
                                 {"x", pose.position.x},
                                 {"y", pose.position.y},
                                 {"z", pose.position.z},
                                 {"yaw_deg", ig::radToDeg(pose.yaw)},
                                 {"pitch_deg", ig::radToDeg(pose.pitch)},
                                 {"eye_separation_m", e},
                                 {"left_ms", poseLeftMs}};
            for (std::size_t c = 0; c < configs.size(); ++c) {
                Totals& t = totals[c];
                if (configs[c].fullCast) {
                    t.rightMs += fullMs;
                    t.rayCast += 1.0;
                    pj["configs"][configs[c].name] = {{"right_ms", fullMs}};
                    continue;
                }
                ig::StereoStats best;
                best.rightMs = std::numeric_limits<double>::infinity();
                ig::RenderedFrame right;
                std::vector<ig::RightPixelSource> source;
                for (int r = 0; r < repeat; ++r) {
                    ig::StereoStats stats;
                    ig::StereoOptions options = configs[c].options;
                    options.eyeSeparation = e;
                    right = ig::reprojectRightEye(map, left, options, renderOptions, source, stats,
                                                  caster.get());
                    if (useCpu) stats.rightMs = stats.rightCpuMs;
                    if (stats.rightMs < best.rightMs) best = stats;
                }
                if (c == 0) abufferRight = right;
                if (configs[c].options.referenceSweep) {
                    for (std::size_t i = 0; i < right.color.size(); ++i) {
                        t.differ += !(right.color[i] == abufferRight.color[i]) ||
                                    std::memcmp(&right.depth[i], &abufferRight.depth[i],
                                                sizeof(float)) != 0;
                    }
                }
                const double mae = ig::meanAbsErrorPct(right.color, full.color);
                t.rightMs += best.rightMs;
                t.reprojectMs += best.reprojectMs;
                t.castMs += best.castMs;
                t.maePct += mae;
                t.mse += mseOf(right.color, full.color);
                t.reprojected += best.reprojected / n;
                t.interpolated += best.interpolated / n;
                t.rayCast += best.rayCast / n;
                pj["configs"][configs[c].name] = {{"right_ms", best.rightMs},
                                                  {"reproject_ms", best.reprojectMs},
                                                  {"cast_ms", best.castMs},
                                                  {"cast_steps", best.steps},
                                                  {"cast_restarts", best.restarts},
                                                  {"sky_without_cast", best.skyWithoutCast},
                                                  {"mae_pct", mae},
                                                  {"ray_cast_fraction", best.rayCast / n}};
            }
            ++used;
            perPose.push_back(pj);
        }
        if (used == 0) throw ig::InputError("no pose left: every right eye is inside the terrain");

        nlohmann::json j;
        j["terrain"] = ig::describeTerrain(map);
        j["width"] = w;
        j["height"] = h;
        j["fov_deg"] = fovDeg;
        j["poses"] = used;
        j["poses_skipped"] = skipped;
        j["threads"] = threads;
        j["kernel"] = std::string(caster->kernelName());
        j["repeat"] = repeat;
        j["clock"] = useCpu ? "thread_cpu" : "wall";
        if (fixedSeparation) {
            j["eye_separation_m"] = *separation;
        } else {
            j["eye_separation_agl"] = aglFactor;
        }
        j["left_ms_mean"] = leftMs / used;
        // The table goes to standard error when the JSON takes standard output.
        std::FILE* table = jsonPath == "-" ? stderr : stdout;
        std::fprintf(table, "%s\n%dx%d, %d poses (%d skipped), left eye %.2f ms mean\n",
                     ig::describeTerrain(map).c_str(), w, h, used, skipped, leftMs / used);
        std::fprintf(table, "%-16s %10s %9s %9s %8s %8s %8s %9s %8s\n", "config", "right/left",
                     "mae_pct", "psnr_db", "reproj", "interp", "cast", "pass1_ms", "pass2_ms");
        for (std::size_t c = 0; c < configs.size(); ++c) {
            const Totals& t = totals[c];
            const double mse = t.mse / used;
            const double psnr = mse > 0.0 ? 10.0 * std::log10(255.0 * 255.0 / mse)
                                          : std::numeric_limits<double>::infinity();
            const double ratio = t.rightMs / leftMs;
            std::fprintf(table, "%-16s %10.4f %9.3f %9.2f %8.4f %8.4f %8.4f",
                         configs[c].name.c_str(), ratio, t.maePct / used, psnr,
                         t.reprojected / used, t.interpolated / used, t.rayCast / used);
            if (configs[c].fullCast) {
                std::fprintf(table, "\n");
            } else {
                std::fprintf(table, " %9.3f %8.3f\n", t.reprojectMs / used, t.castMs / used);
            }
            nlohmann::json r = {
                {"config", configs[c].name},
                {"right_over_left", ratio},
                {"right_ms_mean", t.rightMs / used},
                {"mae_pct", t.maePct / used},
                {"psnr_db", std::isfinite(psnr) ? nlohmann::json(psnr) : nlohmann::json(nullptr)},
                {"reprojected_fraction", t.reprojected / used},
                {"interpolated_fraction", t.interpolated / used},
                {"ray_cast_fraction", t.rayCast / used}};
            if (!configs[c].fullCast) {
                r["gap_threshold_px"] = configs[c].options.gapThreshold;
                r["reproject_ms_mean"] = t.reprojectMs / used;
                r["cast_ms_mean"] = t.castMs / used;
            }
            if (configs[c].options.referenceSweep) r["pixels_differing_from_abuffer"] = t.differ;
            j["results"].push_back(r);
        }
        for (std::size_t c = 0; c < configs.size(); ++c) {
            if (configs[c].options.referenceSweep) {
                std::fprintf(table, "%s: %llu pixels differ from abuffer's (colour or depth)\n",
                             configs[c].name.c_str(),
                             static_cast<unsigned long long>(totals[c].differ));
            }
        }
        j["per_pose"] = perPose;
        if (!jsonPath.empty()) io::writeTextOutput("--json", jsonPath, j.dump(2) + "\n");
        return 0;
    });
}
