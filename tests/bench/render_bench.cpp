// Renderer at full speed: naive vs single-level fast vs multiresolution fast on large synthetic
// maps, output sensitivity (4096^2 vs the 16384^2 map it is a crop of), thread scaling, vertical
// supersampling, huge pages, and the frame-to-frame difference along a slow flight.
//
//   bench-render [sections...] [--size N] [--image WxH] [--repeat N] [--no-hugepages]
//                [--cache DIR] [--caster K] [--levels auto|N] [--span-max-stretch S]
//                [--json FILE]
//   sections: speed packets sensitivity headings pitches threads supersample flight quality
//             frame stream span span-threads autosample lighting edge-fill insets detail
//             (default: speed)
//
// Timings are wall-clock, best of --repeat frames (in `speed` the three fast casters take their
// frames in turn); the machine's load affects them (state it). --json writes every section's
// figures, with each frame time taken (not only the best), for scripts/results.py.
#include "ig/appearance.hpp"
#include "ig/caster.hpp"
#include "ig/cli.hpp"
#include "ig/frame_stream.hpp"
#include "ig/image_compare.hpp"
#include "ig/inset.hpp"
#include "ig/lighting_pass.hpp"
#include "ig/shading.hpp"
#include "ig/stereo.hpp"
#include "ig/synthetic.hpp"
#include "ig/terrain_io.hpp"
#include "prp/processor.hpp"

#include <tbb/global_control.h>
#include <glm/geometric.hpp>
#include <nlohmann/json.hpp>

#include <sched.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <functional>
#include <map>
#include <memory>
#include <string>
#include <vector>

