// warp-eval: speed against error of the post-rendering warp models along trajectories.
#include "ig/caster.hpp"
#include "ig/cli.hpp"
#include "ig/error.hpp"
#include "io/output_file.hpp"
#include "io/stop_signals.hpp"
#include "prp/evaluation.hpp"
#include "sim/trajectory.hpp"
#include "sim/trajectory_poses.hpp"

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <optional>
#include <sstream>

namespace {

// Where the tables go: standard output, or standard error when an output is written there.
std::FILE* tableOut = stdout;

constexpr const char* kNotes = R"(For base frames spread along each trajectory, a frame with margins
is rendered by the fast caster (--levels) at time t (roll 0), warped by each model to t + k * 1001/60000 s,
and compared with a true render at that pose (the reference caster where the pose is rolled):
PSNR and mean absolute error (% of full scale) over the field's lines, averaged over base frames.
Without --trajectory every CSV in the shipped data/trajectories folder is evaluated; over a map
other than the shipped one each is laid over it: moved to its centre, scaled to fit, heights taken
above the highest ground under the path.
Plot the CSV with scripts/plot-warp-eval.sh (gnuplot).)";

std::vector<int> parseHorizons(const std::string& text) {
    std::vector<int> ks;
    std::stringstream ss(text);
    std::string item;
    while (std::getline(ss, item, ',')) {
        const std::size_t dots = item.find("..");
        try {
            std::size_t used = 0;
            if (dots != std::string::npos) {
                const int a = std::stoi(item.substr(0, dots), &used);
                const int b = std::stoi(item.substr(dots + 2));
                if (a < 1 || b < a || b > 600) throw std::invalid_argument("range");
                for (int k = a; k <= b; ++k)
                    ks.push_back(k);
            } else {
                const int k = std::stoi(item, &used);
                if (used != item.size() || k < 1 || k > 600) throw std::invalid_argument("k");
                ks.push_back(k);
            }
        } catch (const std::exception&) {
            throw ig::InputError("--horizons: '" + item +
                                 "' is not a field count 1..600 or a range A..B");
        }
    }
    if (ks.empty()) throw ig::InputError("--horizons: empty");
    std::sort(ks.begin(), ks.end());
    ks.erase(std::unique(ks.begin(), ks.end()), ks.end());
    return ks;
}

std::vector<prp::WarpModel> parseModels(const std::string& text) {
    std::vector<prp::WarpModel> models;
    std::stringstream ss(text);
    std::string item;
    while (std::getline(ss, item, ',')) {
        const auto m = prp::parseWarpModel(item);
        if (!m) {
            throw ig::InputError("--models: unknown model '" + item +
                                 "' (poly, affine, homography, depth, auto, hold)");
        }
        if (std::find(models.begin(), models.end(), *m) == models.end()) models.push_back(*m);
    }
    if (models.empty()) throw ig::InputError("--models: empty");
    return models;
}

nlohmann::json cellsJson(const prp::EvalResult& r) {
    nlohmann::json a = nlohmann::json::array();
    for (const prp::EvalCell& c : r.cells) {
        a.push_back({{"model", prp::warpModelName(c.model)},
                     {"horizon", c.horizon},
                     {"psnr_db", c.psnrDb},
                     {"mae_pct", c.maePct},
                     {"ns_per_pixel", c.nsPerPixel},
                     {"fallbacks", c.fallbacks},
                     {"fallback_affine", c.fallbackCounts[1]},
                     {"fallback_rotation", c.fallbackCounts[2]},
                     {"fallback_hold", c.fallbackCounts[3]},
                     {"edge_fraction", c.edgeFraction},
                     {"depth_fields", c.depthFields},
                     {"base_frames", c.samples}});
    }
    return a;
}

void printTable(const std::string& title, const prp::EvalResult& r,
                const std::vector<int>& horizons) {
    std::fprintf(tableOut, "\n%s (%d base frames)\n", title.c_str(), r.baseFrames);
    std::fprintf(tableOut, "%-11s", "model");
    for (const int k : horizons)
        std::fprintf(tableOut, "  k=%-10d", k);
    std::fprintf(tableOut, "  %9s %9s %8s %7s\n", "ns/px", "fallbacks", "edge%", "depth%");
    std::size_t i = 0;
    while (i < r.cells.size()) {
        const prp::WarpModel m = r.cells[i].model;
        std::fprintf(tableOut, "%-11s", std::string(prp::warpModelName(m)).c_str());
        double ns = 0, edge = 0;
        int fb = 0, n = 0, depth = 0, fields = 0;
        for (; i < r.cells.size() && r.cells[i].model == m; ++i) {
            const prp::EvalCell& c = r.cells[i];
            std::fprintf(tableOut, "  %5.2f/%5.2f%%", c.psnrDb, c.maePct);
            ns += c.nsPerPixel;
            edge += c.edgeFraction;
            fb += c.fallbacks;
            depth += c.depthFields;
            fields += c.samples;
            ++n;
        }
        std::fprintf(tableOut, "  %9.2f %9d %8.3f %7.1f\n", ns / n, fb, 100.0 * edge / n,
                     100.0 * depth / std::max(fields, 1));
    }
    std::fprintf(tableOut,
                 "(cells: PSNR dB / mean absolute error %% of full scale; depth%%: fields warped "
                 "by the depth model)\n");
}

}  // namespace

