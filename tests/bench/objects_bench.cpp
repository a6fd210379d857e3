// Voxel objects: memory of the demo scene's object layer with and without shared sticks, the
// time to load it, and the reference caster's frame with and without the objects.
//
//   bench-objects [--scene FILE] [--repeat N] [--image WxH]
//
// Timings are wall-clock: the mean and standard deviation of --repeat runs (state the load).
#include "ig/caster.hpp"
#include "ig/scene.hpp"
#include "ig/terrain_io.hpp"
#include "sim/scene_motion.hpp"

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

namespace {

using Clock = std::chrono::steady_clock;

double ms(Clock::time_point a, Clock::time_point b) {
    return std::chrono::duration<double, std::milli>(b - a).count();
}

struct Stat {
    double mean = 0, sd = 0;
};
Stat stat(const std::vector<double>& v) {
    Stat s;
    for (double x : v)
        s.mean += x;
    s.mean /= static_cast<double>(v.size());
    for (double x : v)
        s.sd += (x - s.mean) * (x - s.mean);
    s.sd = v.size() > 1 ? std::sqrt(s.sd / static_cast<double>(v.size() - 1)) : 0.0;
    return s;
}

}  // namespace

int main(int argc, char** argv) {
    std::string scenePath = std::string(VIG_DATA_DIR) + "/scenes/puget-sound.json";
    int repeat = 3, w = 360, h = 243;
    for (int i = 1; i < argc; ++i) {
        if (!std::strcmp(argv[i], "--scene") && i + 1 < argc)
            scenePath = argv[++i];
        else if (!std::strcmp(argv[i], "--repeat") && i + 1 < argc)
            repeat = std::atoi(argv[++i]);
        else if (!std::strcmp(argv[i], "--image") && i + 1 < argc) {
            if (std::sscanf(argv[++i], "%dx%d", &w, &h) != 2) return 2;
        } else {
            std::fprintf(stderr,
                         "usage: bench-objects [--scene FILE] [--repeat N] [--image WxH]\n");
            return 2;
        }
    }
    if (repeat < 1) repeat = 1;
    const ig::TerrainMap map = ig::loadPugetSound();
    for (const bool share : {true, false}) {
        std::vector<double> loads;
        std::size_t table = 0, cells = 0, total = 0, objects = 0, entries = 0, lists = 0;
        for (int r = 0; r < repeat; ++r) {
            const auto t0 = Clock::now();
            const ig::Scene scene = ig::loadScene(scenePath, map, share);
            loads.push_back(ms(t0, Clock::now()));
            const ig::ObjectLayer& l = *scene.staticLayer;
            table = l.table().bytes();
            cells = l.cellBytes();
            total = l.bytes();
            objects = l.objects().size();
            entries = l.cellEntries();
            lists = l.table().lists();
        }
        const Stat s = stat(loads);
        std::printf(
            "%s sticks: %zu objects, %zu cell entries (%.1f per object), %zu stick lists; "
            "table %zu B, cells %zu B, per-terrain-cell ranges %zu B; "
            "(table + cells) / object = %.0f B; load %.0f +- %.0f ms\n",
            share ? "shared" : "unshared", objects, entries,
            static_cast<double>(entries) / static_cast<double>(objects), lists, table, cells,
            total - table - cells,
            static_cast<double>(table + cells) / static_cast<double>(objects), s.mean, s.sd);
    }
    // The reference caster at the demo view, without and with the objects.
    const ig::Scene scene = ig::loadScene(scenePath, map);
    const sim::SceneMotion motion(scene);
    const ig::ObjectLayer moving = motion.stamp(10.0);
    ig::Pose pose;
    pose.position = {52450.0, 38150.0, map.surfaceHeight(52450.0, 38150.0) + 25.0};
    pose.yaw = ig::degToRad(20.0);
    pose.pitch = ig::degToRad(-4.0);
    const ig::Intrinsics intr = ig::Intrinsics::fromFov(w, h, ig::degToRad(60.0));
    for (const bool withObjects : {false, true}) {
        ig::RenderOptions options;
        if (withObjects) options.objects = {scene.staticLayer.get(), &moving};
        const auto caster = ig::makeCaster(ig::CasterKind::Reference, map, options);
        std::vector<double> t;
        for (int r = 0; r < repeat; ++r) {
            const auto t0 = Clock::now();
            const ig::RenderedFrame f = ig::renderFrame(*caster, map, pose, intr);
            t.push_back(ms(t0, Clock::now()));
        }
        const Stat s = stat(t);
        std::printf("reference caster %dx%d %s objects: %.0f +- %.0f ms\n", w, h,
                    withObjects ? "with" : "without", s.mean, s.sd);
    }
    return 0;
}
