// ig-render: renders one frame of a terrain with a chosen caster; writes colour, depth, stats.
#include "base/text.hpp"
#include "ig/caster.hpp"
#include "ig/cli.hpp"
#include "ig/error.hpp"
#include "ig/object_trace.hpp"
#include "ig/paged_insets.hpp"
#include "ig/paged_terrain.hpp"
#include "ig/pose_sweep.hpp"
#include "ig/scene.hpp"
#include "ig/stereo.hpp"
#include "io/image_file.hpp"
#include "io/output_file.hpp"
#include "io/stop_signals.hpp"
#include "sim/scene_motion.hpp"
#include "sim/trajectory.hpp"

#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>
#include <unistd.h>
#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <iterator>
#include <limits>
#include <mutex>
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
  The fast and span casters render roll = 0 (the post-rendering processor applies roll as a 2D
  rotation); the naive and reference casters honour any roll. The span caster hands steep frames
  to the fast caster (its JSON "path" says which drew the frame).
  Objects (--scene, every caster): --objects-out writes each pixel's object id as a 16-bit grey
  PNG (0: terrain or sky); --json lists each visible object's pixel count and box [x0, y0, x1,
  y1] (inclusive). With --stereo the objects are drawn over both eyes (--objects-out-left,
  --objects-out-right; --json "objects" and "objects_right"). Moving objects are placed at --time (default: the earliest
  trajectory start).
  Batch times (--poses): frame k of a pose list is at --time + k * --time-step (k from 0, the
  k-th pose, comments not counted; --time defaults as above, --time-step to 0); a trajectory
  CSV's frames are at its own sample times. Each frame's moving objects and sun are at its time.
  A path of '-' writes to standard output.)";

// ---- Stereo (--stereo): left eye by the fast caster, right eye reprojected or cast. ----------

struct StereoFlags {
    std::optional<double> separation;
    std::string right = "reproject";
    std::string variant = "wan";
    bool noAbuffer = false;
    double gapThreshold = 2.0;
    std::string outLeft, outRight, outSbs, outAnaglyph, outMask;
    std::string idsLeft, idsRight;  // object-id PNGs (with --scene)
    double nearM = 0.0;             // --near: both eyes

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
    app.add_option("--objects-out-left", s.idsLeft,
                   "Stereo with --scene: the left eye's object ids, 16-bit grey PNG");
    app.add_option("--objects-out-right", s.idsRight,
                   "Stereo with --scene: the right eye's object ids, 16-bit grey PNG");
}

nlohmann::json objectsJson(const ig::RenderedFrame& frame);