namespace {

using Clock = std::chrono::steady_clock;

struct Config {
    std::string cache;  // folder for raw copies of generated maps (fast to load under valgrind)
    std::string caster = "fast";
    int levels = 0;
    int size = 16384;
    int width = 1920, height = 1080;
    int repeat = 3;
    ig::CasterKernel kernel = ig::CasterKernel::Auto;
    std::vector<std::string> sections;
};

double secondsSince(Clock::time_point start) {
    return std::chrono::duration<double>(Clock::now() - start).count();
}

std::string gCache;
ig::CasterKernel gKernel = ig::CasterKernel::Auto;  // RenderOptions::kernel (--kernel)
double gHeadingDeg = 45.0;  // the issue camera's heading; --heading changes it (frame section)
double gPitchDeg = -10.0;   // its pitch; --pitch changes it (frame section)
double gSpanMaxStretch = ig::RenderOptions{}.spanMaxStretch;  // --span-max-stretch
nlohmann::json gJson = nlohmann::json::object();              // each section's figures, for --json

// Loads a raw copy of the map from the cache folder, if there is one.
bool loadCached(const std::string& path, ig::TerrainMap& map) {
    std::FILE* f = std::fopen(path.c_str(), "rb");
    if (!f) return false;
    const bool ok = std::fread(map.rawHeights().data(), sizeof(std::uint16_t),
                               map.rawHeights().size(), f) == map.rawHeights().size() &&
                    std::fread(map.colors().data(), sizeof(ig::Rgb8), map.colors().size(), f) ==
                        map.colors().size();
    std::fclose(f);
    if (ok) map.updateRange();
    return ok;
}

void saveCached(const std::string& path, const ig::TerrainMap& map) {
    std::FILE* f = std::fopen(path.c_str(), "wb");
    if (!f) {
        std::fprintf(stderr, "bench-render: --cache: cannot write %s\n", path.c_str());
        return;
    }
    std::fwrite(map.rawHeights().data(), sizeof(std::uint16_t), map.rawHeights().size(), f);
    std::fwrite(map.colors().data(), sizeof(ig::Rgb8), map.colors().size(), f);
    std::fclose(f);
}

const ig::TerrainMap& syntheticMap(int size) {
    static std::map<int, std::unique_ptr<ig::TerrainMap>> maps;
    auto& slot = maps[size];
    if (!slot) {
        const auto start = Clock::now();
        const std::string path =
            gCache.empty() ? "" : gCache + "/synthetic-" + std::to_string(size) + "-seed1-10m.raw";
        slot = std::make_unique<ig::TerrainMap>(size, size, 10.0, 10.0, ig::kSyntheticHeightScale,
                                                ig::kSyntheticHeightOffset);
        if (path.empty() || !loadCached(path, *slot)) {
            *slot = ig::makeSyntheticTerrain(size, 1, 10.0);
            if (!path.empty()) saveCached(path, *slot);
        }
        std::printf("# synthetic %d^2 map (seed 1, 10 m): ready in %.1f s\n", size,
                    secondsSince(start));
    }
    return *slot;
}

// The issue's camera: x = y = 20 km, 300 m above the ground, heading 45 deg, pitch -10 deg.
ig::Pose issuePose(const ig::TerrainMap& map, double pitchDeg = -10.0) {
    ig::Pose p;
    p.position = {20000.0, 20000.0, 0.0};
    p.position.z = map.surfaceHeight(p.position.x, p.position.y) + 300.0;
    p.yaw = ig::degToRad(gHeadingDeg);
    p.pitch = ig::degToRad(pitchDeg);
    return p;
}

struct Timed {
    double ms = 0.0;           // the best frame
    std::vector<double> runs;  // every frame's time, in the order taken
    ig::RenderedFrame frame;
};

// The best of `repeat` frames of each caster, taken in turn (one frame of each per round), so
// that a change in the core's speed during the run weighs on all of them alike.
std::vector<Timed> timeInTurn(const std::vector<const ig::Caster*>& casters,
                              const ig::TerrainMap& map, const ig::Pose& pose,
                              const ig::Intrinsics& in, int repeat) {
    std::vector<Timed> best(casters.size());
    for (Timed& b : best)
        b.ms = 1e300;
    for (int i = 0; i < repeat; ++i) {
        for (std::size_t k = 0; k < casters.size(); ++k) {
            ig::RenderedFrame f = ig::renderFrame(*casters[k], map, pose, in);
            best[k].runs.push_back(f.stats.renderMs);
            if (f.stats.renderMs < best[k].ms) {
                best[k].ms = f.stats.renderMs;
                best[k].frame = std::move(f);
            }
        }
    }
    return best;
}

// The best of `repeat` frames of one caster.
Timed timeFrames(const ig::Caster& caster, const ig::TerrainMap& map, const ig::Pose& pose,
                 const ig::Intrinsics& in, int repeat) {
    return timeInTurn({&caster}, map, pose, in, repeat)[0];
}

std::unique_ptr<ig::Caster> caster(ig::CasterKind kind, const ig::TerrainMap& map, int levels,
                                   int threads, int supersample = 1,
                                   ig::CasterKernel kernel = gKernel) {
    ig::RenderOptions o;
    o.levels = levels;
    o.threads = threads;
    o.supersample = supersample;
    o.kernel = kernel;
    o.spanMaxStretch = gSpanMaxStretch;
    const auto start = Clock::now();
    auto c = ig::makeCaster(kind, map, o);
    if (kind == ig::CasterKind::Fast && levels != 0) {
        std::printf("# pyramid built in %.2f s\n", secondsSince(start));
    }
    return c;
}

// One timed frame as JSON: the best time, every time, and the best frame's counts per pixel.
nlohmann::json timedJson(const std::string& name, const Timed& t, double pixels) {
    return {{"name", name},
            {"ms", t.ms},
            {"ms_runs", t.runs},
            {"ns_per_pixel", t.ms * 1e6 / pixels},
            {"steps_per_pixel", static_cast<double>(t.frame.stats.steps) / pixels},
            {"restarts_per_pixel", static_cast<double>(t.frame.stats.restarts) / pixels}};
}

// A section's common facts.
nlohmann::json sectionJson(const Config& c, int mapSize) {
    return {{"map", "synthetic " + std::to_string(mapSize)},
            {"image", std::to_string(c.width) + "x" + std::to_string(c.height)},
            {"repeat", c.repeat}};
}

void printRow(const char* name, const Timed& t, double pixels, double baselineMs = 0.0) {
    std::printf("| %-26s | %9.1f | %8.2f | %8.2f | %9.3f |", name, t.ms, t.ms * 1e6 / pixels,
                static_cast<double>(t.frame.stats.steps) / pixels,
                static_cast<double>(t.frame.stats.restarts) / pixels);
    if (baselineMs > 0.0) std::printf(" %8.2fx |", baselineMs / t.ms);
    std::printf("\n");
}

void header(bool speedup) {
    std::printf("| %-26s | %9s | %8s | %8s | %9s |%s\n", "caster", "frame ms", "ns/px", "steps/px",
                "restart/px", speedup ? "  speed-up |" : "");
    std::printf("|----------------------------|-----------|----------|----------|------------|%s\n",
                speedup ? "-----------|" : "");
}

void speed(const Config& c) {
    const ig::TerrainMap& map = syntheticMap(c.size);
    const ig::Intrinsics in = ig::Intrinsics::fromFov(c.width, c.height, ig::degToRad(60.0));
    const double pixels = static_cast<double>(c.width) * c.height;
    const ig::Pose pose = issuePose(map);
    std::printf("\n## speed: %dx%d, synthetic %d^2, issue camera, one thread\n", c.width, c.height,
                c.size);
    const auto naive = caster(ig::CasterKind::Naive, map, 0, 1);
    const auto single = caster(ig::CasterKind::Fast, map, 0, 1);
    const auto multi = caster(ig::CasterKind::Fast, map, ig::kLevelsAuto, 1);
    // Four lanes where the processor has them.
    const ig::CasterKernel four =
        ig::casterKernelMissing(ig::CasterKernel::Avx2).empty() ? ig::CasterKernel::Avx2 : gKernel;
    const auto multi4 = caster(ig::CasterKind::Fast, map, ig::kLevelsAuto, 1, 1, four);
    const Timed n = timeFrames(*naive, map, pose, in, 1);
    // The three fast casters' frames in turn.
    const std::vector<Timed> t =
        timeInTurn({single.get(), multi.get(), multi4.get()}, map, pose, in, c.repeat);
    const Timed &s = t[0], &m = t[1], &m4 = t[2];
    header(true);
    printRow("naive", n, pixels, n.ms);
    printRow("fast, --levels 0", s, pixels, n.ms);
    printRow("fast, --levels auto", m, pixels, n.ms);
    printRow("fast, --levels auto, 4 lanes", m4, pixels, n.ms);
    std::printf(
        "multires vs single-level: %.2fx (four lanes %.2fx); MAE single vs naive %.3f %%, "
        "multires vs single %.3f %%; images of the widest and four lanes %s\n",
        s.ms / m.ms, s.ms / m4.ms, ig::meanAbsErrorPct(s.frame.color, n.frame.color),
        ig::meanAbsErrorPct(m.frame.color, s.frame.color),
        m.frame.color == m4.frame.color && m.frame.depth == m4.frame.depth ? "identical"
                                                                           : "DIFFER");
    nlohmann::json j = sectionJson(c, c.size);
    j["rows"] = {timedJson("naive", n, pixels), timedJson("levels 0", s, pixels),
                 timedJson("levels auto", m, pixels),
                 timedJson("levels auto, 4 lanes", m4, pixels)};
    j["mae_pct_levels0_vs_naive"] = ig::meanAbsErrorPct(s.frame.color, n.frame.color);
    j["mae_pct_auto_vs_levels0"] = ig::meanAbsErrorPct(m.frame.color, s.frame.color);
    j["lanes_identical"] = m.frame.color == m4.frame.color && m.frame.depth == m4.frame.depth;
    gJson["speed"] = j;
}

// Vector lanes against none: each caster with its lanes (the single level four columns at a
// time, the multiresolution caster's rows in batches) and one column / one row at a time, the
// four frames taken in turn.
void packets(const Config& c) {
    const ig::TerrainMap& map = syntheticMap(c.size);
    const ig::Intrinsics in = ig::Intrinsics::fromFov(c.width, c.height, ig::degToRad(60.0));
    const double pixels = static_cast<double>(c.width) * c.height;
    std::printf(
        "\n## packets: %dx%d, synthetic %d^2, issue camera, one thread, best of %d in turn\n",
        c.width, c.height, c.size, c.repeat);
    auto make = [&](int levels, bool lanes) {
        ig::RenderOptions o;
        o.levels = levels;
        o.threads = 1;
        o.kernel = lanes ? gKernel : ig::CasterKernel::Scalar;
        return ig::makeCaster(ig::CasterKind::Fast, map, o);
    };
    const auto single = make(0, true), singleOne = make(0, false);
    const auto multi = make(ig::kLevelsAuto, true), multiOne = make(ig::kLevelsAuto, false);
    const std::vector<Timed> t =
        timeInTurn({single.get(), singleOne.get(), multi.get(), multiOne.get()}, map,
                   issuePose(map), in, c.repeat);
    const char* names[] = {"levels 0", "levels 0, one column at a time", "levels auto",
                           "levels auto, rows one by one"};
    header(false);
    nlohmann::json j = sectionJson(c, c.size), rows = nlohmann::json::array();
    for (std::size_t i = 0; i < t.size(); ++i) {
        printRow(names[i], t[i], pixels);
        rows.push_back(timedJson(names[i], t[i], pixels));
    }
    std::printf("lanes vs none: levels 0 %.2fx, levels auto %.2fx\n", t[1].ms / t[0].ms,
                t[3].ms / t[2].ms);
    j["rows"] = rows;
    gJson["packets"] = j;
}

// The issue camera moved through a set of views (`what` says how, `column` and `columns` name
// the table's first column): both casters' frames taken in turn at each, a table row each; the
// speed-ups' range.
void viewTable(const Config& c, const char* what, const char* column, const char* columns,
               const std::vector<double>& values,
               const std::function<ig::Pose(const ig::TerrainMap&, double)>& poseAt) {
    const ig::TerrainMap& map = syntheticMap(c.size);
    const ig::Intrinsics in = ig::Intrinsics::fromFov(c.width, c.height, ig::degToRad(60.0));
    const double pixels = static_cast<double>(c.width) * c.height;
    std::printf("\n## %s: %dx%d, synthetic %d^2, issue camera %s, one thread, best of %d in turn\n",
                columns, c.width, c.height, c.size, what, c.repeat);
    const auto single = caster(ig::CasterKind::Fast, map, 0, 1);
    const auto multi = caster(ig::CasterKind::Fast, map, ig::kLevelsAuto, 1);
    std::printf(
        "| %s | levels 0 ms | steps/px | levels auto ms | ns/px | steps/px | speed-up | "
        "MAE auto vs 0 |\n|---:|---:|---:|---:|---:|---:|---:|---:|\n",
        column);
    double worst = 1e300, best = 0.0;
    nlohmann::json j = sectionJson(c, c.size), rows = nlohmann::json::array();
    for (const double value : values) {
        const std::vector<Timed> t =
            timeInTurn({single.get(), multi.get()}, map, poseAt(map, value), in, c.repeat);
        const double ratio = t[0].ms / t[1].ms;
        worst = std::min(worst, ratio);
        best = std::max(best, ratio);
        std::printf("| %.0f | %.1f | %.2f | %.1f | %.2f | %.2f | %.2fx | %.3f %% |\n", value,
                    t[0].ms, static_cast<double>(t[0].frame.stats.steps) / pixels, t[1].ms,
                    t[1].ms * 1e6 / pixels, static_cast<double>(t[1].frame.stats.steps) / pixels,
                    ratio, ig::meanAbsErrorPct(t[1].frame.color, t[0].frame.color));
        rows.push_back(
            {{column, value},
             {"levels0", timedJson("levels 0", t[0], pixels)},
             {"auto", timedJson("levels auto", t[1], pixels)},
             {"mae_pct_auto_vs_levels0", ig::meanAbsErrorPct(t[1].frame.color, t[0].frame.color)}});
    }
    std::printf("multires vs single-level over the %s: %.2fx to %.2fx\n", columns, worst, best);
    j["rows"] = rows;
    gJson[columns] = j;
}

// The issue camera turned to the eight compass headings: how much the multiresolution caster
// gains depends on what the view holds (a heading up a long valley sees far more terrain, grazed
// by the rays near the horizon, than one toward a ridge).
void headings(const Config& c) {
    const double saved = gHeadingDeg;
    viewTable(c, "turned", "heading", "headings", {0, 45, 90, 135, 180, 225, 270, 315},
              [](const ig::TerrainMap& map, double deg) {
                  gHeadingDeg = deg;
                  return issuePose(map);
              });
    gHeadingDeg = saved;
}

// The issue camera tilted down further: the steeper the view, the fewer grid lines a ray
// crosses before its hit, until every batch of rows ends within a line or two and the frame
// costs what a pixel's set-up, hit, colour and store cost (the per-pixel floor).
void pitches(const Config& c) {
    viewTable(c, "tilted", "pitch", "pitches", {-5, -10, -20, -30, -45, -60},
              [](const ig::TerrainMap& map, double deg) { return issuePose(map, deg); });
}

// The frames of the four cases (two maps, two casters) are taken in turn, so that a change in
// the core's speed during the run weighs on all of them alike.
void sensitivity(const Config& c) {
    const ig::Intrinsics in = ig::Intrinsics::fromFov(c.width, c.height, ig::degToRad(60.0));
    const double pixels = static_cast<double>(c.width) * c.height;
    std::printf("\n## output sensitivity: %dx%d, issue camera, one thread, best of %d in turn\n",
                c.width, c.height, c.repeat);
    struct Case {
        int size, levels;
        const ig::TerrainMap* map;
        std::unique_ptr<ig::Caster> caster;
        Timed best;
    };
    std::vector<Case> cases;
    for (int size : {4096, c.size}) {
        const ig::TerrainMap& map = syntheticMap(size);
        for (int levels : {0, ig::kLevelsAuto})
            cases.push_back({size, levels, &map, caster(ig::CasterKind::Fast, map, levels, 1), {}});
    }
    for (int i = 0; i < c.repeat; ++i) {
        for (Case& k : cases) {
            const Timed t = timeFrames(*k.caster, *k.map, issuePose(*k.map), in, 1);
            k.best.runs.push_back(t.ms);
            if (i == 0 || t.ms < k.best.ms) {
                k.best.ms = t.ms;
                k.best.frame = t.frame;
            }
        }
    }
    header(false);
    std::map<std::pair<int, int>, double> ms;
    nlohmann::json j = sectionJson(c, c.size), rows = nlohmann::json::array();
    for (const Case& k : cases) {
        const std::string name = std::to_string(k.size) + "^2, levels " +
                                 (k.levels == 0 ? std::string("0") : std::string("auto"));
        printRow(name.c_str(), k.best, pixels);
        ms[{k.size, k.levels}] = k.best.ms;
        nlohmann::json row = timedJson(name, k.best, pixels);
        row["map_size"] = k.size;
        row["levels"] = k.levels == 0 ? "0" : "auto";
        rows.push_back(row);
    }
    std::printf("frame time %d^2 / 4096^2: levels 0 %.2fx, levels auto %.2fx\n", c.size,
                ms[{c.size, 0}] / ms[{4096, 0}],
                ms[{c.size, ig::kLevelsAuto}] / ms[{4096, ig::kLevelsAuto}]);
    j["rows"] = rows;
    gJson["sensitivity"] = j;
}

// The processors this process may run on (none when they cannot be read).
std::vector<int> allowedCpus() {
    cpu_set_t allowed;
    CPU_ZERO(&allowed);
    std::vector<int> cpus;
    if (sched_getaffinity(0, sizeof allowed, &allowed) != 0) return cpus;
    for (int cpu = 0; cpu < CPU_SETSIZE; ++cpu)
        if (CPU_ISSET(cpu, &allowed)) cpus.push_back(cpu);
    return cpus;
}

// Keeps the process's calling thread on the given processors (none: left as it is).
void runOn(const std::vector<int>& cpus) {
    if (cpus.empty()) return;
    cpu_set_t set;
    CPU_ZERO(&set);
    for (const int cpu : cpus)
        CPU_SET(cpu, &set);
    sched_setaffinity(0, sizeof set, &set);
}

void threads(const Config& c) {
    const ig::TerrainMap& map = syntheticMap(c.size);
    const ig::Intrinsics in = ig::Intrinsics::fromFov(c.width, c.height, ig::degToRad(60.0));
    const double pixels = static_cast<double>(c.width) * c.height;
    std::printf("\n## threads: %dx%d, synthetic %d^2, issue camera, levels auto\n", c.width,
                c.height, c.size);
    header(true);
    const auto single = caster(ig::CasterKind::Fast, map, ig::kLevelsAuto, 1);
    const auto pair = caster(ig::CasterKind::Fast, map, ig::kLevelsAuto, 2);
    // One thread on each of the first two processors the process may use, then two threads: on
    // a virtual machine the two cores need not be equally fast (a neighbour may share one), so
    // the two-thread frame is also compared with what the two cores can do together.
    const std::vector<int> all = allowedCpus();
    std::vector<double> oneMs;
    nlohmann::json j = sectionJson(c, c.size), rows = nlohmann::json::array();
    for (std::size_t i = 0; i < std::min<std::size_t>(all.size(), 2); ++i) {
        runOn({all[i]});
        const Timed t = timeFrames(*single, map, issuePose(map), in, c.repeat + 2);
        oneMs.push_back(t.ms);
        printRow(("1 thread, cpu " + std::to_string(all[i])).c_str(), t, pixels, t.ms);
        rows.push_back(timedJson("1 thread, cpu " + std::to_string(all[i]), t, pixels));
    }
    runOn(all);
    if (oneMs.empty()) {
        const Timed t = timeFrames(*single, map, issuePose(map), in, c.repeat + 2);
        oneMs.push_back(t.ms);
        printRow("1 thread", t, pixels, t.ms);
        rows.push_back(timedJson("1 thread", t, pixels));
    }
    const Timed t = timeFrames(*pair, map, issuePose(map), in, c.repeat + 2);
    const double fastest = *std::min_element(oneMs.begin(), oneMs.end());
    printRow("2 threads", t, pixels, fastest);
    rows.push_back(timedJson("2 threads", t, pixels));
    j["rows"] = rows;
    j["repeat"] = c.repeat + 2;
    gJson["threads"] = j;
    if (oneMs.size() == 2) {
        const double together = 1.0 / (1.0 / oneMs[0] + 1.0 / oneMs[1]);
        std::printf(
            "2 threads: %.2fx the faster core alone; %.0f %% of the two cores' capacity "
            "(%.1f ms if each rendered its share at its own one-thread speed)\n",
            fastest / t.ms, 100.0 * together / t.ms, together);
    }
}

std::vector<ig::Rgb8> supersampledReference(const ig::TerrainMap& map, const ig::Pose& pose, int w,
                                            int h, int f) {
    const auto ref = ig::makeCaster(ig::CasterKind::Reference, map);
    const ig::Intrinsics fine = ig::Intrinsics::fromFov(w * f, h * f, ig::degToRad(60.0));
    const ig::RenderedFrame big = ig::renderFrame(*ref, map, pose, fine);
    return ig::boxDownsample(big.color, w, h, f);
}

// Speed against error: each variant's time at the full size and its error against a 4x4
// supersampled reference at an eighth of the size (same field of view).
void quality(const Config& c, double pitchDeg, const char* title) {
    const int size = std::min(c.size, 4096);
    const ig::TerrainMap& map = syntheticMap(size);
    const ig::Pose pose = issuePose(map, pitchDeg);
    const int qw = c.width / 8, qh = c.height / 8;
    const ig::Intrinsics in = ig::Intrinsics::fromFov(c.width, c.height, ig::degToRad(60.0));
    const ig::Intrinsics small = ig::Intrinsics::fromFov(qw, qh, ig::degToRad(60.0));
    const double pixels = static_cast<double>(c.width) * c.height;
    std::printf(
        "\n## %s: synthetic %d^2, pitch %.0f deg, time at %dx%d (one thread), error at "
        "%dx%d vs 4x4 supersampled reference\n",
        title, size, pitchDeg, c.width, c.height, qw, qh);
    const auto ref = supersampledReference(map, pose, qw, qh, 4);
    std::printf("| %-22s | %9s | %8s | %8s | %8s |\n", "variant", "frame ms", "ns/px", "steps/px",
                "MAE %");
    std::printf("|------------------------|-----------|----------|----------|----------|\n");
    nlohmann::json j = sectionJson(c, size), rows = nlohmann::json::array();
    j["pitch_deg"] = pitchDeg;
    j["error_image"] = std::to_string(qw) + "x" + std::to_string(qh);
    for (int levels : {0, ig::kLevelsAuto}) {
        for (int ss : {1, 2, 4}) {
            const auto fast = caster(ig::CasterKind::Fast, map, levels, 1, ss);
            const Timed t = timeFrames(*fast, map, pose, in, c.repeat);
            const auto q = ig::renderFrame(*fast, map, pose, small);
            const std::string name = std::string("levels ") + (levels == 0 ? "0" : "auto") +
                                     ", supersample " + std::to_string(ss);
            std::printf("| %-22s | %9.1f | %8.2f | %8.2f | %8.3f |\n", name.c_str(), t.ms,
                        t.ms * 1e6 / pixels, static_cast<double>(t.frame.stats.steps) / pixels,
                        ig::meanAbsErrorPct(q.color, ref));
            nlohmann::json row = timedJson(name, t, pixels);
            row["levels"] = levels == 0 ? "0" : "auto";
            row["supersample"] = ss;
            row["mae_pct_vs_reference"] = ig::meanAbsErrorPct(q.color, ref);
            rows.push_back(row);
        }
    }
    j["rows"] = rows;
    gJson[title] = j;
}

// Lower detail (Intrinsics::detail, what a paged flight draws when writing a frame's tiles
// would pass its budget): levels auto, one ray per pixel, at each step the paging takes down to
// 0.5: time at --image (one thread, the details' frames in turn), error at 1/8 of it against
// the 4x4 supersampled reference, and how far level 0 reaches.
void detailSection(const Config& c) {
    const int size = std::min(c.size, 4096);
    const ig::TerrainMap& map = syntheticMap(size);
    const ig::Pose pose = issuePose(map, -10.0);
    const int qw = c.width / 8, qh = c.height / 8;
    const double pixels = static_cast<double>(c.width) * c.height;
    std::printf(
        "\n## detail: synthetic %d^2, pitch -10 deg, time at %dx%d (one thread), error at %dx%d "
        "vs 4x4 supersampled reference\n",
        size, c.width, c.height, qw, qh);
    const auto ref = supersampledReference(map, pose, qw, qh, 4);
    const auto fast = caster(ig::CasterKind::Fast, map, ig::kLevelsAuto, 1);
    const std::vector<double> details{1.0, std::exp2(-0.25), std::exp2(-0.5), std::exp2(-0.75),
                                      0.5};
    std::vector<ig::Intrinsics> ins;
    for (const double d : details) {
        ig::Intrinsics in = ig::Intrinsics::fromFov(c.width, c.height, ig::degToRad(60.0));
        in.detail = d;
        ins.push_back(in);
    }
    std::vector<Timed> best(details.size());
    for (int r = 0; r < c.repeat; ++r) {
        for (std::size_t i = 0; i < details.size(); ++i) {
            ig::RenderedFrame f = ig::renderFrame(*fast, map, pose, ins[i]);
            best[i].runs.push_back(f.stats.renderMs);
            if (r == 0 || f.stats.renderMs < best[i].ms) {
                best[i].ms = f.stats.renderMs;
                best[i].frame = std::move(f);
            }
        }
    }
    std::printf("| %-6s | %12s | %9s | %8s | %8s | %14s |\n", "detail", "level 0 to", "frame ms",
                "ns/px", "MAE %", "vs detail 1 %");
    nlohmann::json j = sectionJson(c, size), rows = nlohmann::json::array();
    j["pitch_deg"] = -10.0;
    j["error_image"] = std::to_string(qw) + "x" + std::to_string(qh);
    for (std::size_t i = 0; i < details.size(); ++i) {
        ig::Intrinsics small = ig::Intrinsics::fromFov(qw, qh, ig::degToRad(60.0));
        small.detail = details[i];
        const auto q = ig::renderFrame(*fast, map, pose, small);
        const double reachKm =
            2.0 * ins[i].lodFocal() * std::max(map.spacingX(), map.spacingY()) / 1000.0;
        const double mae = ig::meanAbsErrorPct(q.color, ref);
        const double vsFull = ig::meanAbsErrorPct(best[i].frame.color, best[0].frame.color);
        std::printf("| %6.3f | %9.1f km | %9.1f | %8.2f | %8.3f | %14.3f |\n", details[i], reachKm,
                    best[i].ms, best[i].ms * 1e6 / pixels, mae, vsFull);
        nlohmann::json row = timedJson("detail " + std::to_string(details[i]), best[i], pixels);
        row["detail"] = details[i];
        row["level0_reach_km"] = reachKm;
        row["mae_pct_vs_reference"] = mae;
        row["mae_pct_vs_detail_1"] = vsFull;
        rows.push_back(row);
    }
    j["rows"] = rows;
    gJson["detail"] = j;
}

// The best of --repeat frames of --caster at --levels, one thread: for profiles, and for
// instruction counts under callgrind (--repeat 1 --toggle-collect='ig::renderFrame*').
void frame(const Config& c) {
    const ig::TerrainMap& map = syntheticMap(c.size);
    const ig::Intrinsics in = ig::Intrinsics::fromFov(c.width, c.height, ig::degToRad(60.0));
    const auto r = caster(ig::parseCasterKind(c.caster), map, c.levels, 1);
    const ig::Pose pose = issuePose(map, gPitchDeg);
    ig::RenderedFrame f = ig::renderFrame(*r, map, pose, in);
    for (int i = 1; i < c.repeat; ++i) {
        ig::RenderedFrame g = ig::renderFrame(*r, map, pose, in);
        if (g.stats.renderMs < f.stats.renderMs) f = std::move(g);
    }
    const double pixels = static_cast<double>(c.width) * c.height;
    std::printf("frame: %s, levels %d, kernel %s, %dx%d, synthetic %d^2: %.1f ms, %.2f steps/px\n",
                c.caster.c_str(), c.levels, std::string(f.stats.kernel).c_str(), c.width, c.height,
                c.size, f.stats.renderMs, static_cast<double>(f.stats.steps) / pixels);
}

// Consecutive frames of a slow flight on two threads: one frame at a time (each frame's
// parallel_for waits for its slowest column before the next frame starts) against FrameStream
// (the next frame's columns start while the last ones finish).
void stream(const Config& c) {
    const ig::TerrainMap& map = syntheticMap(std::min(c.size, 4096));
    const ig::Intrinsics in = ig::Intrinsics::fromFov(c.width, c.height, ig::degToRad(60.0));
    const int frames = 8 * c.repeat;
    std::vector<ig::Pose> poses;
    for (int i = 0; i < frames; ++i) {
        ig::Pose pose = issuePose(map);
        pose.position.x += 20.0 * i;
        pose.position.y += 20.0 * i;
        poses.push_back(pose);
    }
    std::printf(
        "\n## frame stream: synthetic %d^2, %dx%d, issue camera moving 28 m per frame, %d "
        "frames, 2 threads\n",
        map.width(), c.width, c.height, frames);
    ig::RenderOptions o;
    o.threads = 2;
    o.kernel = gKernel;
    const auto fast = ig::makeCaster(ig::CasterKind::Fast, map, o);
    // Frames are compared by a hash of their colours (keeping them all would add page faults).
    auto hash = [](const ig::RenderedFrame& f) {
        std::uint64_t h = 1469598103934665603ull;
        for (const ig::Rgb8& p : f.color)
            h = (h ^ (p.r | p.g << 8 | p.b << 16)) * 1099511628211ull;
        return h;
    };
    std::vector<std::uint64_t> one, many;
    auto start = Clock::now();
    for (int i = 0; i < frames; ++i)
        one.push_back(hash(ig::renderFrame(*fast, map, poses[i], in)));
    const double sequential = secondsSince(start);
    start = Clock::now();
    {
        ig::FrameStream s(*fast, map, 2);
        s.submit(poses[0], in);
        for (int i = 0; i < frames; ++i) {
            s.help();
            if (i + 1 < frames) s.submit(poses[i + 1], in);
            many.push_back(hash(s.take()));
        }
    }
    const double overlapped = secondsSince(start);
    const bool same = one == many;
    std::printf("| mode | frames/s | ms/frame |\n|---|---:|---:|\n");
    std::printf("| one frame at a time | %.2f | %.1f |\n", frames / sequential,
                1e3 * sequential / frames);
    std::printf("| overlapped (FrameStream) | %.2f | %.1f |\n", frames / overlapped,
                1e3 * overlapped / frames);
    std::printf("overlap speed-up %.3fx; images %s\n", sequential / overlapped,
                same ? "identical" : "DIFFER");
    gJson["stream"] = {{"map", "synthetic " + std::to_string(map.width())},
                       {"image", std::to_string(c.width) + "x" + std::to_string(c.height)},
                       {"frames", frames},
                       {"threads", 2},
                       {"ms_per_frame_one_at_a_time", 1e3 * sequential / frames},
                       {"ms_per_frame_overlapped", 1e3 * overlapped / frames},
                       {"identical", same}};
}

void flight(const Config& c) {
    const ig::TerrainMap& map = syntheticMap(std::min(c.size, 4096));
    const int w = c.width / 2, h = c.height / 2;
    const ig::Intrinsics in = ig::Intrinsics::fromFov(w, h, ig::degToRad(60.0));
    std::printf(
        "\n## slow flight: synthetic %d^2, %dx%d, 300 m AGL at the start, heading 45 deg, "
        "pitch -5 deg, 5 m per frame; frame-to-frame MAE %%\n",
        map.width(), w, h);
    const auto single = caster(ig::CasterKind::Fast, map, 0, 0);
    const auto multi = caster(ig::CasterKind::Fast, map, ig::kLevelsAuto, 0);
    std::vector<ig::Rgb8> prevS, prevM;
    std::vector<double> diffS, diffM;
    std::printf("| frame | levels 0 | levels auto |\n|---|---|---|\n");
    const double z = map.surfaceHeight(20000.0, 20000.0) + 300.0;
    for (int i = 0; i <= 60; ++i) {
        ig::Pose pose = issuePose(map, -5.0);
        pose.position.x += 5.0 * i * 0.7071067811865476;
        pose.position.y += 5.0 * i * 0.7071067811865476;
        pose.position.z = z;
        const auto s = ig::renderFrame(*single, map, pose, in);
        const auto m = ig::renderFrame(*multi, map, pose, in);
        if (i > 0) {
            diffS.push_back(ig::meanAbsErrorPct(s.color, prevS));
            diffM.push_back(ig::meanAbsErrorPct(m.color, prevM));
            std::printf("| %d | %.3f | %.3f |\n", i, diffS.back(), diffM.back());
        }
        prevS = s.color;
        prevM = m.color;
    }
    gJson["flight"] = {{"map", "synthetic " + std::to_string(map.width())},
                       {"image", std::to_string(w) + "x" + std::to_string(h)},
                       {"frames", diffS.size()},
                       {"mae_pct_frame_to_frame_levels0", diffS},
                       {"mae_pct_frame_to_frame_auto", diffM}};
}

// ---- Span caster against a Comanche-style voxel-space renderer ------------------------------

// The peer baseline, after the published description of the Comanche voxel-space renderer:
// depth slices across the whole screen from front to back, the slice step growing by a tenth
// of a cell per slice, one y-buffer entry per column, the nearest map sample, pitch as a
// horizon shift, no depth. Returns the map samples it read.
std::uint64_t comanche(const ig::TerrainMap& map, const ig::Pose& pose, const ig::Intrinsics& in,
                       const ig::SkyModel& sky, std::vector<ig::Rgb8>& out,
                       std::vector<int>& ybuf) {
    const int W = in.width, H = in.height;
    const double f = in.focal, horizon = in.cy() + f * std::tan(pose.pitch);
    const double hx = std::sin(pose.yaw), hy = std::cos(pose.yaw);
    const double rx = std::cos(pose.yaw), ry = -std::sin(pose.yaw);
    const double tanHalf = 0.5 * W / f;
    const double sp = map.spacingX(), invSp = 1.0 / sp, invSpY = 1.0 / map.spacingY();
    const double ex = pose.position.x, ey = pose.position.y, ez = pose.position.z;
    const double zmax = std::hypot(map.extentX(), map.extentY()) + std::hypot(ex, ey);
    const double hs = map.heightScale(), ho = map.heightOffset();
    const int mw = map.width(), mh = map.height();
    const std::uint16_t* heights = map.rawHeights().data();
    const ig::Rgb8* colors = map.colors().data();
    out.resize(static_cast<std::size_t>(W) * H);
    ybuf.assign(W, H);
    std::uint64_t samples = 0;
    double dz = sp;
    for (double z = sp; z < zmax; z += dz, dz += 0.1 * sp) {
        const double px0 = ex + z * (hx - rx * tanHalf), py0 = ey + z * (hy - ry * tanHalf);
        const double stepX = 2.0 * tanHalf * z * rx / W, stepY = 2.0 * tanHalf * z * ry / W;
        const double invz = f / z;
        double px = px0 + 0.5 * stepX, py = py0 + 0.5 * stepY;
        for (int i = 0; i < W; ++i, px += stepX, py += stepY) {
            const int ix = static_cast<int>(px * invSp + 0.5),
                      iy = static_cast<int>(py * invSpY + 0.5);
            if (px < 0.0 || py < 0.0 || ix >= mw || iy >= mh) continue;
            ++samples;
            const std::size_t k = static_cast<std::size_t>(iy) * mw + ix;
            const double h = heights[k] * hs + ho;
            const int row = std::max(0, static_cast<int>(horizon + (ez - h) * invz));
            if (row < ybuf[i]) {
                const ig::Rgb8 c = colors[k];
                for (int r = row; r < ybuf[i]; ++r)
                    out[static_cast<std::size_t>(r) * W + i] = c;
                ybuf[i] = row;
            }
        }
    }
    const double spit = std::sin(pose.pitch), cpit = std::cos(pose.pitch);
    for (int r = 0; r < H; ++r) {
        const double yc = r + 0.5 - in.cy();
        const double uz = f * spit - yc * cpit, fw = f * cpit + yc * spit;
        const ig::Rgb8 c = ig::skyColor(sky, uz / std::sqrt(uz * uz + fw * fw));
        for (int i = 0; i < W; ++i)
            if (r < ybuf[i]) out[static_cast<std::size_t>(r) * W + i] = c;
    }
    return samples;
}

struct SpanView {
    std::string name;
    const ig::TerrainMap* map;
    ig::Pose pose;
};

// Puget Sound's flight view (bench-caster's): 300 m above the ground, heading north-east,
// 5 degrees down.
ig::Pose pugetFlightPose(const ig::TerrainMap& map) {
    ig::Pose p;
    p.position = {30000.0, 20000.0, 0.0};
    p.position.z = map.surfaceHeight(p.position.x, p.position.y) + 300.0;
    p.yaw = ig::degToRad(45.0);
    p.pitch = ig::degToRad(-5.0);
    return p;
}

// Per view: the span caster, the multiresolution fast caster and the Comanche-style renderer,
// timed in turn at the full size on one thread; their colour error at an eighth of the size
// against a 4x4 supersampled reference; then the span caster on two threads against one.
void spanSection(const Config& c) {
    const ig::TerrainMap& big = syntheticMap(c.size);
    static const ig::TerrainMap puget = ig::loadPugetSound();
    std::vector<SpanView> views;
    const std::string syn = "synthetic " + std::to_string(c.size) + "^2";
    views.push_back({"issue camera, " + syn, &big, issuePose(big)});
    views.push_back({"Puget Sound flight view", &puget, pugetFlightPose(puget)});
    for (double p : {0.0, -30.0, -60.0, -85.0})
        views.push_back(
            {"pitch " + std::to_string(static_cast<int>(p)) + ", " + syn, &big, issuePose(big, p)});
    const double savedHeading = gHeadingDeg;
    for (double h : {0.0, 90.0, 135.0, 180.0, 225.0, 270.0, 315.0}) {
        gHeadingDeg = h;
        views.push_back(
            {"heading " + std::to_string(static_cast<int>(h)) + ", " + syn, &big, issuePose(big)});
    }
    gHeadingDeg = savedHeading;

    const ig::Intrinsics in = ig::Intrinsics::fromFov(c.width, c.height, ig::degToRad(60.0));
    const int qw = c.width / 8, qh = c.height / 8;
    const ig::Intrinsics small = ig::Intrinsics::fromFov(qw, qh, ig::degToRad(60.0));
    const double pixels = static_cast<double>(c.width) * c.height;
    std::printf(
        "\n## span: %dx%d one thread, best of %d in turn; error at %dx%d vs 4x4 supersampled "
        "reference\n",
        c.width, c.height, c.repeat, qw, qh);
    std::printf(
        "| view | path | span ns/px | samples/px | comanche ns/px | samples/px | span / comanche "
        "| multires ns/px | MAE span %% | MAE multires %% | MAE comanche %% |\n"
        "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n");
    nlohmann::json rows = nlohmann::json::array();
    std::map<const ig::TerrainMap*,
             std::pair<std::unique_ptr<ig::Caster>, std::unique_ptr<ig::Caster>>>
        casters;
    for (const SpanView& v : views) {
        auto& cs = casters[v.map];
        if (!cs.first) {
            cs.first = caster(ig::CasterKind::Span, *v.map, ig::kLevelsAuto, 1);
            cs.second = caster(ig::CasterKind::Fast, *v.map, ig::kLevelsAuto, 1);
        }
        const ig::Caster& span = *cs.first;
        const ig::Caster& multi = *cs.second;
        const ig::SkyModel sky;
        std::vector<ig::Rgb8> comImage;
        std::vector<int> ybuf;
        Timed s, m, k;
        s.ms = m.ms = k.ms = 1e300;
        std::uint64_t comSamples = 0;
        for (int i = 0; i < c.repeat; ++i) {
            for (int which = 0; which < 3; ++which) {
                if (which == 2) {
                    const auto start = Clock::now();
                    comSamples = comanche(*v.map, v.pose, in, sky, comImage, ybuf);
                    const double ms = 1e3 * secondsSince(start);
                    k.runs.push_back(ms);
                    k.ms = std::min(k.ms, ms);
                    continue;
                }
                Timed& t = which == 0 ? s : m;
                ig::RenderedFrame f =
                    ig::renderFrame(which == 0 ? span : multi, *v.map, v.pose, in);
                t.runs.push_back(f.stats.renderMs);
                if (f.stats.renderMs < t.ms) {
                    t.ms = f.stats.renderMs;
                    t.frame = std::move(f);
                }
            }
        }
        const auto ref = supersampledReference(*v.map, v.pose, qw, qh, 4);
        const double maeSpan =
            ig::meanAbsErrorPct(ig::renderFrame(span, *v.map, v.pose, small).color, ref);
        const double maeMulti =
            ig::meanAbsErrorPct(ig::renderFrame(multi, *v.map, v.pose, small).color, ref);
        std::vector<ig::Rgb8> comSmall;
        comanche(*v.map, v.pose, small, sky, comSmall, ybuf);
        const double maeCom = ig::meanAbsErrorPct(comSmall, ref);
        const std::string path(s.frame.stats.path);
        std::printf("| %s | %s | %.2f | %.2f | %.2f | %.2f | %.2f | %.2f | %.3f | %.3f | %.3f |\n",
                    v.name.c_str(), path.c_str(), s.ms * 1e6 / pixels,
                    static_cast<double>(s.frame.stats.steps) / pixels, k.ms * 1e6 / pixels,
                    comSamples / pixels, s.ms / k.ms, m.ms * 1e6 / pixels, maeSpan, maeMulti,
                    maeCom);
        std::fflush(stdout);
        rows.push_back({{"view", v.name},
                        {"path", path},
                        {"span", timedJson("span", s, pixels)},
                        {"multires", timedJson("levels auto", m, pixels)},
                        {"comanche",
                         {{"ms", k.ms},
                          {"ms_runs", k.runs},
                          {"ns_per_pixel", k.ms * 1e6 / pixels},
                          {"samples_per_pixel", comSamples / pixels}}},
                        {"span_over_comanche", s.ms / k.ms},
                        {"mae_pct_span", maeSpan},
                        {"mae_pct_multires", maeMulti},
                        {"mae_pct_comanche", maeCom}});
    }
    nlohmann::json j = sectionJson(c, c.size);
    j["error_image"] = std::to_string(qw) + "x" + std::to_string(qh);
    j["rows"] = rows;
    gJson["span"] = j;
}

// The span caster on two threads against one on the issue camera, frames in turn.
void spanThreads(const Config& c) {
    const ig::TerrainMap& big = syntheticMap(c.size);
    const ig::Intrinsics in = ig::Intrinsics::fromFov(c.width, c.height, ig::degToRad(60.0));
    const double pixels = static_cast<double>(c.width) * c.height;
    // The library may have started while the process ran on one core: allow two workers.
    tbb::global_control allow(tbb::global_control::max_allowed_parallelism, 2);
    const auto one = caster(ig::CasterKind::Span, big, ig::kLevelsAuto, 1);
    const auto two = caster(ig::CasterKind::Span, big, ig::kLevelsAuto, 2);
    const std::vector<Timed> t =
        timeInTurn({one.get(), two.get()}, big, issuePose(big), in, c.repeat + 2);
    const bool same = t[0].frame.color == t[1].frame.color && t[0].frame.depth == t[1].frame.depth;
    std::printf(
        "\n## span threads: issue camera, %dx%d, synthetic %d^2: 1 thread %.2f ns/px, 2 threads "
        "%.2f ns/px (%.2fx); images %s\n",
        c.width, c.height, c.size, t[0].ms * 1e6 / pixels, t[1].ms * 1e6 / pixels,
        t[0].ms / t[1].ms, same ? "identical" : "DIFFER");
    nlohmann::json j = sectionJson(c, c.size);
    j["repeat"] = c.repeat + 2;
    j["one"] = timedJson("span, 1 thread", t[0], pixels);
    j["two"] = timedJson("span, 2 threads", t[1], pixels);
    j["identical"] = same;
    gJson["span_threads"] = j;
}

// The image of a w x h view rendered at 4w x 4h by `one` (one ray per pixel) and box filtered:
// 16 rays per pixel, the reference of the autosample section's flight.
std::vector<ig::Rgb8> sixteenRays(const ig::Caster& one, const ig::TerrainMap& map,
                                  const ig::Pose& pose, int w, int h) {
    const ig::RenderedFrame r =
        ig::renderFrame(one, map, pose, ig::Intrinsics::fromFov(4 * w, 4 * h, ig::degToRad(60.0)));
    return ig::boxDownsample(r.color, w, h, 4);
}

// Supersampling chosen from the pitch (auto) against fixed 1 and 4 rays per pixel over a pitch
// sweep: time at the full image (one thread, best of --repeat), error against a 4x4 supersampled
// reference at an eighth of the size, and the shimmer along a slow shallow flight (mean
// frame-to-frame change, and its excess over a 16-ray render's own change).
void autosample(const Config& c) {
    const int size = std::min(c.size, 4096);
    const ig::TerrainMap& map = syntheticMap(size);
    const ig::Intrinsics in = ig::Intrinsics::fromFov(c.width, c.height, ig::degToRad(60.0));
    const int qw = c.width / 8, qh = c.height / 8;
    const ig::Intrinsics small = ig::Intrinsics::fromFov(qw, qh, ig::degToRad(60.0));
    const double pixels = static_cast<double>(c.width) * c.height;
    struct Variant {
        const char* name;
        int rays;
    };
    const Variant variants[] = {{"1 ray", 1}, {"auto", ig::kSupersampleAuto}, {"4 rays", 4}};
    std::vector<std::unique_ptr<ig::Caster>> casters;
    for (const Variant& v : variants) {
        ig::RenderOptions o;
        o.levels = c.levels;
        o.threads = 1;
        o.kernel = gKernel;
        o.supersample = v.rays;
        casters.push_back(ig::makeCaster(ig::CasterKind::Fast, map, o));
    }
    std::printf(
        "\n## autosample: synthetic %d^2, levels %d, time at %dx%d (one thread, best of %d), "
        "error at %dx%d vs 4x4 supersampled reference\n",
        size, c.levels, c.width, c.height, c.repeat, qw, qh);
    std::printf("| pitch | variant | rays/px | frame ms | MAE %% |\n|---|---|---|---|---|\n");
    nlohmann::json j = sectionJson(c, size), rows = nlohmann::json::array();
    j["levels"] = c.levels;
    j["error_image"] = std::to_string(qw) + "x" + std::to_string(qh);
    std::vector<double> totalMs(3, 0.0), totalErr(3, 0.0);
    const double pitches[] = {0.0, -2.0, -5.0, -10.0, -20.0, -30.0, -45.0, -70.0};
    for (const double pitch : pitches) {
        const ig::Pose pose = issuePose(map, pitch);
        const auto ref = supersampledReference(map, pose, qw, qh, 4);
        for (std::size_t k = 0; k < casters.size(); ++k) {
            const Timed t = timeFrames(*casters[k], map, pose, in, c.repeat);
            const auto q = ig::renderFrame(*casters[k], map, pose, small);
            const double err = ig::meanAbsErrorPct(q.color, ref);
            const double rays = static_cast<double>(t.frame.stats.rays) / pixels;
            std::printf("| %.0f | %s | %.0f | %.1f | %.3f |\n", pitch, variants[k].name, rays, t.ms,
                        err);
            nlohmann::json row = timedJson(variants[k].name, t, pixels);
            row["pitch_deg"] = pitch;
            row["rays_per_pixel"] = rays;
            row["mae_pct_vs_reference"] = err;
            rows.push_back(row);
            totalMs[k] += t.ms;
            totalErr[k] += err / std::size(pitches);
        }
    }
    j["rows"] = rows;
    std::printf("| sweep | variant | | total ms | mean MAE %% |\n");
    nlohmann::json sums = nlohmann::json::array();
    for (std::size_t k = 0; k < casters.size(); ++k) {
        std::printf("| all | %s | | %.1f | %.3f |\n", variants[k].name, totalMs[k], totalErr[k]);
        sums.push_back({{"variant", variants[k].name},
                        {"sweep_ms", totalMs[k]},
                        {"mean_mae_pct_vs_reference", totalErr[k]}});
    }
    j["sweep"] = sums;

    // Shimmer: 5 m per frame at pitch -4 degrees, at a quarter of the size.
    const int fw = c.width / 4, fh = c.height / 4;
    const ig::Intrinsics fin = ig::Intrinsics::fromFov(fw, fh, ig::degToRad(60.0));
    ig::RenderOptions o1;
    o1.levels = c.levels;
    const auto one = ig::makeCaster(ig::CasterKind::Fast, map, o1);
    std::vector<std::vector<ig::Rgb8>> prev(casters.size() + 1);
    std::vector<double> change(casters.size() + 1, 0.0);
    const int frames = 30;
    const double z = map.surfaceHeight(20000.0, 20000.0) + 300.0;
    for (int i = 0; i <= frames; ++i) {
        ig::Pose pose = issuePose(map, -4.0);
        pose.position.x += 5.0 * i * 0.7071067811865476;
        pose.position.y += 5.0 * i * 0.7071067811865476;
        pose.position.z = z;
        for (std::size_t k = 0; k <= casters.size(); ++k) {
            std::vector<ig::Rgb8> img = k < casters.size()
                                            ? ig::renderFrame(*casters[k], map, pose, fin).color
                                            : sixteenRays(*one, map, pose, fw, fh);
            if (i > 0) change[k] += ig::meanAbsErrorPct(img, prev[k]) / frames;
            prev[k] = std::move(img);
        }
    }
    std::printf(
        "\nshimmer along a slow flight (%dx%d, pitch -4, 5 m/frame): mean frame-to-frame "
        "MAE %%: 1 ray %.3f, auto %.3f, 4 rays %.3f, 16-ray reference %.3f\n",
        fw, fh, change[0], change[1], change[2], change[3]);
    j["shimmer"] = {{"image", std::to_string(fw) + "x" + std::to_string(fh)},
                    {"frames", frames},
                    {"pitch_deg", -4.0},
                    {"frame_to_frame_mae_pct_1", change[0]},
                    {"frame_to_frame_mae_pct_auto", change[1]},
                    {"frame_to_frame_mae_pct_4", change[2]},
                    {"frame_to_frame_mae_pct_16", change[3]}};
    gJson["autosample"] = j;
}

}  // namespace