int main(int argc, char** argv) {
    CLI::App app{"Post-rendering warp models: error against horizon, and time per pixel."};
    app.footer(kNotes);
    ig::TerrainOptions terrain;
    ig::addTerrainOptions(app, terrain);
    ig::AppearanceOptions look;
    ig::addAppearanceOptions(app, look);
    std::vector<std::string> trajectories;
    std::string sizeText = "320x240", horizonsText = "1..8",
                modelsText = "poly,affine,homography,depth,auto,hold";
    std::string jsonPath, csvPath, levelsText = "auto", casterText = "fast";
    int margin = 32, frames = 3, repeats = 3;
    double fovDeg = 60.0;
    bool noSky = false;
    std::string edgeFillText = "sky";
    std::string depthWarpText = "splat";
    prp::EvalConfig config;
    app.add_option("--trajectory", trajectories, "Trajectory CSV (repeatable)");
    app.add_option("--size", sizeText, "Output window WxH")->capture_default_str();
    app.add_option("--margin", margin, "Rendered margin, pixels per side")->capture_default_str();
    app.add_option("--fov", fovDeg, "Horizontal field of view, degrees")->capture_default_str();
    app.add_option("--horizons", horizonsText, "Fields ahead: list and/or ranges, e.g. 1..8")
        ->capture_default_str();
    app.add_option("--models", modelsText, "Comma-separated warp models")->capture_default_str();
    app.add_option("--frames", frames, "Base frames per trajectory")->capture_default_str();
    app.add_option("--repeats", repeats, "Timing repeats per warp (fastest counts)")
        ->capture_default_str();
    app.add_option("--caster", casterText,
                   "Caster of the base frames: fast | span (steep frames by the fast caster)")
        ->capture_default_str();
    app.add_option("--levels", levelsText,
                   "Fast caster: auto (the multiresolution caster) | 0 (single level, exact)")
        ->capture_default_str();
    app.add_option("--auto-threshold", config.autoThresholdPx,
                   "Auto model: largest check-point error of the quadratic, rendered pixels")
        ->capture_default_str();
    app.add_flag("--no-sky", noSky, "Fit terrain control points only (drop sky directions)");
    app.add_option("--edge-fill", edgeFillText,
                   "Where a field samples beyond the rendered frame: sky (the sky colour above "
                   "the horizon, the edge pixel below) | sky-haze (the haze colour below) | "
                   "repeat (the edge pixel)")
        ->capture_default_str();
    app.add_option("--depth-warp", depthWarpText,
                   "How the depth model (and auto's depth fields) finds source points: gather "
                   "(Newton steps from the quadratic, the splat where they do not settle) | splat "
                   "(every rendered pixel projected, z-tested)")
        ->capture_default_str();
    app.add_option("--json", jsonPath, "Results as JSON");
    app.add_option("--csv", csvPath, "Results as CSV");
    CLI11_PARSE(app, argc, argv);

    return ig::runProgram("warp-eval", [&]() -> int {
        // A signal ends the run at once (its files are written at the end). Every path is
        // checked before the run: no output on an input or another output.
        io::installStopSignals(true);
        std::vector<io::PathUse> paths = {{"--height", terrain.height, io::PathRole::Input},
                                          {"--color", terrain.color, io::PathRole::Input},
                                          {"--json", jsonPath, io::PathRole::Output},
                                          {"--csv", csvPath, io::PathRole::Output}};
        for (const std::string& t : trajectories)
            paths.push_back({"--trajectory", t, io::PathRole::Input});
        io::checkRunPaths(paths);
        // The tables go to standard error when an output takes standard output.
        if (io::usesStdout(paths)) tableOut = stderr;
        if (!(fovDeg > 0.0 && fovDeg < 179.0)) {
            throw ig::InputError("--fov: must be between 0 and 179 degrees");
        }
        if (margin < 0 || margin > 4096) throw ig::InputError("--margin: must be 0..4096 pixels");
        if (frames < 1 || frames > 10000) throw ig::InputError("--frames: must be 1..10000");
        if (repeats < 1 || repeats > 1000) throw ig::InputError("--repeats: must be 1..1000");
        ig::RenderOptions renderOptions;
        renderOptions.levels = ig::parseLevels(levelsText);
        const ig::CasterKind casterKind = ig::parseCasterKind(casterText);
        if (!ig::casterNeedsLevelRoll(casterKind)) {
            throw ig::InputError("--caster " + casterText + ": expected fast or span");
        }
        if (!(config.autoThresholdPx > 0.0 && config.autoThresholdPx <= 1e6)) {
            throw ig::InputError("--auto-threshold: must be a positive number of pixels");
        }
        std::tie(config.width, config.height) = ig::parseSize(sizeText);
        if (config.width % 2 != 0) throw ig::InputError("--size: width must be even");
        config.margin = margin;
        config.hfov = ig::degToRad(fovDeg);
        config.horizons = parseHorizons(horizonsText);
        config.models = parseModels(modelsText);
        config.baseFrames = frames;
        config.timingRepeats = repeats;
        config.useSky = !noSky;
        const std::optional<prp::EdgeFill> edgeFill = prp::parseEdgeFill(edgeFillText);
        if (!edgeFill) {
            throw ig::InputError("--edge-fill: expected sky, sky-haze or repeat, got '" +
                                 edgeFillText + "'");
        }
        config.edgeFill = *edgeFill;
        const std::optional<prp::DepthMethod> depthMethod = prp::parseDepthMethod(depthWarpText);
        if (!depthMethod) {
            throw ig::InputError("--depth-warp: expected gather or splat, got '" + depthWarpText +
                                 "'");
        }
        config.depthMethod = *depthMethod;
        const bool shippedTrajectories = trajectories.empty();
        if (shippedTrajectories) {
            const std::filesystem::path dir = std::filesystem::path(VIG_DATA_DIR) / "trajectories";
            std::error_code ec;
            for (const auto& e : std::filesystem::directory_iterator(dir, ec)) {
                if (e.path().extension() == ".csv") trajectories.push_back(e.path().string());
            }
            if (ec || trajectories.empty()) {
                throw ig::InputError(dir.string() + ": no trajectory CSV files");
            }
            std::sort(trajectories.begin(), trajectories.end());
        }
        std::vector<sim::Trajectory> loaded;
        for (const std::string& p : trajectories)
            loaded.push_back(sim::Trajectory::loadCsv(p));

        ig::TerrainMap map = ig::loadTerrainFromOptions(terrain);
        ig::applyAppearance(ig::parseAppearance(look, terrain, map), map, renderOptions);
        config.sky = renderOptions.sky;
        std::fprintf(tableOut, "terrain: %s\n", ig::describeTerrain(map).c_str());
        // The shipped trajectories are flown over Puget Sound; over another map they are laid
        // over it (scaled to fit, heights above its highest ground under the path).
        if (shippedTrajectories && !ig::usesShippedMap(terrain)) {
            for (std::size_t i = 0; i < loaded.size(); ++i) {
                const sim::FittedTrajectory f = sim::fitTrajectoryToMap(loaded[i], map);
                std::fprintf(tableOut, "%s: laid over the map, scale %.3g, heights above %.1f m\n",
                             trajectories[i].c_str(), f.scale, f.ground);
                loaded[i] = f.trajectory;
            }
        }
        for (std::size_t i = 0; i < loaded.size(); ++i)
            sim::checkTrajectoryClearance(loaded[i], map, trajectories[i]);
        const auto fast = ig::makeCaster(casterKind, map, renderOptions);
        const auto reference = ig::makeCaster(ig::CasterKind::Reference, map, renderOptions);

        std::vector<prp::EvalResult> parts;
        nlohmann::json perTrajectory = nlohmann::json::array();
        for (std::size_t i = 0; i < loaded.size(); ++i) {
            const sim::Trajectory& tr = loaded[i];
            const prp::EvalResult r = prp::evaluateWarps(
                map, *fast, *reference, [&](double t) { return tr.poseAt(t); }, tr.startTime(),
                tr.endTime(), config);
            printTable(trajectories[i], r, config.horizons);
            perTrajectory.push_back({{"trajectory", trajectories[i]},
                                     {"base_frames", r.baseFrames},
                                     {"rolled_truths", r.rolledTruths},
                                     {"results", cellsJson(r)}});
            parts.push_back(r);
        }
        const prp::EvalResult all = prp::combine(parts);
        printTable("all trajectories", all, config.horizons);

        if (!jsonPath.empty()) {
            nlohmann::json j;
            j["size"] = {config.width, config.height};
            j["levels"] = levelsText;
            j["caster"] = casterText;
            j["margin"] = config.margin;
            j["fov_deg"] = fovDeg;
            j["depth_warp"] = depthWarpText;
            j["field_period_s"] = prp::kFieldPeriod;
            j["terrain"] = ig::describeTerrain(map);
            j["results"] = cellsJson(all);
            j["trajectories"] = perTrajectory;
            io::writeTextOutput("--json", jsonPath, j.dump(2) + "\n");
        }
        if (!csvPath.empty()) {
            std::ostringstream out;
            out << "trajectory,model,horizon,psnr_db,mae_pct,ns_per_pixel,fallbacks,edge_"
                   "fraction\n";
            auto rows = [&](const std::string& name, const prp::EvalResult& r) {
                for (const prp::EvalCell& c : r.cells) {
                    out << name << ',' << prp::warpModelName(c.model) << ',' << c.horizon << ','
                        << c.psnrDb << ',' << c.maePct << ',' << c.nsPerPixel << ',' << c.fallbacks
                        << ',' << c.edgeFraction << '\n';
                }
            };
            for (std::size_t i = 0; i < parts.size(); ++i)
                rows(trajectories[i], parts[i]);
            rows("all", all);
            io::writeTextOutput("--csv", csvPath, out.str());
        }
        return 0;
    });
}