void writeIds(const std::string& path, const std::string& flag, const ig::RenderedFrame& frame) {
    if (path.empty()) return;
    std::string error;
    if (io::writePng16(path, frame.width(), frame.height(), frame.objectId, &error) != 0) {
        throw ig::InputError(flag + " " + error);
    }
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
// A pair over a terrain with insets: its maps and each inset's options (as the nested
// caster's).
struct StereoInsets {
    ig::NestedMaps maps;
    std::vector<ig::RenderOptions> options;
};

void runStereo(const StereoFlags& s, const ig::TerrainMap& map, const StereoInsets* insets,
               const ig::Pose& pose, const ig::Intrinsics& intr, const ig::RenderOptions& options,
               double time, const std::string& depthPath, nlohmann::json& j) {
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
    so.nearM = s.nearM;
    if (s.nearM > 0.0) j["near_m"] = s.nearM;
    const ig::StereoFrame f =
        insets ? ig::renderStereo(insets->maps, insets->options, pose, intr, so, options, time)
               : ig::renderStereo(map, pose, intr, so, options, time);
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
    if (!options.objects.empty()) {
        writeIds(s.idsLeft, "--objects-out-left", f.left);
        writeIds(s.idsRight, "--objects-out-right", f.right);
        j["objects"] = objectsJson(f.left);
        j["objects_right"] = objectsJson(f.right);
        j["objects_ms"] = f.stats.objectsMs;
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
                     const StereoInsets* insets, const ig::Pose& pose, const ig::Intrinsics& intr,
                     const ig::RenderOptions& options, double time, const std::string& depthPath,
                     const std::string& jsonPath, const nlohmann::json& scene) {
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
    if (!scene.is_null()) j["scene"] = scene;
    runStereo(s, map, insets, pose, intr, options, time, depthPath, j);
    if (!jsonPath.empty()) io::writeTextOutput("--json", jsonPath, j.dump(2) + "\n");
    return 0;
}

// ---- Batch (--poses): many frames from one load of the terrain. --------------------------------

// PATTERN with its run of '#' replaced by `index` zero-padded to the run's length (at least);
// empty stays empty.
std::string numberedPath(const std::string& pattern, int index) {
    if (pattern.empty()) return {};
    const std::size_t first = pattern.find('#');
    const std::size_t last = pattern.find_first_not_of('#', first);
    const std::size_t run = (last == std::string::npos ? pattern.size() : last) - first;
    std::string digits = std::to_string(index);
    if (digits.size() < run) digits.insert(0, run - digits.size(), '0');
    return pattern.substr(0, first) + digits + pattern.substr(first + run);
}

void checkPattern(const std::string& pattern, const std::string& flag) {
    if (pattern.empty()) return;
    const std::size_t first = pattern.find('#');
    if (first == std::string::npos || pattern == "-") {
        throw ig::InputError(flag + " " + base::quoted(pattern) +
                             ": with --poses give a file name with a run of # for the frame "
                             "number, e.g. frames/color_####.png");
    }
    const std::size_t last = pattern.find_first_not_of('#', first);
    if (last != std::string::npos && pattern.find('#', last) != std::string::npos) {
        throw ig::InputError(flag + " " + base::quoted(pattern) + ": one run of # only");
    }
}

// Poses of a --poses file: pose lines, or a trajectory CSV sampled every `every` seconds.
// `where` receives what names each pose in a message ("FILE line N", "FILE at t = T s").
std::vector<ig::Pose> batchPoses(const std::string& path, std::optional<double> every,
                                 const ig::TerrainMap& map, std::vector<std::string>& where,
                                 std::vector<double>& times) {
    if (every) {
        if (!(std::isfinite(*every) && *every > 0.0)) {
            throw ig::InputError("--every: must be a positive number of seconds");
        }
        const sim::Trajectory trajectory = sim::Trajectory::loadCsv(path);
        const double span = trajectory.endTime() - trajectory.startTime();
        if (span / *every > 1e6) {
            throw ig::InputError("--every " + base::number(*every) +
                                 ": more than a million frames over " + path);
        }
        std::vector<ig::Pose> poses;
        for (int k = 0;; ++k) {
            const double t = trajectory.startTime() + k * *every;
            if (t > trajectory.endTime() + 1e-9 * std::max(1.0, span)) break;
            poses.push_back(trajectory.poseAt(t));
            times.push_back(t);
            where.push_back(path + " at t = " + base::number(t) + " s");
        }
        return poses;
    }
    std::ifstream in(path, std::ios::binary);
    if (!in) throw ig::InputError("--poses " + path + ": cannot open the file");
    std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    if (text.size() > (64u << 20)) throw ig::InputError("--poses " + path + ": larger than 64 MiB");
    std::vector<int> lines;
    std::vector<ig::Pose> poses = ig::parsePoseList(text, map, path, &lines);
    for (const int line : lines)
        where.push_back(path + " line " + std::to_string(line));
    return poses;
}

struct BatchFlags {
    std::string posesPath;
    std::optional<double> every;
    std::optional<double> timeStep;
    double nearM = 0.0;  // --near
};

// The scene of a batch: the static layer, and the moving objects the caster draws, which the
// batch stamps at each frame's time before rendering it (the caster holds their address).
struct BatchScene {
    const sim::SceneMotion* motion = nullptr;
    ig::ObjectLayer* moving = nullptr;
    std::string idPattern;  // --objects-out, numbered

    bool enabled() const { return motion != nullptr; }
};

// A frame's visible objects as --json lists them.
nlohmann::json objectsJson(const ig::RenderedFrame& frame) {
    nlohmann::json list = nlohmann::json::array();
    for (const ig::ObjectPixels& o : ig::objectPixelStats(frame)) {
        list.push_back({{"id", o.id}, {"pixels", o.pixels}, {"box", {o.x0, o.y0, o.x1, o.y1}}});
    }
    return list;
}

// Renders every pose of the batch (frames spread over the threads, each frame's image the
// same whatever the thread count), writes the numbered images and one JSON.
int renderBatch(const BatchFlags& batch, const ig::Caster& caster, const ig::TerrainMap& map,
                const ig::Intrinsics& intr, int threads, double startTime, const BatchScene& scene,
                const std::string& outPattern, const std::string& depthPattern,
                const std::string& jsonPath, const nlohmann::json& common) {
    std::vector<std::string> where;
    std::vector<double> times;
    const std::vector<ig::Pose> poses = batchPoses(batch.posesPath, batch.every, map, where, times);
    const int n = static_cast<int>(poses.size());
    if (!batch.every) {
        const double step = batch.timeStep.value_or(0.0);
        for (int i = 0; i < n; ++i)
            times.push_back(startTime + i * step);
    }
    for (int i = 0; i < n; ++i) {
        const std::string& what = where[static_cast<std::size_t>(i)];
        if (caster.kind() == ig::CasterKind::Fast && poses[i].roll != 0.0) {
            throw ig::InputError(what +
                                 ": the fast caster renders roll = 0; use --caster naive "
                                 "or reference for a rolled view");
        }
        try {
            ig::validateView(map, poses[i], intr);
        } catch (const ig::InputError& e) {
            throw ig::InputError(what + ": " + e.what());
        }
    }
    std::vector<nlohmann::json> records(static_cast<std::size_t>(n));
    std::atomic<int> done{0};
    std::mutex progressMutex;
    const bool bar = isatty(fileno(stderr)) != 0;
    std::atomic<bool> failed{false};
    std::string failure;
    const auto start = std::chrono::steady_clock::now();
    auto renderOne = [&](int i) {
        if (failed.load() || io::stopRequested()) return;
        try {
            const double time = times[static_cast<std::size_t>(i)];
            if (scene.enabled()) *scene.moving = scene.motion->stamp(time);
            const ig::RenderedFrame frame = ig::renderFrame(
                caster, map, poses[i], intr, time, static_cast<std::uint64_t>(i), batch.nearM);
            std::string error;
            const std::string colorPath = numberedPath(outPattern, i);
            const auto* bytes = reinterpret_cast<const std::uint8_t*>(frame.color.data());
            if (io::writePng8(colorPath, frame.width(), frame.height(), 3,
                              {bytes, frame.color.size() * 3}, &error) != 0) {
                throw ig::InputError("--out " + error);
            }
            const std::string depthPath = numberedPath(depthPattern, i);
            if (!depthPath.empty() &&
                io::writePfm(depthPath, frame.width(), frame.height(), frame.depth, &error) != 0) {
                throw ig::InputError("--depth " + error);
            }
            const std::string idPath = numberedPath(scene.idPattern, i);
            if (!idPath.empty() && io::writePng16(idPath, frame.width(), frame.height(),
                                                  frame.objectId, &error) != 0) {
                throw ig::InputError("--objects-out " + error);
            }
            const double pixels = static_cast<double>(frame.width()) * frame.height();
            nlohmann::json r;
            r["index"] = i;
            r["time"] = time;
            r["pose"] = poseJson(poses[i]);
            r["render_ms"] = frame.stats.renderMs;
            r["rays_per_pixel"] = static_cast<double>(frame.stats.rays) / pixels;
            r["steps_per_pixel"] = static_cast<double>(frame.stats.steps) / pixels;
            r["coherence_restarts"] = frame.stats.restarts;
            r["out"] = colorPath;
            if (!depthPath.empty()) r["depth"] = depthPath;
            if (!idPath.empty()) r["objects_out"] = idPath;
            if (scene.enabled()) r["objects"] = objectsJson(frame);
            records[static_cast<std::size_t>(i)] = std::move(r);
        } catch (const std::exception& e) {
            const std::lock_guard lock(progressMutex);
            if (!failed.exchange(true)) failure = e.what();
            return;
        }
        const int finished = ++done;
        if (bar) {
            const std::lock_guard lock(progressMutex);
            const int width = 40, filled = finished * width / n;
            std::fprintf(stderr, "\r[%s%s] %d/%d frames", std::string(filled, '#').c_str(),
                         std::string(width - filled, ' ').c_str(), finished, n);
            if (finished == n) std::fprintf(stderr, "\n");
        }
    };
    // With a scene the moving layer is the caster's one copy, stamped per frame: frames go one
    // after another, each frame's columns over the workers.
    auto all = [&] {
        if (scene.enabled()) {
            for (int i = 0; i < n; ++i)
                renderOne(i);
        } else {
            tbb::parallel_for(0, n, renderOne);
        }
    };
    if (threads > 0) {
        tbb::task_arena arena(threads);
        arena.execute(all);
    } else {
        all();
    }
    if (failed) throw ig::InputError(failure);
    if (io::stopRequested()) return 130;
    const double seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    nlohmann::json j = common;
    j["poses"] = batch.posesPath;
    if (batch.every) j["every_s"] = *batch.every;
    j["frames"] = records;
    j["total_s"] = seconds;
    j["frames_per_s"] = n / std::max(seconds, 1e-9);
    if (!jsonPath.empty()) io::writeTextOutput("--json", jsonPath, j.dump(2) + "\n");
    std::fprintf(stderr, "%d frames %dx%d in %.2f s (%.2f frames/s) -> %s\n", n, intr.width,
                 intr.height, seconds, n / std::max(seconds, 1e-9), outPattern.c_str());
    return 0;
}

// What the flags ask of one frame from a paged database.
struct PagedRequest {
    std::string poseText, casterText, outPath, depthPath, jsonPath;
    std::string scenePath, objectsOut;  // a scene drawn over the frame, its object-id image
    std::optional<double> sceneTime;
    const StereoFlags* stereo = nullptr;  // a stereo pair instead of one frame
    ig::CasterKind kind = ig::CasterKind::Reference;
    ig::Intrinsics intr;
    int threads = 0;
    int levels = 0;
    ig::CasterKernel kernel = ig::CasterKernel::Auto;
    double nearM = 0.0;
};

// One frame from a database over --cache-mb: the tiles its footprint needs are read (waiting
// for each: no deadline here) into the sparse map (and, for the fast caster, the sparse
// pyramid) the caster reads (ig/paged_terrain.hpp), so the image is the in-memory render's
// wherever every tile could be read; an unreadable tile is drawn from a coarser level and
// reported.
int renderPaged(const ig::TerrainOptions& terrain, const ig::TerrainDb& db,
                const ig::AppearanceOptions& look, const PagedRequest& r) {
    if (r.kind == ig::CasterKind::Span) {
        throw ig::InputError("--caster " + r.casterText + ": " + terrain.db +
                             " is over --cache-mb and is rendered paged, which the reference, "
                             "naive and fast casters do; use one of them, or a larger --cache-mb");
    }
    const bool fast = r.kind == ig::CasterKind::Fast;
    ig::PagedTerrain::Options po;
    po.cache.budgetBytes = static_cast<std::size_t>(terrain.cacheMb * 1048576.0);
    po.pyramid = fast;
    po.levels = r.levels;
    // The map and the insets the database holds, each paged through a cache of its own.
    ig::PagedNestedTerrain nestedPaged(db, po);
    ig::PagedTerrain& paged = nestedPaged.global();
    const bool nesting = nestedPaged.insetCount() > 0;
    const ig::NestedGround nestedGround(nestedPaged.maps());
    const ig::TerrainMap& map = paged.map();
    const ig::Appearance appearance = ig::parseAppearance(look, terrain, map);
    if (appearance.ramp || appearance.shade) {
        throw ig::InputError(std::string(appearance.ramp ? "--colors ramp" : "--shade") +
                             ": not with a database rendered paged (over --cache-mb)");
    }
    // The ground under the pose first (a height given as +H is above it).
    ig::Pose pose;
    if (r.poseText.empty()) {
        nestedPaged.placeAround(0.25 * map.extentX(), 0.25 * map.extentY());
        pose = ig::defaultViewPose(map);
    } else {
        const ig::Pose where = ig::parsePose(r.poseText, map);
        nestedPaged.placeAround(where.position.x, where.position.y);
        // With insets, a height given as +H is above their surface where they lie.
        pose =
            ig::parsePose(r.poseText, nesting ? static_cast<const ig::Ground&>(nestedGround) : map);
    }
    if (fast && pose.roll != 0.0) {
        throw ig::InputError(
            "--pose: the fast caster renders roll = 0 (roll is applied by the "
            "post-rendering processor); use --caster naive or reference for a "
            "truly rolled view");
    }
    ig::RenderOptions options;
    options.threads = r.threads;
    options.levels = r.levels;
    options.kernel = r.kernel;
    options.pyramid = paged.pyramid();
    options.slopes = paged.slopes();
    options.sky.hazeDistance = appearance.hazeDistance;
    options.supersample = appearance.supersample;
    options.supersampleMax = appearance.supersampleMax;
    // A scene stands on the database's ground: each height it reads places the tile under it
    // first (ig::PlacingGround), so its objects are where they are over the map in memory.
    std::optional<ig::Scene> scene;
    std::optional<sim::SceneMotion> motion;
    std::optional<ig::ObjectLayer> moving;
    double time = r.sceneTime.value_or(0.0);
    if (!r.scenePath.empty()) {
        // With insets, the objects stand on their surface where they lie.
        const ig::PlacingNestedGround placing(nestedPaged);
        scene.emplace(ig::loadScene(r.scenePath, map, true, &placing));
        motion.emplace(*scene);
        time = r.sceneTime.value_or(motion->startTime());
        moving.emplace(motion->stamp(time, &placing));
        options.objects = {&*scene->staticLayer, &*moving};
    }
    const ig::Camera camera(pose, r.intr);
    const bool pair = r.stereo && r.stereo->enabled();
    if (pair && r.kind != ig::CasterKind::Fast) {
        throw ig::InputError("--stereo: the pair is rendered by the fast caster; drop --caster");
    }
    // A pair's right eye (reprojected or cast whole) reads its own tiles too.
    const ig::Camera rightEye(ig::rightEyePose(pose, pair ? *r.stereo->separation : 0.0), r.intr);
    const auto start = std::chrono::steady_clock::now();
    const ig::PagedFrameStats st =
        nestedPaged.prepare(camera, true, {}, 0.0, pair ? &rightEye : nullptr);
    const double pageMs =
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
    for (const std::string& m : st.failures)
        std::fprintf(stderr, "ig-render: %s (drawn from a coarser level)\n", m.c_str());
    if (st.substituted > st.failed) {
        std::fprintf(stderr,
                     "ig-render: %zu of the frame's %zu tiles did not fit --cache-mb %g: drawn "
                     "from a coarser level\n",
                     st.substituted - st.failed, st.required, terrain.cacheMb);
    }
    if (pair) {
        nlohmann::json sceneJson;
        if (scene) {
            sceneJson = {{"file", r.scenePath},
                         {"time", time},
                         {"static_objects", scene->staticLayer->objects().size()},
                         {"moving_objects", scene->moving.size()}};
        }
        std::optional<StereoInsets> pairInsets;
        if (nesting) {
            pairInsets.emplace(StereoInsets{nestedPaged.maps(), nestedPaged.insetOptions(options)});
        }
        return renderStereoPair(*r.stereo, r.kind, map, pairInsets ? &*pairInsets : nullptr, pose,
                                r.intr, nesting ? nestedPaged.globalOptions(options) : options,
                                time, r.depthPath, r.jsonPath, sceneJson);
    }
    const auto caster =
        nesting ? nestedPaged.makeCaster(r.kind, options) : ig::makeCaster(r.kind, map, options);
    const ig::RenderedFrame frame =
        nesting ? ig::renderNestedFrame(*caster, nestedPaged.maps(), pose, r.intr, time, 0, r.nearM)
                : ig::renderFrame(*caster, map, pose, r.intr, time, 0, r.nearM);
    std::string error;
    if (!r.objectsOut.empty() &&
        io::writePng16(r.objectsOut, frame.width(), frame.height(), frame.objectId, &error) != 0) {
        throw ig::InputError("--objects-out " + error);
    }
    const auto* bytes = reinterpret_cast<const std::uint8_t*>(frame.color.data());
    if (io::writePng8(r.outPath, frame.width(), frame.height(), 3, {bytes, frame.color.size() * 3},
                      &error) != 0) {
        throw ig::InputError("--out " + error);
    }
    if (!r.depthPath.empty() &&
        io::writePfm(r.depthPath, frame.width(), frame.height(), frame.depth, &error) != 0) {
        throw ig::InputError("--depth " + error);
    }
    const ig::TileCacheStats cs = paged.cache().stats();
    nlohmann::json j;
    j["caster"] = r.casterText;
    j["kernel"] = std::string(frame.stats.kernel);
    j["width"] = frame.width();
    j["height"] = frame.height();
    j["render_ms"] = frame.stats.renderMs;
    j["pose"] = poseJson(pose);
    j["terrain"] = ig::describeTerrain(map);
    for (std::size_t k = 0; k < nestedPaged.insetCount(); ++k) {
        const ig::Inset& in = nestedPaged.placement(k);
        j["insets"].push_back({{"name", in.name},
                               {"cells", {in.x0, in.y0, in.x1, in.y1}},
                               {"factor", in.factor},
                               {"spacing_m", nestedPaged.inset(k).map().spacingX()},
                               {"tiles_read", nestedPaged.inset(k).cache().stats().tilesRead}});
    }
    if (scene) {
        j["scene"] = {{"file", r.scenePath},
                      {"time", time},
                      {"static_objects", scene->staticLayer->objects().size()},
                      {"moving_objects", scene->moving.size()}};
        j["objects"] = nlohmann::json::array();
        for (const ig::ObjectPixels& o : ig::objectPixelStats(frame)) {
            j["objects"].push_back(
                {{"id", o.id}, {"pixels", o.pixels}, {"box", {o.x0, o.y0, o.x1, o.y1}}});
        }
    }
    j["paging"] = {{"budget_mb", terrain.cacheMb},
                   {"tiles_needed", st.required},
                   {"tiles_substituted", st.substituted},
                   {"node_tiles_needed", st.nodesRequired},
                   {"node_tiles_missing", st.nodesMissing},
                   {"tiles_failed", st.failed},
                   {"tiles_read", cs.tilesRead},
                   {"bytes_read", cs.bytesRead},
                   {"resident_bytes", paged.cache().residentBytes()},
                   {"page_ms", pageMs}};
    if (!r.jsonPath.empty()) io::writeTextOutput("--json", r.jsonPath, j.dump(2) + "\n");
    if (r.outPath != "-") {
        std::fprintf(
            stderr, "%s (paged, %zu tiles, %llu read in %.1f ms): %dx%d in %.1f ms -> %s\n",
            r.casterText.c_str(), st.required, static_cast<unsigned long long>(cs.tilesRead),
            pageMs, frame.width(), frame.height(), frame.stats.renderMs, r.outPath.c_str());
    }
    return 0;
}

}  // namespace

int main(int argc, char** argv) {
    CLI::App app{"Render frames of a voxel terrain by ray casting: one pose, or a batch."};
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
    std::string outPath;
    std::string depthPath, jsonPath;
    int threads = 0;
    std::string levelsText = "auto";
    std::string kernelText = "auto";
    ig::AppearanceOptions look;
    ig::InsetOptions insets;
    BatchFlags batch;
    app.add_option("--pose", poseText,
                   "x,y,z,yaw,pitch,roll (metres, degrees; z may be +H). Default: " + shippedPose +
                       " over the shipped map; over others, above the south-west quarter looking "
                       "toward the far corner");
    app.add_option("--poses", batch.posesPath,
                   "Batch: a file of x,y,z,yaw,pitch,roll lines (as --pose), or with --every a "
                   "trajectory CSV; --out and --depth then name numbered files (a run of #)");
    app.add_option("--every", batch.every,
                   "Batch: --poses is a trajectory CSV, sampled every this many seconds (each "
                   "frame at its sample time)");
    app.add_option("--time-step", batch.timeStep,
                   "Batch of pose lines: frame k is at --time + k * this many seconds (default "
                   "0: every frame at --time)");
    app.add_option("--fov", fovDeg, "Horizontal field of view of the window, degrees")
        ->capture_default_str();
    app.add_option("--size", sizeText, "Window size WxH")->capture_default_str();
    app.add_option("--margin", margin, "Extra pixels rendered on every side")
        ->capture_default_str();
    app.add_option("--near", batch.nearM,
                   "Near clipping plane, metres ahead along the view axis: nothing nearer is "
                   "drawn (default 0: none)")
        ->capture_default_str();
    app.add_option("--caster", casterText, "fast | span | naive | reference")
        ->capture_default_str();
    app.add_option("--out", outPath, "Colour PNG (default frame.png; with --poses frame_####.png)");
    app.add_option("--depth", depthPath, "Depth PFM (metres from the eye, +inf for sky)");
    app.add_option("--json", jsonPath, "Stats and control points as JSON (--poses: per frame)");
    app.add_option("--threads", threads,
                   "Worker threads (0: all cores); a batch spreads frames and pixels over them")
        ->capture_default_str();
    ig::addAppearanceOptions(app, look);
    // Multiresolution (fast caster).
    app.add_option("--levels", levelsText,
                   "Coarser levels beyond the distance where a voxel shrinks below a pixel: auto "
                   "(all) | 0 (single level, exact) | N (at most N)")
        ->capture_default_str();
    app.add_option("--kernel", kernelText,
                   "Fast caster: auto (the widest the processor has) | scalar | avx2 | avx512, "
                   "refused where the processor lacks it | rows4-portable | rows8-portable (the "
                   "row batches' scalar twins, for tests: the avx2 and avx512 images on any "
                   "processor)")
        ->capture_default_str();
    std::string scenePath, objectsOut;
    std::optional<double> sceneTime;
    app.add_option("--scene", scenePath,
                   "Scene file (JSON): voxel objects placed and scattered over the terrain; drawn "
                   "by every caster over its terrain");
    app.add_option("--objects-out", objectsOut,
                   "Object-id image: 16-bit grey PNG, 0 for terrain or sky (needs --scene; with "
                   "--poses numbered as --out)");
    app.add_option("--time", sceneTime,
                   "Scene time, seconds, for the moving objects (default: the earliest start of "
                   "their trajectories) and a sun moved by --sun-rate (default 0)");
    ig::addInsetOptions(app, insets);
    StereoFlags stereo;
    addStereoFlags(app, stereo);
    CLI11_PARSE(app, argc, argv);

    return ig::runProgram("ig-render", [&]() -> int {
        // A signal ends the run at once, leaving no file half written.
        io::installStopSignals(true);
        const bool batchMode = !batch.posesPath.empty();
        if (outPath.empty()) outPath = batchMode ? "frame_####.png" : "frame.png";
        if (!(batch.nearM >= 0.0) || !std::isfinite(batch.nearM))
            throw ig::InputError("--near: must be a finite distance of 0 (none) or more metres");
        stereo.nearM = batch.nearM;
        if (batchMode) {
            if (stereo.enabled()) throw ig::InputError("--poses: not with --stereo");
            if (!poseText.empty())
                throw ig::InputError("--poses: give --pose or --poses, not both");
            checkPattern(outPath, "--out");
            checkPattern(depthPath, "--depth");
            checkPattern(objectsOut, "--objects-out");
            if (batch.every && (sceneTime || batch.timeStep)) {
                throw ig::InputError(std::string(sceneTime ? "--time" : "--time-step") +
                                     ": a trajectory's frames (--every) are at its own times");
            }
            if (batch.timeStep && !(std::isfinite(*batch.timeStep) && *batch.timeStep >= 0.0 &&
                                    *batch.timeStep <= 1e7)) {
                throw ig::InputError("--time-step: must be 0..1e7 seconds");
            }
        } else if (batch.every) {
            throw ig::InputError("--every: needs --poses (a trajectory CSV)");
        } else if (batch.timeStep) {
            throw ig::InputError("--time-step: needs --poses (a file of pose lines)");
        }
        // Every path, checked before the terrain is loaded and the frame rendered: no output
        // on an input or on another output, standard output for one at most. (--out is not
        // written with --stereo.)
        const auto out = io::PathRole::Output;
        io::checkRunPaths({{"--height", terrain.height, io::PathRole::Input},
                           {"--color", terrain.color, io::PathRole::Input},
                           {"--poses", batch.posesPath, io::PathRole::Input},
                           {"--out", stereo.enabled() ? std::string() : outPath, out},
                           {"--depth", depthPath, out},
                           {"--json", jsonPath, out},
                           {"--scene", scenePath, io::PathRole::Input},
                           {"--objects-out", objectsOut, out},
                           {"--out-left", stereo.outLeft, out},
                           {"--out-right", stereo.outRight, out},
                           {"--out-sbs", stereo.outSbs, out},
                           {"--out-anaglyph", stereo.outAnaglyph, out},
                           {"--out-raycast-mask", stereo.outMask, out},
                           {"--objects-out-left", stereo.idsLeft, out},
                           {"--objects-out-right", stereo.idsRight, out}});
        if (!(fovDeg > 0.0 && fovDeg < 179.0)) {
            throw ig::InputError("--fov: must be between 0 and 179 degrees");
        }
        if (margin < 0 || margin > 4096) throw ig::InputError("--margin: must be 0..4096 pixels");
        if (threads < 0 || threads > 1024) throw ig::InputError("--threads: must be 0..1024");
        const auto [w, h] = ig::parseSize(sizeText);
        const ig::CasterKind kind = ig::parseCasterKind(casterText);
        if (!objectsOut.empty() && scenePath.empty()) {
            throw ig::InputError("--objects-out: give a --scene to draw objects from");
        }
        if (sceneTime && scenePath.empty() && look.sunRate.empty()) {
            throw ig::InputError("--time: give a --scene or a moving sun (--sun-rate)");
        }
        if (sceneTime && !std::isfinite(*sceneTime))
            throw ig::InputError("--time: not a finite number");
        if (!objectsOut.empty() && stereo.enabled()) {
            throw ig::InputError(
                "--objects-out: with --stereo give --objects-out-left and --objects-out-right");
        }
        if ((!stereo.idsLeft.empty() || !stereo.idsRight.empty()) &&
            (!stereo.enabled() || scenePath.empty())) {
            throw ig::InputError(
                std::string(stereo.idsLeft.empty() ? "--objects-out-right" : "--objects-out-left") +
                ": needs --stereo and a --scene to draw objects from");
        }
        if (!terrain.db.empty()) {
            ig::checkDatabaseOptions(terrain);
            const ig::TerrainDb db = ig::TerrainDb::open(terrain.db);
            if (ig::databaseNeedsPaging(terrain, db)) {
                if (insets.any()) {
                    throw ig::InputError("--inset: not with " + terrain.db +
                                         " paged beyond --cache-mb (add insets to the database "
                                         "with ig-build-db --db " +
                                         terrain.db + " --inset ...)");
                }
                if (!db.insets().empty() && batchMode) {
                    throw ig::InputError(terrain.db +
                                         " holds insets: one frame or pair, without --poses");
                }
                if (batchMode) {
                    throw ig::InputError(terrain.db +
                                         " is over --cache-mb and is rendered paged: one frame "
                                         "or pair, without --poses (or give a larger --cache-mb)");
                }
                PagedRequest req;
                req.poseText = poseText;
                req.stereo = &stereo;
                req.scenePath = scenePath;
                req.objectsOut = objectsOut;
                req.sceneTime = sceneTime;
                req.casterText = casterText;
                req.outPath = outPath;
                req.depthPath = depthPath;
                req.jsonPath = jsonPath;
                req.kind = kind;
                req.intr = ig::Intrinsics::fromFov(w, h, ig::degToRad(fovDeg), margin);
                req.threads = threads;
                req.levels = ig::parseLevels(levelsText);
                req.kernel = ig::parseCasterKernel(kernelText);
                if (kind != ig::CasterKind::Fast && req.kernel != ig::CasterKernel::Auto) {
                    throw ig::InputError("--kernel " + kernelText +
                                         ": only the fast caster has kernels; drop --kernel or "
                                         "use --caster fast");
                }
                req.nearM = batch.nearM;
                return renderPaged(terrain, db, look, req);
            }
        }
        // Insets from the flags, or held by the database.
        const bool nesting = insets.any() || ig::databaseHasInsets(terrain);
        if (nesting) {
            if (batchMode) {
                throw ig::InputError(
                    std::string(insets.any() ? "--inset" : terrain.db + " holds insets") +
                    ": one frame or pair, without --poses");
            }
        }
        ig::TerrainMap map = ig::loadTerrainFromOptions(terrain);
        const ig::Appearance appearance = ig::parseAppearance(look, terrain, map);
        // With insets the map is the global one nested with them, and heights in --pose are
        // above a ground on or over every inset (NestedTerrain::upperGround).
        std::optional<ig::NestedTerrain> nested;
        if (nesting) {
            nested.emplace(ig::loadNestedTerrain(std::move(map), terrain, insets));
            map = nested->upperGround();
        }
        const bool shippedMap = ig::usesShippedMap(terrain);
        const ig::Pose pose = !poseText.empty() ? ig::parsePose(poseText, map)
                              : shippedMap      ? ig::parsePose(shippedPose, map)
                                                : ig::defaultViewPose(map);
        if (!batchMode && ig::casterNeedsLevelRoll(kind) && pose.roll != 0.0) {
            throw ig::InputError(
                "--pose: the " + casterText +
                " caster renders roll = 0 (roll is applied by the post-rendering "
                "processor); use --caster naive or reference for a truly rolled view");
        }
        const ig::Intrinsics intr = ig::Intrinsics::fromFov(w, h, ig::degToRad(fovDeg), margin);
        ig::RenderOptions options;
        options.threads = threads;
        options.levels = ig::parseLevels(levelsText);
        if (nested) {
            ig::applyAppearance(appearance, *nested, options);
        } else {
            ig::applyAppearance(appearance, map, options);
        }
        options.kernel = ig::parseCasterKernel(kernelText);
        if (kind != ig::CasterKind::Fast && options.kernel != ig::CasterKernel::Auto) {
            throw ig::InputError("--kernel " + kernelText +
                                 ": only the fast caster has kernels; drop --kernel or use "
                                 "--caster fast");
        }
        // The scene: the static layer, and the moving objects stamped at the frame's time.
        std::optional<ig::Scene> scene;
        std::optional<sim::SceneMotion> motion;
        std::optional<ig::ObjectLayer> moving;
        double time = sceneTime.value_or(0.0);  // the sun's too
        if (!scenePath.empty()) {
            // Over insets, the objects stand on the nested surface (the map here is the
            // upper ground, on the same grid).
            std::optional<ig::NestedGround> onInsets;
            if (nested) onInsets.emplace(nested->maps());
            const ig::Ground* ground = onInsets ? &*onInsets : nullptr;
            scene.emplace(ig::loadScene(scenePath, map, true, ground));
            motion.emplace(*scene);
            time = sceneTime.value_or(motion->startTime());
            moving.emplace(motion->stamp(time, ground));
            // Every caster draws the objects over its terrain by their own walk (the fast ones
            // by the objects' screen footprint), so the terrain's bounds stay as they are.
            options.objects = {&*scene->staticLayer, &*moving};
        }
        if (stereo.enabled()) {
            nlohmann::json sceneJson;
            if (scene) {
                sceneJson = {{"file", scenePath},
                             {"time", time},
                             {"static_objects", scene->staticLayer->objects().size()},
                             {"moving_objects", scene->moving.size()}};
            }
            std::optional<StereoInsets> pairInsets;
            if (nested) {
                pairInsets.emplace(
                    StereoInsets{nested->maps(),
                                 std::vector<ig::RenderOptions>(nested->insets().size(), options)});
            }
            return renderStereoPair(stereo, kind, map, pairInsets ? &*pairInsets : nullptr, pose,
                                    intr, options, time, depthPath, jsonPath, sceneJson);
        }
        const auto caster = nested ? ig::makeNestedCaster(kind, *nested, options)
                                   : ig::makeCaster(kind, map, options);
        if (batchMode) {
            nlohmann::json common;
            common["caster"] = casterText;
            common["width"] = intr.width;
            common["height"] = intr.height;
            common["margin"] = margin;
            common["near_m"] = batch.nearM;
            common["focal_px"] = intr.focal;
            common["levels"] = levelsText;
            common["supersample"] = look.supersample;
            common["haze_m"] = appearance.hazeDistance;
            common["haze_falloff_m"] = appearance.hazeFalloff;
            common["kernel"] = std::string(caster->kernelName());
            common["threads"] = threads;
            common["terrain"] = ig::describeTerrain(map);
            BatchScene batchScene;
            if (scene) {
                batchScene.motion = &*motion;
                batchScene.moving = &*moving;
                batchScene.idPattern = objectsOut;
                common["scene"] = {{"file", scenePath},
                                   {"static_objects", scene->staticLayer->objects().size()},
                                   {"moving_objects", scene->moving.size()}};
            }
            return renderBatch(batch, *caster, map, intr, threads, time, batchScene, outPath,
                               depthPath, jsonPath, common);
        }
        const ig::RenderedFrame frame =
            nested ? ig::renderNestedFrame(*caster, *nested, pose, intr, time, 0, batch.nearM)
                   : ig::renderFrame(*caster, map, pose, intr, time, 0, batch.nearM);
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
        j["near_m"] = batch.nearM;
        j["focal_px"] = intr.focal;
        j["render_ms"] = frame.stats.renderMs;
        j["ns_per_pixel"] = frame.stats.renderMs * 1e6 / pixels;
        j["steps_per_pixel"] = static_cast<double>(frame.stats.steps) / pixels;
        j["coherence_restarts"] = frame.stats.restarts;
        j["levels"] = levelsText;
        j["supersample"] = look.supersample;
        j["rays_per_pixel"] = static_cast<double>(frame.stats.rays) / pixels;
        j["haze_m"] = appearance.hazeDistance;
        j["haze_falloff_m"] = appearance.hazeFalloff;
        j["kernel"] = std::string(frame.stats.kernel);
        if (!frame.stats.path.empty()) j["path"] = std::string(frame.stats.path);
        j["pose"] = poseJson(pose);
        j["terrain"] = ig::describeTerrain(nested ? nested->global() : map);
        if (nested) {
            for (const ig::Inset& in : nested->insets()) {
                j["insets"].push_back({{"name", in.name},
                                       {"cells", {in.x0, in.y0, in.x1, in.y1}},
                                       {"factor", in.factor},
                                       {"spacing_m", in.map.spacingX()}});
            }
        }
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
