// ig-render: renders one frame of a terrain with a chosen caster; writes colour, depth, stats.
#include "base/text.hpp"
#include "ig/caster.hpp"
#include "ig/cli.hpp"
#include "ig/error.hpp"
#include "ig/object_trace.hpp"
#include "ig/scene.hpp"
#include "ig/stereo.hpp"
#include "io/image_file.hpp"
#include "io/output_file.hpp"
#include "io/stop_signals.hpp"
#include "sim/scene_motion.hpp"

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <limits>
#include <optional>
#include <string>
#include <vector>

namespace {

// A pose as JSON, angles in degrees.
nlohmann::json poseJson(const ig::Pose& pose) {
    return {{"x", pose.position.x},
            {"y", pose.position.y},
            {"z", pose.position.z},
            {"yaw_deg", ig::radToDeg(pose.yaw)},
            {"pitch_deg", ig::radToDeg(pose.pitch)},
            {"roll_deg", ig::radToDeg(pose.roll)}};
}

constexpr const char* kConventions = R"(Conventions:
  World: metres, x east, y north, z up. Terrain sample column i is at x = i * spacing, row j
  (row 0 = the file's top, the north edge) at y = (rows - 1 - j) * spacing.
  Pose x,y,z,yaw,pitch,roll: degrees; yaw = heading clockwise from north toward east, pitch
  nose-up positive, roll right-wing-down positive. z written +H is H metres above the terrain.
  Image: x right, y down, pixel centres at +0.5, principal point at the centre. --fov is the
  horizontal field of view of the WxH window; --margin PX adds PX pixels on every side at the
  same focal length (the written image is (W+2PX) x (H+2PX)).
  Depth (PFM): Euclidean distance from the eye in metres, +inf for sky.
  Objects (--scene, reference and naive casters): --objects-out writes each pixel's object id
  as a 16-bit grey PNG (0: terrain or sky); --json lists each visible object's pixel count and
  box [x0, y0, x1, y1] (inclusive). Moving objects are placed at --time (default: the earliest
  trajectory start).
  The fast caster renders roll = 0 (the post-rendering processor applies roll as a 2D rotation);
  the naive and reference casters honour any roll.
  A path of '-' writes to standard output.)";

// ---- Stereo (--stereo): left eye by the fast caster, right eye reprojected or cast. ----------

struct StereoFlags {
    std::optional<double> separation;
    std::string right = "reproject";
    std::string variant = "wan";
    bool noAbuffer = false;
    double gapThreshold = 2.0;
    std::string outLeft, outRight, outSbs, outAnaglyph, outMask;

