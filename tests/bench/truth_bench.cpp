// Ground truth: the processor time of one field's exact truth line, and its slow twin's.
//
//   bench-truth [--scene FILE] [--start X,Y,Z,HEADING] [--size WxH] [--fov DEG] [--views N]
//               [--step M] [--repeat N] [--json FILE]
//
// Views along the flythrough's demo heading (--start, default the demo's low pass over the
// forest, --step metres apart, level): each is rendered once (fast caster, objects drawn) and
// its two fields' truth computed from the frame's own ids by TruthComputer on one worker, the
// fast path and the reference (TruthComputer(1, true)), --repeat times each, in turn. Processor
// time of the calling thread (CLOCK_THREAD_CPUTIME_ID), so other work on the machine changes it
// little. Every line of the fast path must equal the reference's: the program exits 1 otherwise.
#include "ig/caster.hpp"
#include "ig/cli.hpp"
#include "ig/scene.hpp"
#include "ig/sticks.hpp"
#include "ig/terrain_io.hpp"
#include "prp/field.hpp"
#include "sim/scene_motion.hpp"
#include "sim/truth.hpp"

#include <time.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <string>
#include <vector>

namespace {

double threadCpuMs() {
    timespec ts{};
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
    return static_cast<double>(ts.tv_sec) * 1e3 + static_cast<double>(ts.tv_nsec) * 1e-6;
}

nlohmann::json stats(std::vector<double> v) {
    std::sort(v.begin(), v.end());
    double sum = 0.0, sq = 0.0;
    for (const double x : v)
        sum += x;
    const double mean = sum / static_cast<double>(v.size());
    for (const double x : v)
        sq += (x - mean) * (x - mean);
    return {{"n", v.size()},
            {"mean", mean},
            {"sd", v.size() > 1 ? std::sqrt(sq / static_cast<double>(v.size() - 1)) : 0.0},
            {"p50", v[v.size() / 2]},
            {"max", v.back()}};
}

}  // namespace

