// target-eval: moving targets through the post-rendering warp. A vehicle's centroid in warped
// fields against its centroid in truly rendered fields, by horizon.
#include "ig/caster.hpp"
#include "ig/cli.hpp"
#include "ig/error.hpp"
#include "ig/scene.hpp"
#include "ig/sticks.hpp"
#include "io/output_file.hpp"
#include "prp/processor.hpp"
#include "sim/pipeline.hpp"
#include "sim/scene_motion.hpp"
#include "sim/trajectory.hpp"
#include "sim/truth.hpp"

#include <time.h>
#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

namespace {

constexpr const char* kNotes =
    R"(For base frames spread along the camera trajectory, a frame with margins is rendered (naive
caster, objects drawn, moving ones stamped at the frame's instant, roll 0) and warped by each model
to t + k * 1001/60000 s; the same field is rendered truly (objects stamped at the field's instant,
the field's pose with roll). Each object's centroid in the warped ids is compared with its centroid
in the true render's ids (the field's lines of both): the moving target (--target) and, for
contrast, every static object visible in both. The warp follows the terrain's motion, not the
vehicle's: the moving target lags by its own motion over the frame's age, unless the processor
re-stamps the moving objects at the field's instant ("restamped": the same fields with each
moving object moved by its own image motion since the frame).)";

struct Stat {
    std::vector<double> v;
    nlohmann::json json() const {
        nlohmann::json j;
        j["n"] = v.size();
        if (v.empty()) return j;
        std::vector<double> s = v;
        std::sort(s.begin(), s.end());
        double sum = 0.0;
        for (const double x : s)
            sum += x;
        const auto at = [&](double q) {
            return s[static_cast<std::size_t>(std::lround(q * static_cast<double>(s.size() - 1)))];
        };
        j["mean"] = sum / static_cast<double>(s.size());
        j["p50"] = at(0.5);
        j["p95"] = at(0.95);
        j["max"] = s.back();
        return j;
    }
};

double threadCpuMs() {
    timespec ts{};
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
    return static_cast<double>(ts.tv_sec) * 1e3 + static_cast<double>(ts.tv_nsec) * 1e-6;
}

const sim::ObjectTruth* find(const sim::FieldTruth& t, std::uint16_t id) {
    for (const sim::ObjectTruth& o : t.objects)
        if (o.id == id) return &o;
    return nullptr;
}

}  // namespace