// The median of some numbers.
double median(std::vector<double> v) {
    std::sort(v.begin(), v.end());
    return v.empty() ? 0.0 : v[v.size() / 2];
}

// A render at w x h (60 degree view) of `map` with `options`, box-averaged from f x f rays.
std::vector<ig::Rgb8> supersampled(const ig::TerrainMap& map, const ig::RenderOptions& options,
                                   ig::CasterKind kind, const ig::Pose& pose, int w, int h, int f) {
    const auto caster = ig::makeCaster(kind, map, options);
    const ig::Intrinsics fine = ig::Intrinsics::fromFov(w * f, h * f, ig::degToRad(60.0));
    const ig::RenderedFrame big = ig::renderFrame(*caster, map, pose, fine);
    return f == 1 ? big.color : ig::boxDownsample(big.color, w, h, f);
}

// Deferred sun lighting (docs/design/appearance.md): the pass's cost per pixel at 720x486 and
// 1920x1080 on one thread, and its images against the baked relight (the map's colours lit,
// the pyramid averaging lit colours) and against a 4x4 supersampled reference caster render
// of the baked relight, over the synthetic map and the shipped one, with haze.
// Insets (docs/design/insets.md): a 2048^2 synthetic map at 8 m with a 2 km inset four times
// finer (2 m), against the same world as one map at 2 m (the whole fine terrain in memory, the
// truth) and the global map alone, at three views of the inset; fast caster, every level, one
// thread, frames of the three in turn.
void insetsSection(const Config& c) {
    const double spacing = 8.0;
    const int size = 2048, x0 = 896, cells = 256, f = 4;
    const auto start = Clock::now();
    std::vector<ig::InsetSource> sources;
    sources.push_back(ig::syntheticInset(1, spacing, x0, x0, cells, cells, f));
    const ig::NestedTerrain nested(ig::makeSyntheticTerrain(size, 1, spacing), std::move(sources));
    const ig::TerrainMap plain = ig::makeSyntheticTerrain(size, 1, spacing);
    const ig::Inset& in = nested.insets()[0];
    // The nested surface as one map at the inset's spacing.
    const ig::TerrainMap whole = nested.fineEquivalent();
    ig::RenderOptions o;
    o.levels = ig::kLevelsAuto;
    o.threads = 1;
    o.kernel = gKernel;
    const auto nestedCaster = ig::makeNestedCaster(ig::CasterKind::Fast, nested, o);
    const auto wholeCaster = ig::makeCaster(ig::CasterKind::Fast, whole, o);
    const auto plainCaster = ig::makeCaster(ig::CasterKind::Fast, plain, o);
    std::printf(
        "\n## insets: %dx%d, synthetic %d^2 at %g m, a %d-cell inset at %g m (ready in "
        "%.1f s), one thread\n",
        c.width, c.height, size, spacing, cells, spacing / f, secondsSince(start));
    const ig::Intrinsics intr = ig::Intrinsics::fromFov(c.width, c.height, ig::degToRad(60.0));
    const double pixels = static_cast<double>(c.width) * c.height;
    const glm::dvec2 centre = 0.5 * (in.coverMin + in.coverMax);
    const struct {
        const char* name;
        double back, up, pitch, yaw;
    } views[] = {{"approach, 3 km out", 3000.0, 300.0, -8.0, 30.0},
                 {"oblique, 1.2 km out", 1200.0, 600.0, -30.0, 120.0},
                 {"overhead", 300.0, 900.0, -70.0, 200.0}};
    nlohmann::json rows = nlohmann::json::array();
    std::printf("| %-22s | %9s | %9s | %9s | %7s | %12s | %12s | %12s |\n", "view", "global ns",
                "nested ns", "whole ns", "inset %", "MAE frame %", "MAE inset %", "global inset %");
    for (const auto& v : views) {
        ig::Pose pose;
        pose.yaw = ig::degToRad(v.yaw);
        pose.pitch = ig::degToRad(v.pitch);
        pose.position = {centre.x - v.back * std::sin(pose.yaw),
                         centre.y - v.back * std::cos(pose.yaw), 0.0};
        pose.position.z =
            nested.upperGround().surfaceHeight(pose.position.x, pose.position.y) + v.up;
        Timed tg, tn, tw;
        tg.ms = tn.ms = tw.ms = 1e300;
        for (int r = 0; r < c.repeat; ++r) {
            auto keep = [](Timed& t, ig::RenderedFrame frame) {
                t.runs.push_back(frame.stats.renderMs);
                if (frame.stats.renderMs < t.ms) {
                    t.ms = frame.stats.renderMs;
                    t.frame = std::move(frame);
                }
            };
            keep(tg, ig::renderFrame(*plainCaster, plain, pose, intr));
            keep(tn, ig::renderNestedFrame(*nestedCaster, nested, pose, intr));
            keep(tw, ig::renderFrame(*wholeCaster, whole, pose, intr));
        }
        // The pixels whose true hit lies over the inset.
        const ig::Camera cam(pose, intr);
        std::vector<ig::Rgb8> a, b, g;
        for (int y = 0; y < intr.height; ++y) {
            for (int x = 0; x < intr.width; ++x) {
                const std::size_t i = static_cast<std::size_t>(y) * intr.width + x;
                if (!std::isfinite(tw.frame.depth[i])) continue;
                const glm::dvec3 q =
                    pose.position +
                    double(tw.frame.depth[i]) * glm::normalize(cam.rayDirection(x + 0.5, y + 0.5));
                if (!in.covers(q.x, q.y)) continue;
                a.push_back(tn.frame.color[i]);
                b.push_back(tw.frame.color[i]);
                g.push_back(tg.frame.color[i]);
            }
        }
        const double share = a.size() / pixels;
        const double maeFrame = ig::meanAbsErrorPct(tn.frame.color, tw.frame.color);
        const double maeInset = a.empty() ? 0.0 : ig::meanAbsErrorPct(a, b);
        const double maeGlobal = a.empty() ? 0.0 : ig::meanAbsErrorPct(g, b);
        std::printf("| %-22s | %9.1f | %9.1f | %9.1f | %7.1f | %12.4f | %12.4f | %12.3f |\n",
                    v.name, tg.ms * 1e6 / pixels, tn.ms * 1e6 / pixels, tw.ms * 1e6 / pixels,
                    100.0 * share, maeFrame, maeInset, maeGlobal);
        rows.push_back({{"view", v.name},
                        {"global", timedJson("global alone", tg, pixels)},
                        {"nested", timedJson("nested", tn, pixels)},
                        {"whole", timedJson("whole fine map", tw, pixels)},
                        {"inset_pixel_share", share},
                        {"mae_pct_frame_vs_whole", maeFrame},
                        {"mae_pct_inset_vs_whole", maeInset},
                        {"mae_pct_global_inset_vs_whole", maeGlobal}});
    }
    nlohmann::json j = sectionJson(c, size);
    j["spacing_m"] = spacing;
    j["inset"] = {{"cells", cells}, {"factor", f}, {"spacing_m", spacing / f}};
    j["rows"] = rows;
    gJson["insets"] = j;
}

