// ig-render: renders one frame of a terrain with a chosen caster; writes colour, depth, stats.
#include "ig/caster.hpp"
#include "ig/cli.hpp"
#include "ig/error.hpp"
#include "io/image_file.hpp"

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <iostream>

namespace {

constexpr const char* kConventions = R"(Conventions:
  World: metres, x east, y north, z up. Terrain sample column i is at x = i * spacing, row j
  (row 0 = the file's top, the north edge) at y = (rows - 1 - j) * spacing.
  Pose x,y,z,yaw,pitch,roll: degrees; yaw = heading clockwise from north toward east, pitch
  nose-up positive, roll right-wing-down positive. z written +H is H metres above the terrain.
  Image: x right, y down, pixel centres at +0.5, principal point at the centre. --fov is the
  horizontal field of view of the WxH window; --margin PX adds PX pixels on every side at the
  same focal length (the written image is (W+2PX) x (H+2PX)).
  Depth (PFM): Euclidean distance from the eye in metres, +inf for sky.
  The fast caster renders roll = 0 (the post-rendering processor applies roll as a 2D rotation);
  the naive and reference casters honour any roll.
  A path of '-' writes to standard output.)";

}  // namespace

int main(int argc, char** argv) {
    CLI::App app{"Render one frame of a voxel terrain by ray casting."};
    app.footer(kConventions);
    ig::TerrainOptions terrain;
    ig::addTerrainOptions(app, terrain);
    std::string poseText = "52000,38000,+1200,55,-8,0";
    std::string sizeText = "720x486";
    double fovDeg = 60.0;
    int margin = 0;
    std::string casterText = "fast";
    std::string outPath = "frame.png";
    std::string depthPath, jsonPath;
    int threads = 0;
    double haze = 0.0;
    app.add_option("--pose", poseText, "x,y,z,yaw,pitch,roll (metres, degrees; z may be +H)")
        ->capture_default_str();
    app.add_option("--fov", fovDeg, "Horizontal field of view of the window, degrees")
        ->capture_default_str();
    app.add_option("--size", sizeText, "Window size WxH")->capture_default_str();
    app.add_option("--margin", margin, "Extra pixels rendered on every side")
        ->capture_default_str();
    app.add_option("--caster", casterText, "fast | naive | reference")->capture_default_str();
    app.add_option("--out", outPath, "Colour PNG")->capture_default_str();
    app.add_option("--depth", depthPath, "Depth PFM (metres from the eye, +inf for sky)");
    app.add_option("--json", jsonPath, "Stats and control points as JSON");
    app.add_option("--threads", threads, "Worker threads (0: all cores)")->capture_default_str();
    app.add_option("--haze", haze, "Distance haze: metres for 63% blend to the horizon (0: off)")
        ->capture_default_str();
    CLI11_PARSE(app, argc, argv);

    try {
        if (!(fovDeg > 0.0 && fovDeg < 179.0)) {
            throw ig::InputError("--fov: must be between 0 and 179 degrees");
        }
        if (margin < 0 || margin > 4096) throw ig::InputError("--margin: must be 0..4096 pixels");
        if (threads < 0) throw ig::InputError("--threads: must be 0 or more");
        if (!(haze >= 0.0) || !std::isfinite(haze)) throw ig::InputError("--haze: must be >= 0");
        const auto [w, h] = ig::parseSize(sizeText);
        const ig::CasterKind kind = ig::parseCasterKind(casterText);
        const ig::TerrainMap map = ig::loadTerrainFromOptions(terrain);
        const ig::Pose pose = ig::parsePose(poseText, map);
        if (kind == ig::CasterKind::Fast && pose.roll != 0.0) {
            throw ig::InputError(
                "--pose: the fast caster renders roll = 0 (roll is applied by the post-rendering "
                "processor); use --caster naive or reference for a truly rolled view");
        }
        const ig::Intrinsics intr = ig::Intrinsics::fromFov(w, h, ig::degToRad(fovDeg), margin);
        ig::RenderOptions options;
        options.threads = threads;
        options.sky.hazeDistance = haze;
        const auto caster = ig::makeCaster(kind, map, options);
        const ig::RenderedFrame frame = ig::renderFrame(*caster, map, pose, intr);

        std::string error;
        const auto* bytes = reinterpret_cast<const std::uint8_t*>(frame.color.data());
        if (io::writePng8(outPath, frame.width(), frame.height(), 3,
                          {bytes, frame.color.size() * 3}, &error) != 0) {
            throw ig::InputError("--out " + error);
        }
        if (!depthPath.empty() &&
            io::writePfm(depthPath, frame.width(), frame.height(), frame.depth, &error) != 0) {
            throw ig::InputError("--depth " + error);
        }
        const double pixels = static_cast<double>(frame.width()) * frame.height();
        nlohmann::json j;
        j["caster"] = casterText;
        j["width"] = frame.width();
        j["height"] = frame.height();
        j["margin"] = margin;
        j["focal_px"] = intr.focal;
        j["render_ms"] = frame.stats.renderMs;
        j["ns_per_pixel"] = frame.stats.renderMs * 1e6 / pixels;
        j["steps_per_pixel"] = static_cast<double>(frame.stats.steps) / pixels;
        j["coherence_restarts"] = frame.stats.restarts;
        j["pose"] = {{"x", pose.position.x},
                     {"y", pose.position.y},
                     {"z", pose.position.z},
                     {"yaw_deg", ig::radToDeg(pose.yaw)},
                     {"pitch_deg", ig::radToDeg(pose.pitch)},
                     {"roll_deg", ig::radToDeg(pose.roll)}};
        j["terrain"] = ig::describeTerrain(map);
        for (const ig::ControlPoint& cp : frame.controlPoints) {
            j["control_points"].push_back(
                {{"px", {cp.pixel.x, cp.pixel.y}},
                 {"world", {cp.world.x, cp.world.y, cp.world.z, cp.world.w}}});
        }
        if (!jsonPath.empty()) {
            if (jsonPath == "-") {
                std::cout << j.dump(2) << "\n";
            } else {
                std::ofstream out(jsonPath);
                out << j.dump(2) << "\n";
                if (!out) throw ig::InputError("--json " + jsonPath + ": cannot write the file");
            }
        }
        if (outPath != "-") {
            std::fprintf(stderr, "%s: %dx%d in %.1f ms (%.1f ns/pixel, %.2f steps/pixel) -> %s\n",
                         casterText.c_str(), frame.width(), frame.height(), frame.stats.renderMs,
                         frame.stats.renderMs * 1e6 / pixels,
                         static_cast<double>(frame.stats.steps) / pixels, outPath.c_str());
        }
    } catch (const ig::InputError& e) {
        std::fprintf(stderr, "ig-render: %s\n", e.what());
        return 2;
    } catch (const std::exception& e) {
        std::fprintf(stderr, "ig-render: error: %s\n", e.what());
        return 1;
    }
    return 0;
}