int main(int argc, char** argv) {
    CLI::App app{"Moving targets through the post-rendering warp: centroid error by horizon."};
    app.footer(kNotes);
    ig::TerrainOptions terrain;
    ig::addTerrainOptions(app, terrain);
    std::string scenePath = "data/scenes/puget-sound.json";
    std::string trajectoryPath = "data/scenes/village-pass.csv";
    std::string sizeText = "240x162";
    std::string modelsText = "poly,depth";
    std::string jsonPath;
    double fovDeg = 50.0;
    int frames = 12, horizons = 8, margin = 24, target = 8, minPixels = 8;
    app.add_option("--scene", scenePath, "Scene file")->capture_default_str();
    app.add_option("--trajectory", trajectoryPath, "Camera trajectory CSV")->capture_default_str();
    app.add_option("--size", sizeText, "Output window WxH")->capture_default_str();
    app.add_option("--fov", fovDeg, "Horizontal field of view, degrees")->capture_default_str();
    app.add_option("--margin", margin, "Rendered margin, pixels")->capture_default_str();
    app.add_option("--frames", frames, "Base frames along the trajectory")->capture_default_str();
    app.add_option("--horizons", horizons, "Horizons k = 1..N fields")->capture_default_str();
    app.add_option("--target", target, "Object id of the moving target")->capture_default_str();
    app.add_option("--min-px", minPixels, "Pixels an object must show in both fields")
        ->capture_default_str();
    app.add_option("--models", modelsText, "Warp models, comma separated")->capture_default_str();
    app.add_option("--json", jsonPath, "Write the figures as JSON");
    CLI11_PARSE(app, argc, argv);

    return ig::runProgram("target-eval", [&]() -> int {
        if (frames < 1 || frames > 1000) throw ig::InputError("--frames: must be 1..1000");
        if (horizons < 1 || horizons > 120) throw ig::InputError("--horizons: must be 1..120");
        if (target < 1 || target > 65535) throw ig::InputError("--target: must be 1..65535");
        if (!(fovDeg > 0.0 && fovDeg < 179.0)) throw ig::InputError("--fov: must be 0..179");
        if (margin < 0 || margin > 2048) throw ig::InputError("--margin: must be 0..2048");
        std::vector<prp::WarpModel> models;
        for (std::size_t at = 0; at <= modelsText.size();) {
            const std::size_t comma = std::min(modelsText.find(',', at), modelsText.size());
            const std::string name = modelsText.substr(at, comma - at);
            const std::optional<prp::WarpModel> m = prp::parseWarpModel(name);
            if (!m) throw ig::InputError("--models: unknown warp model '" + name + "'");
            models.push_back(*m);
            at = comma + 1;
        }
        const auto [width, height] = ig::parseSize(sizeText);
        if (!jsonPath.empty()) io::checkRunPaths({{"--json", jsonPath, io::PathRole::Output}});

        ig::TerrainMap map = ig::loadTerrainFromOptions(terrain);
        ig::Scene scene = ig::loadScene(scenePath, map);
        const sim::SceneMotion motion(scene);
        ig::includeStickTops(map, *scene.staticLayer);
        const sim::Trajectory camera = sim::Trajectory::loadCsv(trajectoryPath);
        bool known = false;
        for (const ig::MovingObject& m : scene.moving)
            known = known || m.id == target;
        if (!known) {
            throw ig::InputError("--target " + std::to_string(target) +
                                 ": not a moving object of " + scenePath);
        }

        sim::RenderGeometry geometry;
        geometry.windowWidth = width;
        geometry.windowHeight = height;
        geometry.hfov = ig::degToRad(fovDeg);
        geometry.margin = margin;
        const ig::Intrinsics window = sim::renderIntrinsics(geometry, ig::Pose{}).window();
        ig::ObjectLayer moving = motion.stamp(camera.startTime());
        ig::RenderOptions options;
        options.objects = {scene.staticLayer.get(), &moving};
        const auto caster = ig::makeCaster(ig::CasterKind::Naive, map, options);
        const sim::TruthScene truthScene(scene, motion, map);
        sim::TruthCamera truthCamera{window, width, height};
        sim::TruthComputer warpedTruth(1),
            trueTruth(1);  // one worker: its processor time is the cost

        sim::ObjectMotionBetween motionBetween(truthScene);
        struct PerK {
            std::vector<Stat> target, statics;  // per model
            // The same with the moving objects re-stamped at the field's instant.
            std::vector<Stat> targetRestamped, staticsRestamped;
            Stat targetMotion;  // true centroid's move since the frame, px
        };
        std::vector<PerK> perK(static_cast<std::size_t>(horizons));
        for (PerK& p : perK) {
            p.target.resize(models.size());
            p.statics.resize(models.size());
            p.targetRestamped.resize(models.size());
            p.staticsRestamped.resize(models.size());
        }
        const double span = camera.endTime() - camera.startTime();
        const double last = span - horizons * prp::kFieldPeriod;
        if (!(last > 0.0)) throw ig::InputError("--trajectory: shorter than the horizons");
        std::vector<std::uint16_t> trueIds;
        Stat truthMs;  // one field's truth (TruthComputer::compute), processor milliseconds
        prp::Field field;
        sim::FieldTruth warped, truth, atFrame;
        const auto start = std::chrono::steady_clock::now();
        for (int f = 0; f < frames; ++f) {
            const double tf = camera.startTime() + last * (f + 0.5) / frames;
            ig::Pose framePose = camera.poseAt(tf);
            framePose.roll = 0.0;  // the PRP applies roll
            moving = motion.stamp(tf);
            const ig::RenderedFrame frame = ig::renderFrame(
                *caster, map, framePose, sim::renderIntrinsics(geometry, camera.poseAt(tf)), tf);
            bool haveAtFrame = false;
            for (int k = 0; k <= horizons; ++k) {
                const double t = tf + k * prp::kFieldPeriod;
                const ig::Pose pose = camera.poseAt(t);
                moving = motion.stamp(t);
                const ig::RenderedFrame real = ig::renderFrame(*caster, map, pose, window, t);
                const std::uint64_t index = static_cast<std::uint64_t>(k);
                const int first = prp::fieldFirstLine(prp::fieldParity(index));
                const int lines = prp::fieldLines(height, prp::fieldParity(index));
                trueIds.resize(static_cast<std::size_t>(width) * lines);
                for (int l = 0; l < lines; ++l) {
                    std::copy_n(
                        real.objectId.begin() + static_cast<std::ptrdiff_t>(first + 2 * l) * width,
                        width, trueIds.begin() + static_cast<std::ptrdiff_t>(l) * width);
                }
                trueTruth.compute(truthScene, truthCamera, trueIds.data(), width, lines, first,
                                  pose, t, index, truth);
                const sim::ObjectTruth* tt = find(truth, static_cast<std::uint16_t>(target));
                if (k == 0) {
                    // The target where the frame shows it (rendered at the frame's instant).
                    haveAtFrame = tt && tt->visiblePx > 0;
                    if (haveAtFrame) atFrame = truth;
                    continue;
                }
                if (haveAtFrame && tt && tt->visiblePx > 0) {
                    const sim::ObjectTruth* t1 = find(atFrame, static_cast<std::uint16_t>(target));
                    perK[k - 1].targetMotion.v.push_back(std::hypot(
                        tt->centroid[0] - t1->centroid[0], tt->centroid[1] - t1->centroid[1]));
                }
                const std::span<const prp::ObjectMotion> motions = motionBetween.between(tf, t);
                for (std::size_t m = 0; m < models.size(); ++m) {
                    for (const bool restamp : {false, true}) {
                        prp::PrpOptions po;
                        po.outWidth = width;
                        po.outHeight = height;
                        po.format = prp::PixelFormat::Rgb8;
                        po.model = models[m];
                        prp::PostRenderingProcessor prp(po);
                        prp.process(frame, pose, t, index, field, std::nullopt, 0.0,
                                    restamp ? motions : std::span<const prp::ObjectMotion>{});
                        // Processor time of this thread: the figure a loaded machine leaves
                        // alone.
                        const double before = threadCpuMs();
                        warpedTruth.compute(truthScene, truthCamera, field.objectId.data(), width,
                                            field.lines, first, pose, t, index, warped);
                        if (!restamp) truthMs.v.push_back(threadCpuMs() - before);
                        PerK& p = perK[k - 1];
                        for (const sim::ObjectTruth& w : warped.objects) {
                            const sim::ObjectTruth* r = find(truth, w.id);
                            if (!r || w.visiblePx < static_cast<std::uint64_t>(minPixels) ||
                                r->visiblePx < static_cast<std::uint64_t>(minPixels)) {
                                continue;
                            }
                            const double e = std::hypot(w.centroid[0] - r->centroid[0],
                                                        w.centroid[1] - r->centroid[1]);
                            if (w.id == target) {
                                (restamp ? p.targetRestamped : p.target)[m].v.push_back(e);
                            } else {
                                (restamp ? p.staticsRestamped : p.statics)[m].v.push_back(e);
                            }
                        }
                    }
                }
            }
            std::fprintf(stderr, "\rframe %d/%d", f + 1, frames);
        }
        std::fprintf(stderr, "\n");
        const double seconds =
            std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();

        nlohmann::json j;
        j["scene"] = scenePath;
        j["trajectory"] = trajectoryPath;
        j["width"] = width;
        j["height"] = height;
        j["fov_deg"] = fovDeg;
        j["frames"] = frames;
        j["target"] = target;
        j["min_px"] = minPixels;
        j["seconds"] = seconds;
        j["truth_ms"] = truthMs.json();
        j["objects_in_scene"] = scene.staticLayer->objects().size() + scene.moving.size();
        std::printf(
            "truth of one field: mean %.2f ms, p95 %.2f ms of processor time (%zu fields)\n",
            truthMs.json()["mean"].get<double>(), truthMs.json()["p95"].get<double>(),
            truthMs.v.size());
        std::printf("centroid error, output pixels (mean / p95 / max over base frames)\n");
        std::printf("%3s  %-22s", "k", "target moved since t");
        for (const prp::WarpModel m : models) {
            const std::string name(prp::warpModelName(m));
            std::printf("  %-22s  %-22s  %-22s", (name + " target").c_str(),
                        (name + " target restamped").c_str(), (name + " static").c_str());
        }
        std::printf("\n");
        nlohmann::json rows = nlohmann::json::array();
        for (int k = 1; k <= horizons; ++k) {
            const PerK& p = perK[k - 1];
            nlohmann::json row;
            row["k"] = k;
            row["target_motion_px"] = p.targetMotion.json();
            const auto cell = [](const Stat& s) {
                const nlohmann::json js = s.json();
                char buf[64];
                if (s.v.empty()) return std::string("-");
                std::snprintf(buf, sizeof buf, "%.2f / %.2f / %.2f (%zu)", js["mean"].get<double>(),
                              js["p95"].get<double>(), js["max"].get<double>(), s.v.size());
                return std::string(buf);
            };
            std::printf("%3d  %-22s", k, cell(p.targetMotion).c_str());
            for (std::size_t m = 0; m < models.size(); ++m) {
                const std::string name(prp::warpModelName(models[m]));
                row[name]["target"] = p.target[m].json();
                row[name]["static"] = p.statics[m].json();
                row[name]["target_restamped"] = p.targetRestamped[m].json();
                row[name]["static_restamped"] = p.staticsRestamped[m].json();
                std::printf("  %-22s  %-22s  %-22s", cell(p.target[m]).c_str(),
                            cell(p.targetRestamped[m]).c_str(), cell(p.statics[m]).c_str());
            }
            std::printf("\n");
            rows.push_back(row);
        }
        j["horizons"] = rows;
        if (!jsonPath.empty()) io::writeTextOutput("--json", jsonPath, j.dump(2) + "\n");
        return 0;
    });
}
