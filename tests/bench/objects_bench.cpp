// Voxel objects: what a populated world costs the fast caster, what the objects cost in memory.
//
//   bench-objects [--scene FILE] [--repeat N] [--image WxH] [--error-image WxH] [--json FILE]
//
// Frame time: the fast caster (levels auto, the default, and levels 0) on one thread at --image
// (default 1920x1080) over Puget Sound at the demo view, with the scene's objects and without,
// frames taken in turn (--repeat pairs); the ratio per pair. The object pass alone on the same
// terrain, and its alternative, every pixel's ray through the object grid (traceObjects per
// pixel), at --error-image (default 480x270; the alternative is too slow for the full size).
// Error at --error-image: the fast caster's objects against the reference caster's (ids that
// differ, colour error over the object pixels). Memory: the layer with the shared stick table
// and with every copy's own lists. Times are wall-clock on whatever else the machine runs.
#include "ig/caster.hpp"
#include "ig/image_compare.hpp"
#include "ig/object_pass.hpp"
#include "ig/object_trace.hpp"
#include "ig/scene.hpp"
#include "ig/terrain_io.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <string>
#include <vector>

namespace {

using Clock = std::chrono::steady_clock;

double ms(Clock::time_point a, Clock::time_point b) {
    return std::chrono::duration<double, std::milli>(b - a).count();
}

double median(std::vector<double> v) {
    std::sort(v.begin(), v.end());
    const std::size_t n = v.size();
    return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

std::string range(const std::vector<double>& v, int digits) {
    const auto [lo, hi] = std::minmax_element(v.begin(), v.end());
    char buf[96];
    std::snprintf(buf, sizeof buf, "%.*f (%.*f-%.*f, %zu runs)", digits, median(v), digits, *lo,
                  digits, *hi, v.size());
    return buf;
}

}  // namespace

int main(int argc, char** argv) {
    std::string scenePath = std::string(VIG_DATA_DIR) + "/scenes/puget-sound-busy.json";
    std::string jsonPath;
    int repeat = 3, w = 1920, h = 1080, ew = 480, eh = 270;
    for (int i = 1; i < argc; ++i) {
        if (!std::strcmp(argv[i], "--scene") && i + 1 < argc) {
            scenePath = argv[++i];
        } else if (!std::strcmp(argv[i], "--repeat") && i + 1 < argc) {
            repeat = std::max(1, std::atoi(argv[++i]));
        } else if (!std::strcmp(argv[i], "--image") && i + 1 < argc) {
            if (std::sscanf(argv[++i], "%dx%d", &w, &h) != 2 || w < 1 || h < 1) return 2;
        } else if (!std::strcmp(argv[i], "--error-image") && i + 1 < argc) {
            if (std::sscanf(argv[++i], "%dx%d", &ew, &eh) != 2 || ew < 1 || eh < 1) return 2;
        } else if (!std::strcmp(argv[i], "--json") && i + 1 < argc) {
            jsonPath = argv[++i];
        } else {
            std::fprintf(stderr,
                         "usage: bench-objects [--scene FILE] [--repeat N] [--image WxH] "
                         "[--error-image WxH] [--json FILE]\n");
            return 2;
        }
    }
    nlohmann::json out;
    out["scene"] = scenePath.substr(
        scenePath.rfind("/data/") != std::string::npos ? scenePath.rfind("/data/") + 1 : 0);
    out["image"] = std::to_string(w) + "x" + std::to_string(h);
    out["error_image"] = std::to_string(ew) + "x" + std::to_string(eh);
    const ig::TerrainMap map = ig::loadPugetSound();

    // Memory, with and without the shared stick table.
    for (const bool share : {true, false}) {
        std::vector<double> loads;
        nlohmann::json m;
        for (int r = 0; r < repeat; ++r) {
            const auto t0 = Clock::now();
            const ig::Scene scene = ig::loadScene(scenePath, map, share);
            loads.push_back(ms(t0, Clock::now()));
            const ig::ObjectLayer& l = *scene.staticLayer;
            const double objects = static_cast<double>(l.objects().size());
            m = {{"objects", l.objects().size()},
                 {"cell_entries", l.cellEntries()},
                 {"stick_lists", l.table().lists()},
                 {"table_bytes", l.table().bytes()},
                 {"cell_bytes", l.cellBytes()},
                 {"box_bytes", l.boxBytes()},
                 {"layer_bytes", l.bytes()},
                 {"bytes_per_object",
                  static_cast<double>(l.table().bytes() + l.cellBytes() + l.boxBytes()) / objects}};
        }
        m["load_ms"] = loads;
        std::printf(
            "%s sticks: %d objects, %d stick lists, table %d B, cells %d B, boxes %d B: "
            "%.0f B per object; load %s ms\n",
            share ? "shared" : "own", m["objects"].get<int>(), m["stick_lists"].get<int>(),
            m["table_bytes"].get<int>(), m["cell_bytes"].get<int>(), m["box_bytes"].get<int>(),
            m["bytes_per_object"].get<double>(), range(loads, 0).c_str());
        out[share ? "memory_shared" : "memory_own"] = m;
    }

    const ig::Scene scene = ig::loadScene(scenePath, map);
    const std::vector<const ig::ObjectLayer*> layers = {scene.staticLayer.get()};
    ig::Pose pose;
    pose.position = {52450.0, 38150.0, map.surfaceHeight(52450.0, 38150.0) + 25.0};
    pose.yaw = ig::degToRad(20.0);
    pose.pitch = ig::degToRad(-4.0);
    out["pose"] = "52450,38150,+25,20,-4,0";

    // Frame time with and without the objects, frames in turn.
    const ig::Intrinsics intr = ig::Intrinsics::fromFov(w, h, ig::degToRad(60.0));
    for (const int levels : {ig::kLevelsAuto, 0}) {
        ig::RenderOptions plain;
        plain.threads = 1;
        plain.levels = levels;
        ig::RenderOptions with = plain;
        with.objects = layers;
        const auto casterPlain = ig::makeCaster(ig::CasterKind::Fast, map, plain);
        const auto casterWith = ig::makeCaster(ig::CasterKind::Fast, map, with);
        std::vector<double> without, withObjects, ratio;
        std::uint64_t objectPixels = 0;
        for (int r = 0; r < repeat; ++r) {
            const ig::RenderedFrame a = ig::renderFrame(*casterPlain, map, pose, intr);
            const ig::RenderedFrame b = ig::renderFrame(*casterWith, map, pose, intr);
            without.push_back(a.stats.renderMs);
            withObjects.push_back(b.stats.renderMs);
            ratio.push_back(b.stats.renderMs / a.stats.renderMs);
            objectPixels = static_cast<std::uint64_t>(
                b.objectId.size() - static_cast<std::size_t>(std::count(
                                        b.objectId.begin(), b.objectId.end(), std::uint16_t{0})));
        }
        const std::string name = levels == 0 ? "levels 0" : "levels auto";
        std::printf(
            "fast %s %dx%d, 1 thread: %s ms without objects, %s ms with; ratio %s; %.1f %% "
            "of pixels objects\n",
            name.c_str(), w, h, range(without, 1).c_str(), range(withObjects, 1).c_str(),
            range(ratio, 2).c_str(), 100.0 * objectPixels / (static_cast<double>(w) * h));
        out["frames"].push_back({{"caster", "fast " + name},
                                 {"kernel", std::string(casterWith->kernelName())},
                                 {"without_ms", without},
                                 {"with_ms", withObjects},
                                 {"object_pixel_fraction", static_cast<double>(objectPixels) /
                                                               (static_cast<double>(w) * h)}});
    }

    // Near boxes splatted (the pass's choice) against every box walked, at the frame's size, on
    // one terrain image, in turn.
    {
        ig::RenderOptions plain;
        plain.threads = 1;
        const auto caster = ig::makeCaster(ig::CasterKind::Fast, map, plain);
        const ig::RenderedFrame terrain = ig::renderFrame(*caster, map, pose, intr);
        const ig::Camera camera(pose, intr);
        std::vector<double> splat, walk, ratio;
        bool same = true;
        ig::ObjectPassStats stats;
        for (int r = 0; r < repeat; ++r) {
            ig::RenderedFrame a = terrain, b = terrain;
            a.objectId.assign(a.color.size(), 0);
            b.objectId.assign(b.color.size(), 0);
            auto t0 = Clock::now();
            ig::drawObjects(
                layers, plain.sky, camera, a, 0, w, false,
                ig::ObjectPassOptions{ig::ObjectPassOptions{}.splatPixelsPerColumn, &stats});
            splat.push_back(ms(t0, Clock::now()));
            t0 = Clock::now();
            ig::drawObjects(layers, plain.sky, camera, b, 0, w, false,
                            ig::ObjectPassOptions{INFINITY, nullptr});
            walk.push_back(ms(t0, Clock::now()));
            ratio.push_back(walk.back() / splat.back());
            same = same && a.objectId == b.objectId && a.depth == b.depth && a.color == b.color;
        }
        std::printf(
            "%dx%d, 1 thread: object pass %s ms with %zu of %zu boxes splatted (%zu columns), "
            "%s ms with every box walked (%s x); images %s\n",
            w, h, range(splat, 1).c_str(), stats.splatted, stats.boxes, stats.columns,
            range(walk, 1).c_str(), range(ratio, 2).c_str(), same ? "identical" : "DIFFER");
        out["splat_vs_walk"] = {{"splat_ms", splat},          {"walk_ms", walk},
                                {"identical", same},          {"boxes", stats.boxes},
                                {"splatted", stats.splatted}, {"columns", stats.columns}};
    }

    // The pass alone against every pixel's ray through the object grid, on one terrain image.
    {
        const ig::Intrinsics in = ig::Intrinsics::fromFov(ew, eh, ig::degToRad(60.0));
        ig::RenderOptions plain;
        plain.threads = 1;
        const auto caster = ig::makeCaster(ig::CasterKind::Fast, map, plain);
        const ig::RenderedFrame terrain = ig::renderFrame(*caster, map, pose, in);
        const ig::Camera camera(pose, in);
        std::vector<double> pass, perPixel;
        bool same = true;
        for (int r = 0; r < repeat; ++r) {
            ig::RenderedFrame a = terrain, b = terrain;
            a.objectId.assign(a.color.size(), 0);
            b.objectId.assign(b.color.size(), 0);
            auto t0 = Clock::now();
            ig::drawObjects(layers, plain.sky, camera, a, 0, ew, false);
            pass.push_back(ms(t0, Clock::now()));
            t0 = Clock::now();
            ig::drawObjectsPerPixel(layers, plain.sky, camera, b, 0, ew);
            perPixel.push_back(ms(t0, Clock::now()));
            same = same && a.objectId == b.objectId && a.color == b.color && a.depth == b.depth;
        }
        std::vector<double> ratio;
        for (int r = 0; r < repeat; ++r)
            ratio.push_back(perPixel[static_cast<std::size_t>(r)] /
                            pass[static_cast<std::size_t>(r)]);
        std::printf(
            "%dx%d, 1 thread: object pass %s ms; every pixel through the object grid %s "
            "ms (%s x); images %s\n",
            ew, eh, range(pass, 1).c_str(), range(perPixel, 1).c_str(), range(ratio, 1).c_str(),
            same ? "identical" : "DIFFER");
        out["pass_vs_per_pixel"] = {
            {"pass_ms", pass}, {"per_pixel_ms", perPixel}, {"identical", same}};
    }

    // The fast casters' objects against the reference caster's.
    {
        const ig::Intrinsics in = ig::Intrinsics::fromFov(ew, eh, ig::degToRad(60.0));
        ig::RenderOptions ro;
        ro.objects = layers;
        const auto reference = ig::makeCaster(ig::CasterKind::Reference, map, ro);
        const ig::RenderedFrame ref = ig::renderFrame(*reference, map, pose, in);
        for (const int levels : {ig::kLevelsAuto, 0}) {
            ig::RenderOptions o = ro;
            o.levels = levels;
            const auto fast = ig::makeCaster(ig::CasterKind::Fast, map, o);
            const ig::RenderedFrame got = ig::renderFrame(*fast, map, pose, in);
            std::uint64_t refPixels = 0, differ = 0, n = 0;
            double err = 0.0;
            for (std::size_t i = 0; i < ref.objectId.size(); ++i) {
                refPixels += ref.objectId[i] != 0;
                differ += got.objectId[i] != ref.objectId[i];
                if (ref.objectId[i] == 0 && got.objectId[i] == 0) continue;
                const ig::Rgb8 p = got.color[i], q = ref.color[i];
                err += std::abs(p.r - q.r) + std::abs(p.g - q.g) + std::abs(p.b - q.b);
                ++n;
            }
            const double mae = n ? 100.0 * err / (3.0 * 255.0 * static_cast<double>(n)) : 0.0;
            const std::string name = levels == 0 ? "levels 0" : "levels auto";
            std::printf(
                "fast %s vs reference, %dx%d: %llu object pixels, ids differ on %llu "
                "(%.3f %%), colour error over object pixels %.3f %%\n",
                name.c_str(), ew, eh, static_cast<unsigned long long>(refPixels),
                static_cast<unsigned long long>(differ),
                refPixels ? 100.0 * differ / static_cast<double>(refPixels) : 0.0, mae);
            out["error"].push_back({{"caster", "fast " + name},
                                    {"object_pixels", refPixels},
                                    {"ids_differ", differ},
                                    {"mae_pct", mae}});
        }
    }
    if (!jsonPath.empty()) {
        std::ofstream f(jsonPath);
        f << out.dump(1) << "\n";
        if (!f) {
            std::fprintf(stderr, "bench-objects: cannot write %s\n", jsonPath.c_str());
            return 2;
        }
    }
    return 0;
}