    bool enabled() const { return separation.has_value(); }
};

void addStereoFlags(CLI::App& app, StereoFlags& s) {
    app.add_option("--stereo", s.separation,
                   "Render a stereo pair with this eye separation, metres (right eye along the "
                   "camera's right); needs --out-left and --out-right");
    app.add_option("--right", s.right, "Right eye: reproject (from the left) | raycast")
        ->capture_default_str();
    app.add_option("--stereo-variant", s.variant,
                   "Reprojection: wan (right to left, A-buffer) | adelson-hodges (left-to-right "
                   "overwrite, integer placement)")
        ->capture_default_str();
    app.add_flag("--no-abuffer", s.noAbuffer, "Integer placement instead of the 1x8 A-buffer");
    app.add_option("--gap-threshold", s.gapThreshold,
                   "Gaps up to this many pixels are interpolated, wider ones ray cast")
        ->capture_default_str();
    app.add_option("--out-left", s.outLeft, "Stereo: left eye PNG");
    app.add_option("--out-right", s.outRight, "Stereo: right eye PNG");
    app.add_option("--out-sbs", s.outSbs, "Stereo: side-by-side PNG (left | right)");
    app.add_option("--out-anaglyph", s.outAnaglyph, "Stereo: red-cyan anaglyph PNG");
    app.add_option("--out-raycast-mask", s.outMask,
                   "Stereo: the right eye in grey with its ray-cast pixels in red");
}

void writeRgb(const std::string& path, const std::string& flag, int w, int h,
              const std::vector<ig::Rgb8>& pixels) {
    if (path.empty()) return;
    std::string error;
    const auto* bytes = reinterpret_cast<const std::uint8_t*>(pixels.data());
    if (io::writePng8(path, w, h, 3, {bytes, pixels.size() * 3}, &error) != 0) {
        throw ig::InputError(flag + " " + error);
    }
}

// Renders and writes the stereo outputs; fills the stereo fields of `j`.
void runStereo(const StereoFlags& s, const ig::TerrainMap& map, const ig::Pose& pose,
               const ig::Intrinsics& intr, const ig::RenderOptions& options,
               const std::string& depthPath, nlohmann::json& j) {
    if (s.outLeft.empty() || s.outRight.empty()) {
        throw ig::InputError("--stereo: give --out-left and --out-right");
    }
    ig::StereoOptions so;
    if (!(std::isfinite(*s.separation) && *s.separation > 0.0 && *s.separation <= 1e4)) {
        throw ig::InputError("--stereo " + base::number(*s.separation) +
                             ": the eye separation must be more than 0 and at most 10000 metres");
    }
    so.eyeSeparation = *s.separation;
    so.method = ig::parseRightEyeMethod(s.right);
    if (s.variant == "adelson-hodges") {
        so.variant = ig::ReprojectVariant::AdelsonHodges;
    } else if (s.variant != "wan") {
        throw ig::InputError("--stereo-variant '" + s.variant +
                             "': expected wan or adelson-hodges");
    }
    so.abuffer = !s.noAbuffer;
    so.gapThreshold = s.gapThreshold;
    const ig::StereoFrame f = ig::renderStereo(map, pose, intr, so, options);
    const int w = f.left.width(), h = f.left.height();
    writeRgb(s.outLeft, "--out-left", w, h, f.left.color);
    writeRgb(s.outRight, "--out-right", w, h, f.right.color);
    if (!s.outSbs.empty())
        writeRgb(s.outSbs, "--out-sbs", 2 * w, h, ig::sideBySide(f.left, f.right));
    if (!s.outAnaglyph.empty()) {
        writeRgb(s.outAnaglyph, "--out-anaglyph", w, h, ig::anaglyph(f.left, f.right));
    }
    if (!s.outMask.empty()) {
        writeRgb(s.outMask, "--out-raycast-mask", w, h, ig::rayCastMask(f.right, f.source));
    }
    std::string error;
    if (!depthPath.empty() && io::writePfm(depthPath, w, h, f.left.depth, &error) != 0) {
        throw ig::InputError("--depth " + error);
    }
    const double pixels = static_cast<double>(w) * h;
    j["stereo"] = {{"eye_separation_m", *s.separation},
                   {"right", s.right},
                   {"reproject", s.variant},
                   {"abuffer", !s.noAbuffer},
                   {"gap_threshold_px", s.gapThreshold}};
    j["left_ms"] = f.stats.leftMs;
    j["right_ms"] = f.stats.rightMs;
    j["kernel"] = std::string(f.left.stats.kernel);
    j["right_over_left"] = f.stats.leftMs > 0.0 ? f.stats.rightMs / f.stats.leftMs : 0.0;
    j["reproject_ms"] = f.stats.reprojectMs;
    j["cast_ms"] = f.stats.castMs;
    j["reprojected_fraction"] = f.stats.reprojected / pixels;
    j["interpolated_fraction"] = f.stats.interpolated / pixels;
    j["ray_cast_fraction"] = f.stats.rayCast / pixels;
    j["sky_without_cast"] = f.stats.skyWithoutCast;
    std::fprintf(stderr,
                 "stereo %dx%d, e = %g m: left %.1f ms, right (%s) %.1f ms = %.1f%% of left; "
                 "right pixels %.2f%% reprojected, %.2f%% interpolated, %.2f%% ray cast\n",
                 w, h, *s.separation, f.stats.leftMs, s.right.c_str(), f.stats.rightMs,
                 100.0 * j["right_over_left"].get<double>(), 100.0 * f.stats.reprojected / pixels,
                 100.0 * f.stats.interpolated / pixels, 100.0 * f.stats.rayCast / pixels);
}

// The --stereo path of main: the pair, its images and its JSON.
int renderStereoPair(const StereoFlags& s, ig::CasterKind kind, const ig::TerrainMap& map,
                     const ig::Pose& pose, const ig::Intrinsics& intr,
                     const ig::RenderOptions& options, const std::string& depthPath,
                     const std::string& jsonPath) {
    if (kind != ig::CasterKind::Fast) {
        throw ig::InputError("--stereo: the pair is rendered by the fast caster; drop --caster");
    }
    nlohmann::json j;
    j["caster"] = "fast";
    j["width"] = intr.width;
    j["height"] = intr.height;
    j["margin"] = intr.margin;
    j["focal_px"] = intr.focal;
    j["pose"] = poseJson(pose);
    j["terrain"] = ig::describeTerrain(map);
    runStereo(s, map, pose, intr, options, depthPath, j);
    if (!jsonPath.empty()) io::writeTextOutput("--json", jsonPath, j.dump(2) + "\n");
    return 0;
}

}  // namespace