void lighting(const Config& c) {
    struct Scene {
        std::string name;
        ig::TerrainMap map;
        ig::Pose pose;
    };
    std::vector<Scene> scenes;
    {
        const ig::TerrainMap& synth = syntheticMap(std::min(c.size, 4096));
        scenes.push_back({"synthetic " + std::to_string(synth.width()), synth, issuePose(synth)});
        ig::TerrainMap puget = ig::loadPugetSound();
        const ig::Pose pose = ig::defaultViewPose(puget);
        scenes.push_back({"Puget Sound", std::move(puget), pose});
    }
    const ig::Sun sun{ig::degToRad(135.0), ig::degToRad(30.0)};
    nlohmann::json j = sectionJson(c, std::min(c.size, 4096)), costs = nlohmann::json::array(),
                   errors = nlohmann::json::array();
    j["sun_deg"] = {135.0, 30.0};
    std::printf(
        "\n## lighting: deferred sun lighting, one thread, sun 135/30 deg, haze a quarter "
        "of the map\n");
    std::printf("| %-14s | %9s | %13s | %12s | %12s | %7s |\n", "map", "image", "frame CPU ms",
                "pass CPU ms", "pass ns/px", "pass/frame");
    for (Scene& sc : scenes) {
        ig::TerrainMap albedo = sc.map;
        albedo.colors() = ig::elevationRampAlbedo(sc.map);
        ig::TerrainMap baked = sc.map;
        ig::TerrainLighting(sc.map, ig::TerrainLighting::Albedo::Ramp).relight(baked, sun);
        auto lit = std::make_shared<ig::SunLighting>();
        lit->normals = std::make_shared<const ig::TerrainNormals>(albedo);
        lit->clock.sun = sun;
        auto levelZero = std::make_shared<ig::SunLighting>(*lit);
        levelZero->levelZeroNormals = true;
        auto options = [&](int levels, std::shared_ptr<const ig::SunLighting> l) {
            ig::RenderOptions o;
            o.levels = levels;
            o.threads = 1;
            o.kernel = gKernel;
            o.sky.hazeDistance = 0.25 * std::max(sc.map.extentX(), sc.map.extentY());
            o.lighting = std::move(l);
            return o;
        };
        // Cost: the frame (unlit) and the pass over it, in turn, by the thread's CPU time (one
        // thread: the casters and the pass run on the calling thread), immune to other
        // processes' load; wall time beside it.
        for (const auto& [w, h] : {std::pair{720, 486}, std::pair{1920, 1080}}) {
            const ig::Intrinsics in = ig::Intrinsics::fromFov(w, h, ig::degToRad(60.0));
            const ig::RenderOptions o = options(ig::kLevelsAuto, nullptr);
            const auto fast = ig::makeCaster(ig::CasterKind::Fast, albedo, o);
            const ig::Camera camera(sc.pose, in);
            const ig::LevelBands bands{in.focal * std::max(albedo.spacingX(), albedo.spacingY()),
                                       lit->normals->levelCount() - 1};
            const double pixels = static_cast<double>(w) * h;
            std::vector<double> frameCpu, passCpu, passWall, passNs, ratio;
            for (int r = 0; r < 3 * c.repeat; ++r) {
                double cpu = ig::threadCpuMs();
                ig::RenderedFrame frame = ig::renderFrame(*fast, albedo, sc.pose, in);
                frameCpu.push_back(ig::threadCpuMs() - cpu);
                cpu = ig::threadCpuMs();
                const auto start = Clock::now();
                ig::lightFrame(*lit, o.sky, bands, camera, frame, 1);
                passWall.push_back(secondsSince(start) * 1e3);
                passCpu.push_back(ig::threadCpuMs() - cpu);
                passNs.push_back(passCpu.back() * 1e6 / pixels);
                ratio.push_back(passCpu.back() / frameCpu.back());
            }
            std::printf("| %-14s | %4dx%-4d | %13.1f | %12.2f | %12.2f | %7.3f |\n",
                        sc.name.c_str(), w, h, median(frameCpu), median(passCpu), median(passNs),
                        median(ratio));
            costs.push_back({{"map", sc.name},
                             {"image", std::to_string(w) + "x" + std::to_string(h)},
                             {"frame_cpu_ms_runs", frameCpu},
                             {"pass_cpu_ms_runs", passCpu},
                             {"pass_wall_ms_runs", passWall},
                             {"pass_ns_per_pixel_runs", passNs},
                             {"pass_over_frame_runs", ratio}});
        }
        // Error at 180x120 against the baked relight and a 4x4 supersampled reference of it.
        const int qw = 180, qh = 120;
        for (const double pitch : {-4.0, -10.0, -30.0}) {
            ig::Pose pose = sc.pose;
            pose.pitch = ig::degToRad(pitch);
            const auto ref = supersampled(baked, options(0, nullptr), ig::CasterKind::Reference,
                                          pose, qw, qh, 4);
            nlohmann::json row = {{"map", sc.name}, {"pitch_deg", pitch}};
            std::printf("%s, pitch %.0f: vs baked (same caster) / vs 4x4 baked reference, MAE %%:",
                        sc.name.c_str(), pitch);
            for (const int levels : {0, ig::kLevelsAuto}) {
                const std::string key = levels == 0 ? "levels0" : "multires";
                const auto bakedImage = supersampled(baked, options(levels, nullptr),
                                                     ig::CasterKind::Fast, pose, qw, qh, 1);
                const auto deferred = supersampled(albedo, options(levels, lit),
                                                   ig::CasterKind::Fast, pose, qw, qh, 1);
                const auto zero = supersampled(albedo, options(levels, levelZero),
                                               ig::CasterKind::Fast, pose, qw, qh, 1);
                row[key] = {
                    {"deferred_vs_baked_mae_pct", ig::meanAbsErrorPct(deferred, bakedImage)},
                    {"deferred_vs_baked_psnr_db", ig::psnrDb(deferred, bakedImage)},
                    {"level0_normals_vs_baked_mae_pct", ig::meanAbsErrorPct(zero, bakedImage)},
                    {"deferred_vs_reference_mae_pct", ig::meanAbsErrorPct(deferred, ref)},
                    {"level0_normals_vs_reference_mae_pct", ig::meanAbsErrorPct(zero, ref)},
                    {"baked_vs_reference_mae_pct", ig::meanAbsErrorPct(bakedImage, ref)}};
                std::printf(
                    " %s: deferred %.3f / %.3f, level-0 normals %.3f / %.3f, baked - / %.3f;",
                    key.c_str(), ig::meanAbsErrorPct(deferred, bakedImage),
                    ig::meanAbsErrorPct(deferred, ref), ig::meanAbsErrorPct(zero, bakedImage),
                    ig::meanAbsErrorPct(zero, ref), ig::meanAbsErrorPct(bakedImage, ref));
            }
            std::printf("\n");
            errors.push_back(row);
        }
    }
    j["cost"] = costs;
    j["error"] = errors;
    j["error_image"] = "180x120";
    gJson["lighting"] = j;
}