int main(int argc, char** argv) {
    std::string scenePath = std::string(VIG_DATA_DIR) + "/scenes/puget-sound.json";
    std::string startText = "52250,37950,+120,40", jsonPath;
    int w = 720, h = 486, views = 6, repeat = 3;
    double fovDeg = 60.0, step = 60.0;
    for (int i = 1; i < argc; ++i) {
        if (!std::strcmp(argv[i], "--scene") && i + 1 < argc) {
            scenePath = argv[++i];
        } else if (!std::strcmp(argv[i], "--start") && i + 1 < argc) {
            startText = argv[++i];
        } else if (!std::strcmp(argv[i], "--size") && i + 1 < argc) {
            if (std::sscanf(argv[++i], "%dx%d", &w, &h) != 2 || w < 1 || h < 2) return 2;
        } else if (!std::strcmp(argv[i], "--fov") && i + 1 < argc) {
            fovDeg = std::atof(argv[++i]);
        } else if (!std::strcmp(argv[i], "--views") && i + 1 < argc) {
            views = std::max(1, std::atoi(argv[++i]));
        } else if (!std::strcmp(argv[i], "--step") && i + 1 < argc) {
            step = std::atof(argv[++i]);
        } else if (!std::strcmp(argv[i], "--repeat") && i + 1 < argc) {
            repeat = std::max(1, std::atoi(argv[++i]));
        } else if (!std::strcmp(argv[i], "--json") && i + 1 < argc) {
            jsonPath = argv[++i];
        } else {
            std::fprintf(stderr,
                         "usage: bench-truth [--scene FILE] [--start X,Y,Z,HEADING] [--size WxH] "
                         "[--fov DEG] [--views N] [--step M] [--repeat N] [--json FILE]\n");
            return 2;
        }
    }
    return ig::runProgram("bench-truth", [&]() -> int {
        ig::TerrainMap map = ig::loadPugetSound();
        const ig::Scene scene = ig::loadScene(scenePath, map);
        const sim::SceneMotion motion(scene);
        ig::includeStickTops(map, *scene.staticLayer);
        const ig::Pose start = ig::parsePose(startText + ",0,0", map, "--start");
        const ig::Intrinsics window = ig::Intrinsics::fromFov(w, h, ig::degToRad(fovDeg));
        ig::ObjectLayer moving = motion.stamp(0.0);
        ig::RenderOptions options;
        options.objects = {scene.staticLayer.get(), &moving};
        const auto caster = ig::makeCaster(ig::CasterKind::Fast, map, options);
        const sim::TruthScene truthScene(scene, motion, map);
        const sim::TruthCamera camera{window, w, h};
        sim::TruthComputer fast(1), reference(1, true);
        sim::FieldTruth a, b;
        std::vector<double> fastMs, referenceMs;
        std::vector<std::uint16_t> ids;
        std::uint64_t listed = 0, unoccluded = 0, fields = 0, mismatches = 0;
        for (int v = 0; v < views; ++v) {
            const double t = v * step / 50.0;
            ig::Pose pose = start;
            pose.position.x += v * step * std::sin(start.yaw);
            pose.position.y += v * step * std::cos(start.yaw);
            moving = motion.stamp(t);
            const ig::RenderedFrame frame = ig::renderFrame(*caster, map, pose, window, t);
            for (const prp::FieldParity parity :
                 {prp::FieldParity::Top, prp::FieldParity::Bottom}) {
                const int first = prp::fieldFirstLine(parity);
                const int lines = prp::fieldLines(h, parity);
                ids.resize(static_cast<std::size_t>(w) * lines);
                for (int l = 0; l < lines; ++l) {
                    std::copy_n(
                        frame.objectId.begin() + static_cast<std::ptrdiff_t>(first + 2 * l) * w, w,
                        ids.begin() + static_cast<std::ptrdiff_t>(l) * w);
                }
                for (int r = 0; r < repeat; ++r) {
                    double t0 = threadCpuMs();
                    fast.compute(truthScene, camera, ids.data(), w, lines, first, pose, t, fields,
                                 a);
                    fastMs.push_back(threadCpuMs() - t0);
                    t0 = threadCpuMs();
                    reference.compute(truthScene, camera, ids.data(), w, lines, first, pose, t,
                                      fields, b);
                    referenceMs.push_back(threadCpuMs() - t0);
                    if (sim::truthLine(a) != sim::truthLine(b)) ++mismatches;
                }
                listed += a.objects.size();
                for (const sim::ObjectTruth& o : a.objects)
                    unoccluded += o.unoccludedPx;
                ++fields;
            }
        }
        nlohmann::json out;
        out["scene"] = scenePath.substr(
            scenePath.rfind("/data/") != std::string::npos ? scenePath.rfind("/data/") + 1 : 0);
        out["start"] = startText;
        out["size"] = std::to_string(w) + "x" + std::to_string(h);
        out["fov_deg"] = fovDeg;
        out["fields"] = fields;
        out["repeat"] = repeat;
        out["objects_listed_per_field"] = static_cast<double>(listed) / fields;
        out["unoccluded_px_per_field"] = static_cast<double>(unoccluded) / fields;
        out["fast_ms"] = stats(fastMs);
        out["reference_ms"] = stats(referenceMs);
        out["mismatched_lines"] = mismatches;
        std::printf(
            "%llu fields of %dx%d, %.0f objects listed and %.0f unoccluded pixels a field\n",
            static_cast<unsigned long long>(fields), w, h,
            out["objects_listed_per_field"].get<double>(),
            out["unoccluded_px_per_field"].get<double>());
        std::printf("truth of one field, processor ms (mean +- sd, p50, max of %zu):\n",
                    fastMs.size());
        for (const char* k : {"fast_ms", "reference_ms"}) {
            const nlohmann::json& s = out[k];
            std::printf("  %-13s %6.2f +- %5.2f  p50 %6.2f  max %6.2f\n", k,
                        s["mean"].get<double>(), s["sd"].get<double>(), s["p50"].get<double>(),
                        s["max"].get<double>());
        }
        std::printf("lines differing from the reference: %llu\n",
                    static_cast<unsigned long long>(mismatches));
        if (!jsonPath.empty()) std::ofstream(jsonPath) << out.dump(2) << "\n";
        return mismatches == 0 ? 0 : 1;
    });
}