int main(int argc, char** argv) {
    CLI::App app{"Render one frame of a voxel terrain by ray casting."};
    app.footer(kConventions);
    ig::TerrainOptions terrain;
    ig::addTerrainOptions(app, terrain);
    // The shipped map's view; other maps get ig::defaultViewPose.
    const std::string shippedPose = "52000,38000,+1200,55,-8,0";
    std::string poseText;
    std::string sizeText = "720x486";
    double fovDeg = 60.0;
    int margin = 0;
    std::string casterText = "fast";
    std::string outPath = "frame.png";
    std::string depthPath, jsonPath;
    int threads = 0;
    double haze = 0.0;
    std::string levelsText = "auto";
    int supersample = 1;
    std::string kernelText = "auto";
    app.add_option("--pose", poseText,
                   "x,y,z,yaw,pitch,roll (metres, degrees; z may be +H). Default: " + shippedPose +
                       " over the shipped map; over others, above the south-west quarter looking "
                       "toward the far corner");
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
    // Multiresolution (fast caster).
    app.add_option("--levels", levelsText,
                   "Coarser levels beyond the distance where a voxel shrinks below a pixel: auto "
                   "(all) | 0 (single level, exact) | N (at most N)")
        ->capture_default_str();
    app.add_option("--supersample", supersample,
                   "Fast caster: rays per pixel stacked vertically and averaged, 1..8 (a fixed "
                   "setting; it helps most at shallow pitch)")
        ->capture_default_str();
    app.add_option("--kernel", kernelText,
                   "Fast caster: auto (the widest the processor has) | scalar | avx2 | avx512; "
                   "the same image with each, refused where the processor lacks it")
        ->capture_default_str();
    std::string scenePath, objectsOut;
    std::optional<double> sceneTime;
    app.add_option("--scene", scenePath,
                   "Scene file (JSON): voxel objects placed and scattered over the terrain; drawn "
                   "by the reference and naive casters");
    app.add_option("--objects-out", objectsOut,
                   "Object-id image: 16-bit grey PNG, 0 for terrain or sky (needs --scene)");
    app.add_option("--time", sceneTime,
                   "Scene time, seconds, for the moving objects (default: the earliest start of "
                   "their trajectories)");
    StereoFlags stereo;
    addStereoFlags(app, stereo);
    CLI11_PARSE(app, argc, argv);

    return ig::runProgram("ig-render", [&]() -> int {
        // A signal ends the run at once, leaving no file half written.
        io::installStopSignals(true);
        // Every path, checked before the terrain is loaded and the frame rendered: no output
        // on an input or on another output, standard output for one at most. (--out is not
        // written with --stereo.)
        const auto out = io::PathRole::Output;
        io::checkRunPaths({{"--height", terrain.height, io::PathRole::Input},
                           {"--color", terrain.color, io::PathRole::Input},
                           {"--out", stereo.enabled() ? std::string() : outPath, out},
                           {"--depth", depthPath, out},
                           {"--json", jsonPath, out},
                           {"--scene", scenePath, io::PathRole::Input},
                           {"--objects-out", objectsOut, out},
                           {"--out-left", stereo.outLeft, out},
                           {"--out-right", stereo.outRight, out},
                           {"--out-sbs", stereo.outSbs, out},
                           {"--out-anaglyph", stereo.outAnaglyph, out},
                           {"--out-raycast-mask", stereo.outMask, out}});
        if (!(fovDeg > 0.0 && fovDeg < 179.0)) {
            throw ig::InputError("--fov: must be between 0 and 179 degrees");
        }
        if (margin < 0 || margin > 4096) throw ig::InputError("--margin: must be 0..4096 pixels");
        if (threads < 0 || threads > 1024) throw ig::InputError("--threads: must be 0..1024");
        if (!(haze >= 0.0) || !std::isfinite(haze)) throw ig::InputError("--haze: must be >= 0");
        const auto [w, h] = ig::parseSize(sizeText);
        const ig::CasterKind kind = ig::parseCasterKind(casterText);
        if (!objectsOut.empty() && scenePath.empty()) {
            throw ig::InputError("--objects-out: give a --scene to draw objects from");
        }
        if (sceneTime && scenePath.empty()) throw ig::InputError("--time: give a --scene");
        if (sceneTime && !std::isfinite(*sceneTime))
            throw ig::InputError("--time: not a finite number");
        if (!scenePath.empty() && (kind == ig::CasterKind::Fast || stereo.enabled())) {
            throw ig::InputError(
                "--scene: objects are drawn by the reference and naive casters; "
                "add --caster reference (or naive), without --stereo");
        }
        ig::TerrainMap map = ig::loadTerrainFromOptions(terrain);
        const bool shippedMap = terrain.height.empty() && terrain.synthetic.empty();
        const ig::Pose pose = !poseText.empty() ? ig::parsePose(poseText, map)
                              : shippedMap      ? ig::parsePose(shippedPose, map)
                                                : ig::defaultViewPose(map);
        if (kind == ig::CasterKind::Fast && pose.roll != 0.0) {
            throw ig::InputError(
                "--pose: the fast caster renders roll = 0 (roll is applied by the post-rendering "
                "processor); use --caster naive or reference for a truly rolled view");
        }
        const ig::Intrinsics intr = ig::Intrinsics::fromFov(w, h, ig::degToRad(fovDeg), margin);
        ig::RenderOptions options;
        options.threads = threads;
        options.sky.hazeDistance = haze;
        options.levels = ig::parseLevels(levelsText);
        if (supersample < 1 || supersample > 8) {
            throw ig::InputError("--supersample: must be 1..8 rays per pixel");
        }
        options.supersample = supersample;
        options.kernel = ig::parseCasterKernel(kernelText);
        if (kind != ig::CasterKind::Fast && options.kernel != ig::CasterKernel::Auto) {
            throw ig::InputError("--kernel " + kernelText +
                                 ": only the fast caster has kernels; drop --kernel or use "
                                 "--caster fast");
        }
        if (stereo.enabled())
            return renderStereoPair(stereo, kind, map, pose, intr, options, depthPath, jsonPath);
        // The scene: the static layer, and the moving objects stamped at the frame's time.
        std::optional<ig::Scene> scene;
        std::optional<sim::SceneMotion> motion;
        std::optional<ig::ObjectLayer> moving;
        double time = 0.0;
        if (!scenePath.empty()) {
            scene.emplace(ig::loadScene(scenePath, map));
            motion.emplace(*scene);
            time = sceneTime.value_or(motion->startTime());
            moving.emplace(motion->stamp(time));
            // The max-height bounds cover the objects (static ones: the moving ones are
            // stamped per frame and looked up by the casters directly).
            ig::includeStickTops(map, *scene->staticLayer);
            options.objects = {&*scene->staticLayer, &*moving};
        }
        const auto caster = ig::makeCaster(kind, map, options);
        const ig::RenderedFrame frame = ig::renderFrame(*caster, map, pose, intr, time);
        if (!objectsOut.empty()) {
            std::string idError;
            if (io::writePng16(objectsOut, frame.width(), frame.height(), frame.objectId,
                               &idError) != 0) {
                throw ig::InputError("--objects-out " + idError);
            }
        }

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
        j["levels"] = levelsText;
        j["supersample"] = supersample;
        j["kernel"] = std::string(frame.stats.kernel);
        j["pose"] = poseJson(pose);
        j["terrain"] = ig::describeTerrain(map);
        for (const ig::ControlPoint& cp : frame.controlPoints) {
            j["control_points"].push_back(
                {{"px", {cp.pixel.x, cp.pixel.y}},
                 {"world", {cp.world.x, cp.world.y, cp.world.z, cp.world.w}}});
        }
        if (scene) {
            const ig::ObjectLayer& layer = *scene->staticLayer;
            j["scene"] = {{"file", scenePath},
                          {"time", time},
                          {"static_objects", layer.objects().size()},
                          {"moving_objects", scene->moving.size()},
                          {"object_cell_m", layer.cellSizeX()},
                          {"object_cells", layer.cellEntries()},
                          {"stick_lists", layer.table().lists()},
                          {"stick_table_bytes", layer.table().bytes()},
                          {"layer_bytes", layer.bytes()}};
            j["objects"] = nlohmann::json::array();
            for (const ig::ObjectPixels& o : ig::objectPixelStats(frame)) {
                j["objects"].push_back(
                    {{"id", o.id}, {"pixels", o.pixels}, {"box", {o.x0, o.y0, o.x1, o.y1}}});
            }
        }
        if (!jsonPath.empty()) io::writeTextOutput("--json", jsonPath, j.dump(2) + "\n");
        if (outPath != "-") {
            std::fprintf(stderr,
                         "%s (%s): %dx%d in %.1f ms (%.1f ns/pixel, %.2f steps/pixel) -> %s\n",
                         casterText.c_str(), std::string(frame.stats.kernel).c_str(), frame.width(),
                         frame.height(), frame.stats.renderMs, frame.stats.renderMs * 1e6 / pixels,
                         static_cast<double>(frame.stats.steps) / pixels, outPath.c_str());
        }
        return 0;
    });
}