// Out-of-frame fill in the PRP: a frame rendered with the pipeline's margin (48 px), warped to
// a pose turned by 1 to 2 margins (with roll in one case), against a true render at that pose:
// the field's error with the edge pixels repeated, with the sky above the horizon and the edge
// below (sky), and with the sky above and the haze colour below (sky-haze).
void edgeFill(const Config& c) {
    ig::TerrainMap map = ig::loadPugetSound();
    ig::RenderOptions o;
    o.levels = ig::kLevelsAuto;
    o.kernel = gKernel;
    o.sky.hazeDistance = 0.25 * std::max(map.extentX(), map.extentY());
    const auto fast = ig::makeCaster(ig::CasterKind::Fast, map, o);
    const auto rolled = ig::makeCaster(ig::CasterKind::Naive, map, o);
    const int w = 720, h = 486, margin = 48;
    const ig::Intrinsics framed = ig::Intrinsics::fromFov(w, h, ig::degToRad(60.0), margin);
    const ig::Intrinsics window = framed.window();
    nlohmann::json j = {{"map", "Puget Sound"},
                        {"image", "720x486"},
                        {"margin", margin},
                        {"haze_m", o.sky.hazeDistance}},
                   rows = nlohmann::json::array();
    std::printf(
        "\n## edge-fill: Puget Sound, %dx%d, margin %d, haze %.0f m; field MAE %% vs a "
        "true render over the pixels taken from beyond the frame (and the whole field)\n",
        w, h, margin, o.sky.hazeDistance);
    std::printf("| pitch | roll | turn px | outside %% | repeat | sky | sky-haze |\n");
    struct Case {
        double pitch, roll;
    };
    for (const Case cs : {Case{-3.0, 0.0}, Case{-10.0, 0.0}, Case{0.0, 15.0}}) {
        ig::Pose base = ig::defaultViewPose(map);
        base.pitch = ig::degToRad(cs.pitch);
        const ig::RenderedFrame frame = ig::renderFrame(*fast, map, base, framed);
        for (const double k : {1.0, 1.5, 2.0}) {
            const double shiftPx = k * margin;
            ig::Pose pose = base;
            // The view turns right by shiftPx at the image centre (the margin's limit at k = 1).
            pose.yaw += std::atan(shiftPx / framed.focal);
            pose.roll = ig::degToRad(cs.roll);
            const ig::RenderedFrame truth =
                ig::renderFrame(cs.roll != 0.0 ? *rolled : *fast, map, pose, window);
            // Every mode warps the same fields; the pixels where a fill differs from the
            // repeated edge are the ones taken from beyond the frame (where the fill equals the
            // edge, both errors are the same anyway).
            const prp::EdgeFill modes[] = {prp::EdgeFill::Repeat, prp::EdgeFill::Sky,
                                           prp::EdgeFill::SkyHaze};
            std::vector<prp::PostRenderingProcessor> prps;
            for (const prp::EdgeFill m : modes) {
                prp::PrpOptions po;
                po.outWidth = w;
                po.outHeight = h;
                po.format = prp::PixelFormat::Rgb8;
                po.sky = o.sky;
                po.edgeFill = m;
                prps.emplace_back(po);
            }
            double sumOut[3] = {0, 0, 0}, sumAll[3] = {0, 0, 0};
            std::uint64_t nOut = 0, nAll = 0, outside = 0;
            for (int parity = 0; parity < 2; ++parity) {
                prp::Field fields[3];
                for (int m = 0; m < 3; ++m)
                    prps[m].process(frame, pose, 0.0, static_cast<std::uint64_t>(parity),
                                    fields[m]);
                outside += fields[0].edgeSamples;
                for (int line = 0; line < fields[0].lines; ++line) {
                    const ig::Rgb8* t = truth.color.data() +
                                        static_cast<std::size_t>(fields[0].frameLine(line)) * w;
                    for (int x = 0; x < w; ++x) {
                        double e[3];
                        for (int m = 0; m < 3; ++m) {
                            const std::uint8_t* p = fields[m].line(line) + 3 * x;
                            e[m] = (std::abs(p[0] - t[x].r) + std::abs(p[1] - t[x].g) +
                                    std::abs(p[2] - t[x].b)) /
                                   (3.0 * 255.0);
                        }
                        const std::uint8_t* p0 = fields[0].line(line) + 3 * x;
                        bool beyond = false;
                        for (int m = 1; m < 3; ++m) {
                            const std::uint8_t* p = fields[m].line(line) + 3 * x;
                            beyond |= p[0] != p0[0] || p[1] != p0[1] || p[2] != p0[2];
                        }
                        ++nAll;
                        nOut += beyond;
                        for (int m = 0; m < 3; ++m) {
                            sumAll[m] += e[m];
                            if (beyond) sumOut[m] += e[m];
                        }
                    }
                }
            }
            const double outsidePct = 100.0 * outside / (static_cast<double>(w) * h);
            nlohmann::json row = {{"pitch_deg", cs.pitch},
                                  {"roll_deg", cs.roll},
                                  {"turn_px", shiftPx},
                                  {"outside_pct", outsidePct}};
            std::printf("| %5.0f | %4.0f | %7.0f | %9.2f |", cs.pitch, cs.roll, shiftPx,
                        outsidePct);
            for (int m = 0; m < 3; ++m) {
                const double out = nOut ? 100.0 * sumOut[m] / nOut : 0.0;
                const double all = 100.0 * sumAll[m] / nAll;
                const std::string name(prp::edgeFillName(modes[m]));
                row[name + "_beyond_mae_pct"] = out;
                row[name + "_mae_pct"] = all;
                std::printf(" %5.2f (%5.3f) |", out, all);
            }
            std::printf("\n");
            rows.push_back(row);
        }
    }
    j["rows"] = rows;
    gJson["edge-fill"] = j;
    (void)c;
}

int main(int argc, char** argv) {
    Config c;
    std::string jsonPath;
    for (int i = 1; i < argc; ++i) {
        const std::string a = argv[i];
        auto next = [&]() -> std::string {
            if (i + 1 >= argc) {
                std::fprintf(stderr, "bench-render: %s needs a value\n", a.c_str());
                std::exit(2);
            }
            return argv[++i];
        };
        if (a == "--size") {
            c.size = std::atoi(next().c_str());
        } else if (a == "--image") {
            const std::string v = next();
            if (std::sscanf(v.c_str(), "%dx%d", &c.width, &c.height) != 2 || c.width < 8 ||
                c.height < 8) {
                std::fprintf(stderr, "bench-render: --image %s: expected WxH\n", v.c_str());
                return 2;
            }
        } else if (a == "--repeat") {
            c.repeat = std::max(1, std::atoi(next().c_str()));
        } else if (a == "--cache") {
            c.cache = next();
        } else if (a == "--json") {
            jsonPath = next();
        } else if (a == "--caster") {
            c.caster = next();
        } else if (a == "--levels") {
            try {
                c.levels = ig::parseLevels(next());
            } catch (const std::exception& e) {
                std::fprintf(stderr, "bench-render: %s\n", e.what());
                return 2;
            }
        } else if (a == "--heading") {
            gHeadingDeg = std::atof(next().c_str());
        } else if (a == "--pitch") {
            gPitchDeg = std::atof(next().c_str());
            if (!(gPitchDeg >= -90.0 && gPitchDeg <= 90.0)) {
                std::fprintf(stderr, "bench-render: --pitch: expected degrees in [-90, 90]\n");
                return 2;
            }
        } else if (a == "--span-max-stretch") {
            gSpanMaxStretch = std::atof(next().c_str());
            if (!(gSpanMaxStretch >= 1.0 && gSpanMaxStretch <= 16.0)) {
                std::fprintf(stderr, "bench-render: --span-max-stretch: expected 1..16\n");
                return 2;
            }
        } else if (a == "--kernel") {
            try {
                c.kernel = ig::parseCasterKernel(next());
            } catch (const std::exception& e) {
                std::fprintf(stderr, "bench-render: %s\n", e.what());
                return 2;
            }
        } else if (a == "--no-hugepages") {
            ig::setHugePageAdvice(false);
        } else if (a == "speed" || a == "sensitivity" || a == "threads" || a == "supersample" ||
                   a == "flight" || a == "quality" || a == "frame" || a == "stream" ||
                   a == "headings" || a == "pitches" || a == "packets" || a == "span" ||
                   a == "span-threads" || a == "autosample" || a == "lighting" ||
                   a == "edge-fill" || a == "insets" || a == "detail") {
            c.sections.push_back(a);
        } else {
            std::fprintf(
                stderr,
                "bench-render: unknown argument '%s'\nusage: bench-render [speed] [packets] "
                "[sensitivity] [threads] [supersample] [quality] [flight] [frame] "
                "[stream] [headings] [pitches] [span] [span-threads] [autosample] [lighting] "
                "[edge-fill] [insets] [detail] [--size N] "
                "[--image WxH] [--repeat N] [--no-hugepages] [--kernel auto|scalar|avx2|avx512] "
                "[--heading "
                "DEG] [--pitch DEG] [--span-max-stretch S] [--cache DIR] "
                "[--caster fast|span|naive|reference] [--levels auto|N] [--json FILE]\n",
                a.c_str());
            return 2;
        }
    }
    if (c.sections.empty()) c.sections.push_back("speed");
    gCache = c.cache;
    gKernel = c.kernel;
    try {
        // One-thread sections run on one core, so the casters they compare share it (a VM's
        // cores need not be equally fast); threads and stream use every core allowed.
        const std::vector<int> all = allowedCpus();
        for (const std::string& s : c.sections) {
            const bool parallel = s == "threads" || s == "stream" || s == "span-threads";
            if (!all.empty()) runOn(parallel ? all : std::vector<int>{all.front()});
            if (s == "speed") speed(c);
            if (s == "packets") packets(c);
            if (s == "sensitivity") sensitivity(c);
            if (s == "headings") headings(c);
            if (s == "pitches") pitches(c);
            if (s == "threads") threads(c);
            if (s == "quality") quality(c, -10.0, "quality");
            if (s == "supersample") quality(c, -1.0, "supersample");
            if (s == "flight") flight(c);
            if (s == "stream") stream(c);
            if (s == "frame") frame(c);
            if (s == "span") spanSection(c);
            if (s == "span-threads") spanThreads(c);
            if (s == "autosample") autosample(c);
            if (s == "lighting") lighting(c);
            if (s == "edge-fill") edgeFill(c);
            if (s == "insets") insetsSection(c);
            if (s == "detail") detailSection(c);
        }
    } catch (const std::exception& e) {
        std::fprintf(stderr, "bench-render: %s\n", e.what());
        return 1;
    }
    if (!jsonPath.empty()) {
        std::ofstream out(jsonPath);
        out << gJson.dump(1) << "\n";
        if (!out) {
            std::fprintf(stderr, "bench-render: --json %s: cannot write\n", jsonPath.c_str());
            return 1;
        }
    }
    return 0;
}
