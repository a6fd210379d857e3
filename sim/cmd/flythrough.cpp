// flythrough: flies an aircraft over terrain through the real-time pipeline and writes fields.
#include "base/text.hpp"
#include "ig/caster.hpp"
#include "ig/cli.hpp"
#include "ig/error.hpp"
#include "ig/paged_ground.hpp"
#include "ig/paged_insets.hpp"
#include "ig/paged_terrain.hpp"
#include "ig/scene.hpp"
#include "ig/stereo.hpp"
#include "ig/sticks.hpp"
#include "ig/terrain_db.hpp"
#include "ig/terrain_db_build.hpp"
#include "io/contact_sheet.hpp"
#include "io/field_clock.hpp"
#include "io/field_weaver.hpp"
#include "io/frame_sink.hpp"
#include "io/gpio_stick.hpp"
#include "io/memory_lock.hpp"
#include "io/output_file.hpp"
#include "io/stick.hpp"
#include "io/stop_signals.hpp"
#include "io/udp_socket.hpp"
#include "prp/field.hpp"
#include "sim/cigi_session.hpp"
#include "sim/pipeline.hpp"
#include "sim/pose_source.hpp"
#include "sim/scenario.hpp"
#include "sim/scene_motion.hpp"
#include "sim/stereo_output.hpp"
#include "sim/terrain_queries.hpp"
#include "sim/trajectory.hpp"
#include "sim/trajectory_poses.hpp"
#include "sim/truth.hpp"

#include <unistd.h>
#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <optional>
#include <sstream>
#include <string>
#include <utility>

namespace {

constexpr const char* kDefaultOut = "y4m:out/flythrough.y4m";
constexpr const char* kDefaultContact = "out/flythrough_contact.png";

constexpr const char* kNotes =
    R"(With no arguments: flies the built-in ~10 s scenario over the shipped Puget Sound
terrain (a right turn, a climb, an aileron roll; data/scenarios/default.stick) and writes
out/flythrough.y4m (interlaced NTSC, bottom field first) and out/flythrough_contact.png.

Timing: a renderer thread renders as fast as it can (or --render-hz) into a latest-frame
mailbox; every 1001/60000 s a field is warped from the newest frame to the pose at the field's
own instant and handed to the output. --clock simulated runs the same loop without wall time,
every render modelled as taking 1/--render-hz s (12 Hz when uncapped): reproducible output.

Stick scripts: "TIME axis pitch|roll|yaw|throttle VALUE [ramp S]" or "TIME button trigger
down|up" per line. Trajectory CSV: a header naming t,x,y,z,yaw_deg,pitch_deg,roll_deg (any order; other columns ignored).
--start X,Y,Z,HEADING (metres, degrees; Z written +H is H metres above the terrain) sets where
a stick flight begins (default: the scenario's start on Puget Sound, else over the south-west
of the map heading north-east).

CIGI: --cigi [ADDR:]PORT --cigi-host ADDR:PORT --cigi-origin LAT,LON[,ALT] lets a CIGI 3.3 host
drive the ownship (entity 0, dead-reckoned with its Rate Control to every field's instant) and
ask HAT/HOT and line-of-sight questions; Start of Frame goes to the host every field. The origin
is the geodetic position of the map's south-west sample at height 0 (a local tangent plane
about it). Until the first Entity Control the ownship holds the --start pose; --cigi-wait S
waits up to S seconds for it before the first field. --cigi-view N picks the view shown (View
Control places the eye on the ownship every field; a symmetric View Definition received before
the first field sets the field of view, overriding --fov, and its far plane the draw
distance; one received during the run changes them from that field on). A host silent for
--cigi-timeout S is reported lost; the ownship dead-reckons for --cigi-extrapolate S after its
last message, then holds. Several image generators (one per channel, each on its own port) can
share one host.
--cigi-entity TYPE=MODEL[:SCALE] draws the host's other entities of that CIGI entity type as a
model of --scene, each at its dead-reckoned pose at the frame's instant with its entity id as
its object id (a renderer process gets them placed with each render request).

Objects: --scene FILE draws a scene's voxel objects (every caster, over its terrain), the moving
ones stamped at each frame's instant; every field carries the object ids warped with its
colour. With --stereo the objects are drawn over both eyes (not with --truth). --truth FILE writes one JSON line per field: each object in view or in
the frustum with its visible pixels, box and centroid in the field (output pixels, y the frame
line), its range, the box of its exact 3-D placement projected at the field's pose, and the
fraction hidden (docs/design/objects.md, "Ground truth"). On the wall clock a field whose truth
falls behind is written "late" (the objects it shows, no hidden fraction) or "lost" (its index
and time only): one line per field whatever happens, counted in the report.

Outputs: a file is written beside its path and renamed into place when complete; a device or
FIFO is written in place; an output on an input or another output is refused before the run;
standard output ('-') carries one output at most. SIGINT/SIGTERM end the run after the field in
hand with every output written (exit 130/143); a second signal ends it at once, the video cut to
its last whole frame.)";

// "x,y,z,heading": z may be "+H" (above the terrain).
// `paged`: the map is paged, and the tiles under the start are placed before its ground is read.
sim::FlightState parseStart(const std::string& text, const ig::TerrainMap& map,
                            const sim::FlightLimits& limits, ig::PagedTerrain* paged = nullptr) {
    std::stringstream ss(text);
    std::string part[4];
    for (int i = 0; i < 4; ++i) {
        if (!std::getline(ss, part[i], ',')) {
            throw ig::InputError("--start '" + text + "': expected X,Y,Z,HEADING");
        }
    }
    std::string rest;
    if (std::getline(ss, rest, ',')) {
        throw ig::InputError("--start '" + text + "': expected X,Y,Z,HEADING");
    }
    if (paged) {
        const double x = std::strtod(part[0].c_str(), nullptr);
        const double y = std::strtod(part[1].c_str(), nullptr);
        if (std::isfinite(x) && std::isfinite(y) && ig::nearMap(map, x, y)) {
            paged->placeAround(x, y);
        }
    }
    // Reuse the pose parser (it knows "+H").
    const ig::Pose p = ig::parsePose(
        part[0] + "," + part[1] + "," + part[2] + "," + part[3] + ",0,0", map, "--start");
    // As for trajectories: a start far off the map is a mistake of coordinates, not a flight.
    if (!ig::nearMap(map, p.position.x, p.position.y)) {
        char buf[256];
        std::snprintf(buf, sizeof buf,
                      "lies far off the map (which spans x 0..%.1f, y 0..%.1f m): X and Y are "
                      "metres east and north of the map's south-west sample",
                      map.extentX(), map.extentY());
        throw ig::InputError("--start '" + text + "': " + buf);
    }
    const double ground = map.surfaceHeight(p.position.x, p.position.y);
    if (!(p.position.z >= ground + 1.0)) {
        throw ig::InputError("--start '" + text + "': Z " + base::number(p.position.z) +
                             " m is not above the terrain there (ground at " +
                             base::number(ground) +
                             " m); write Z as +H for H metres above the ground");
    }
    sim::FlightState s;
    s.position = p.position;
    s.heading = p.yaw;
    s.speed = limits.cruiseSpeed;
    return s;
}

// --field-log: the stick as the flight last sampled it (the field loop samples it while it
// advances the flight to a field's instant).
class RecordingStick final : public io::StickInput {
  public:
    explicit RecordingStick(std::unique_ptr<io::StickInput> inner)
        : inner_(std::move(inner)), gpio_(dynamic_cast<const io::GpioStick*>(inner_.get())) {}
    io::StickState sample(double t) override {
        last_ = inner_->sample(t);
        return last_;
    }
    const io::StickState& last() const { return last_; }
    // Edges read from the chip so far (before debouncing); null for a scripted stick.
    std::optional<std::uint64_t> edges() const {
        return gpio_ ? std::optional<std::uint64_t>(gpio_->edgesSeen()) : std::nullopt;
    }

  private:
    std::unique_ptr<io::StickInput> inner_;
    const io::GpioStick* gpio_;
    io::StickState last_;
};

// --field-log: the pose of the last field instant the flight was advanced to, which is the
// pose the field is warped to (predictions for the renderer pass through untouched).
class RecordingPoses final : public sim::PoseSource {
  public:
    explicit RecordingPoses(std::unique_ptr<sim::PoseSource> inner) : inner_(std::move(inner)) {}
    ig::Pose advanceTo(double t) override {
        last_ = inner_->advanceTo(t);
        return last_;
    }
    ig::Pose predict(double t) override { return inner_->predict(t); }
    double startTime() const override { return inner_->startTime(); }
    const ig::Pose& last() const { return last_; }

  private:
    std::unique_ptr<sim::PoseSource> inner_;
    ig::Pose last_;
};

// One JSON line per field: index, instant, the pose it was warped to, the stick sampled for it
// (null without a stick; a gpiod stick adds the edges read from the chip so far), the frame it
// came from and that frame's age.
std::string fieldLogLine(const prp::Field& field, const ig::Pose& pose,
                         const RecordingStick* stick) {
    nlohmann::json j;
    j["field"] = field.index;
    j["time_s"] = field.time;
    j["pose"] = {{"x", pose.position.x},
                 {"y", pose.position.y},
                 {"z", pose.position.z},
                 {"yaw_deg", ig::radToDeg(pose.yaw)},
                 {"pitch_deg", ig::radToDeg(pose.pitch)},
                 {"roll_deg", ig::radToDeg(pose.roll)}};
    if (stick) {
        const io::StickState& s = stick->last();
        j["stick"] = {{"pitch", s.pitch},
                      {"roll", s.roll},
                      {"yaw", s.yaw},
                      {"throttle", s.throttle},
                      {"trigger", s.trigger}};
        if (const auto edges = stick->edges()) j["stick"]["edges"] = *edges;
    } else {
        j["stick"] = nullptr;
    }
    j["frame"] = field.frameSequence;
    j["frame_age_ms"] = field.frameAge * 1e3;
    j["warp"] = std::string(prp::warpModelName(field.warp.model));
    return j.dump() + "\n";
}

}  // namespace

// What paging a database did over the run (sim::PagingLog, written by the renderer's thread or
// process), for the summary and --json.
nlohmann::json pagingSummary(const sim::PagingLog& pagingLog, double cacheMb,
                             bool rendererProcess) {
    const std::vector<sim::PagingLog::Frame> frames = pagingLog.frames();
    nlohmann::json j;
    j["budget_mb"] = cacheMb;
    j["frames"] = frames.size();
    j["frames_not_kept"] = pagingLog.dropped();
    j["in_renderer_process"] = rendererProcess;
    std::size_t substituted = 0, withSub = 0, withSubLate = 0, maxSub = 0, failed = 0;
    double pageSum = 0.0, pageMax = 0.0, detailSum = 0.0, detailMin = 1.0;
    std::size_t reduced = 0;
    std::uint64_t rendererPeak = 0;
    const double t0 = frames.empty() ? 0.0 : frames.front().time;
    for (const sim::PagingLog::Frame& f : frames) {
        detailSum += f.detail;
        detailMin = std::min(detailMin, f.detail);
        reduced += f.detail < 1.0;
        substituted += f.substituted;
        withSub += f.substituted > 0;
        withSubLate += f.substituted > 0 && f.time >= t0 + 1.0;
        maxSub = std::max<std::size_t>(maxSub, f.substituted);
        failed += f.failed;
        pageSum += f.pageMs;
        pageMax = std::max(pageMax, f.pageMs);
        rendererPeak = std::max(rendererPeak, f.peakRssBytes);
    }
    const double span = frames.size() > 1 ? frames.back().time - t0 : 0.0;
    const std::uint64_t read = frames.empty() ? 0 : frames.back().tilesRead;
    j["substituted_tiles"] = substituted;
    j["frames_with_substitutions"] = withSub;
    j["frames_with_substitutions_after_1s"] = withSubLate;
    j["max_substituted_per_frame"] = maxSub;
    j["mean_substituted_per_frame"] =
        frames.empty() ? 0.0 : static_cast<double>(substituted) / frames.size();
    j["failed_tiles"] = failed;
    std::vector<double> late;  // the instants of frames with substitutions after the first second
    for (const sim::PagingLog::Frame& f : frames)
        if (f.substituted > 0 && f.time >= t0 + 1.0) late.push_back(f.time);
    j["substitution_times_after_1s"] = late;
    j["tiles_read"] = read;
    j["bytes_read"] = frames.empty() ? 0 : frames.back().bytesRead;
    j["tiles_read_per_s"] = span > 0.0 ? static_cast<double>(read) / span : 0.0;
    j["page_ms_mean"] = frames.empty() ? 0.0 : pageSum / frames.size();
    j["page_ms_max"] = pageMax;
    // Frames drawn at lower detail to keep the placing in its budget (--place-budget-ms).
    j["frames_reduced_detail"] = reduced;
    j["detail_min"] = detailMin;
    j["detail_mean"] = frames.empty() ? 1.0 : detailSum / frames.size();
    // Resident memory: the field process's peak, and a renderer process's (each restart's own:
    // they do not overlap) on top of it. The two count the pages they shared since the fork
    // twice, so their sum is an upper bound.
    const double fieldPeak = static_cast<double>(ig::peakResidentBytes()) / 1048576.0;
    const double rendererPeakMb = static_cast<double>(rendererPeak) / 1048576.0;
    j["peak_rss_mb"] = rendererProcess ? fieldPeak + rendererPeakMb : fieldPeak;
    j["field_process_peak_rss_mb"] = fieldPeak;
    j["renderer_process_peak_rss_mb"] = rendererProcess ? rendererPeakMb : 0.0;
    // The renderer's longest silence in each frame (between two signs of life, which is what
    // the supervisor's silence rule sees): the longest of the run and where it fell, and the
    // frames with one over 100 ms by the steps it lay between. A process's first frame, which
    // waits for its tiles under the start allowance, apart.
    std::vector<double> silences;
    const sim::PagingLog::Frame* longest = nullptr;
    std::map<std::string, std::pair<std::size_t, double>> longSilences;  // frames, longest
    std::int32_t pid = 0;
    for (const sim::PagingLog::Frame& f : frames) {
        if (std::exchange(pid, f.pid) != f.pid) continue;
        silences.push_back(f.silenceMs);
        if (!longest || f.silenceMs > longest->silenceMs) longest = &f;
        if (f.silenceMs > 100.0) {
            auto& [count, ms] = longSilences[std::string(sim::renderStepName(f.silenceAfter)) +
                                             " -> " + sim::renderStepName(f.silenceUntil)];
            ++count;
            ms = std::max(ms, f.silenceMs);
        }
    }
    j["renderer_silence_ms_p99"] = silences.empty() ? 0.0 : sim::percentiles(silences).p99;
    j["renderer_silence_ms_max"] = longest ? longest->silenceMs : 0.0;
    j["renderer_silence_max_between"] =
        longest ? std::string(sim::renderStepName(longest->silenceAfter)) + " -> " +
                      sim::renderStepName(longest->silenceUntil)
                : std::string();
    j["renderer_silence_max_time"] = longest ? longest->time : 0.0;
    nlohmann::json over = nlohmann::json::object();
    for (const auto& [between, counted] : longSilences)
        over[between] = {{"frames", counted.first}, {"max_ms", counted.second}};
    j["renderer_silences_over_100ms"] = over;
    // The renderer's largest resident set after a frame, and what it held then.
    const sim::PagingLog::Frame* fullest = nullptr;
    for (const sim::PagingLog::Frame& f : frames)
        if (!fullest || f.rssBytes > fullest->rssBytes) fullest = &f;
    if (fullest) {
        const double mb = 1.0 / 1048576.0;
        const double rssMb = static_cast<double>(fullest->rssBytes) * mb;
        const double tilesMb = static_cast<double>(fullest->cacheBytes) * mb;
        const double mapMb = static_cast<double>(fullest->mapBytes) * mb;
        j["renderer_fullest_frame"] = {{"time_s", fullest->time},
                                       {"rss_mb", rssMb},
                                       {"tile_cache_mb", tilesMb},
                                       {"map_pages_held_mb", mapMb},
                                       {"rest_mb", rssMb - tilesMb - mapMb}};
    }
    return j;
}

int main(int argc, char** argv) {
    CLI::App app{
        "Fly over a voxel terrain in real time: render, warp every NTSC field to its own "
        "instant, and write interlaced video."};
    app.footer(kNotes);
    ig::TerrainOptions terrain;
    ig::addTerrainOptions(app, terrain);
    // Haze at a quarter of the map's extent and the lit colour ramp: the map's far edge fades
    // into the horizon (docs/design/appearance.md).
    ig::AppearanceOptions look;
    look.haze = "auto";
    look.colors = "auto";
    ig::addAppearanceOptions(app, look);
    ig::InsetOptions insets;
    ig::addInsetOptions(app, insets);
    std::string trajectoryPath, stickSpec, startText;
    std::optional<double> duration;
    double renderHz = 0.0;
    std::string outSpec = kDefaultOut;
    std::string contactPath = kDefaultContact;
    std::string sizeText = "720x486";
    std::string formatText = "uyvy";
    std::string warpText = "auto";
    double autoThreshold = 0.25;
    double autoDepthBudgetMs = 10.0;
    std::string clockText = "wall";
    std::string jsonPath, fieldLogPath;
    double fovDeg = 60.0;
    int margin = 48;
    int renderThreads = 0;
    std::string rendererText = "process";
    std::optional<double> stereoSeparation;
    std::string stereoLayoutText = "sbs";
    double renderTimeoutMs = 0.0, holdAfterMs = 1000.0;
    double prefetchSeconds = 0.5;
    int tileLoaders = 2;
    double placeBudgetMs = 60.0;
    double minDetail = 0.5;
    std::string faultText;
    std::string levelsText = "auto";
    std::string casterText = "fast";
    bool agc = false, antiTwitter = false, quiet = false, fixedMargin = false, noRestamp = false;
    bool terrainPointsOnly = false, overwrite = false;
    std::string edgeFillText = "sky";
    std::string cigiBind, cigiHost, cigiOrigin;
    double cigiWait = 0.0, cigiTimeout = 0.5, cigiExtrapolate = 2.0;
    int cigiView = 0;
    std::vector<std::string> cigiEntities;
    std::string scenePath, truthPath;

    auto* trajectoryOpt =
        app.add_option("--trajectory", trajectoryPath, "Fly a CSV trajectory instead of a stick");
    app.add_option("--stick", stickSpec, "script:FILE | gpiod:CHIP:OFFSETS[:active-low]")
        ->excludes(trajectoryOpt);
    app.add_option("--start", startText, "Stick flight start X,Y,Z,HEADING (metres, degrees)")
        ->excludes(trajectoryOpt);
    app.add_option("--cigi", cigiBind,
                   "Be driven by a CIGI 3.3 host: receive its UDP messages on [ADDR:]PORT (0: any "
                   "free port)")
        ->excludes(trajectoryOpt);
    app.add_option("--cigi-host", cigiHost, "CIGI: send Start of Frame to ADDR:PORT");
    app.add_option("--cigi-wait", cigiWait,
                   "CIGI: before the first field, wait up to this many seconds for the host's "
                   "first Entity Control, sending Start of Frame meanwhile (0: start at once)")
        ->capture_default_str();
    app.add_option("--cigi-view", cigiView, "CIGI: the view id this image generator shows")
        ->capture_default_str();
    app.add_option("--cigi-timeout", cigiTimeout,
                   "CIGI: seconds without a good message before the host is reported lost")
        ->capture_default_str();
    app.add_option("--cigi-extrapolate", cigiExtrapolate,
                   "CIGI: seconds after the host's last message the ownship keeps moving at its "
                   "last rates before it holds")
        ->capture_default_str();
    app.add_option("--cigi-entity", cigiEntities,
                   "CIGI: draw host entities of TYPE as the scene's MODEL (TYPE=MODEL[:SCALE], "
                   "repeatable; needs --scene)");
    app.add_option("--cigi-origin", cigiOrigin,
                   "CIGI: LAT,LON[,ALT] of the map's south-west sample at height 0 (degrees, "
                   "metres); default: from the map's georeference (a georeferenced raster or "
                   "database), at altitude 0");
    app.add_option("--duration", duration,
                   "Seconds to fly (default: the scenario's 10 s, or the trajectory's span)");
    app.add_option("--render-hz", renderHz, "Cap on the render rate (0: as fast as it can)")
        ->capture_default_str();
    app.add_option("--out", outSpec, "y4m:PATH | v4l2:/dev/videoN | png:DIR[:EVERY_N] | null")
        ->capture_default_str();
    app.add_option("--contact", contactPath, "Contact sheet PNG ('none': no sheet)")
        ->capture_default_str();
    app.add_option("--size", sizeText,
                   "Output frame WxH, 1..8192 x 2..8192, even width for uyvy (NTSC: 720x486 or "
                   "720x480)")
        ->capture_default_str();
    app.add_option("--format", formatText, "Output pixels: uyvy | y8 | rgb8")
        ->capture_default_str();
    app.add_option("--warp", warpText,
                   "auto | poly | affine | homography | depth | hold (auto: the quadratic, or the "
                   "depth warp on fields where the quadratic misses its check points by more than "
                   "--auto-threshold)")
        ->capture_default_str();
    app.add_option("--stereo", stereoSeparation,
                   "Stereo: eye separation in metres (centred on the aircraft); --size is per "
                   "eye");
    app.add_option("--stereo-layout", stereoLayoutText,
                   "Stereo output: sbs (side by side, 2W x H) | tb (top-bottom, W x 2H) | "
                   "anaglyph (red-cyan preview, W x H)")
        ->capture_default_str();
    app.add_option("--auto-threshold", autoThreshold,
                   "Auto warp: largest check-point error of the quadratic, rendered pixels")
        ->capture_default_str();
    app.add_option("--auto-depth-budget-ms", autoDepthBudgetMs,
                   "Auto warp, wall clock: the depth model's time per field beyond which the "
                   "quadratic warps the fields that wanted it (0: no limit)")
        ->capture_default_str();
    app.add_option("--clock", clockText, "wall | simulated")->capture_default_str();
    app.add_option("--json", jsonPath, "Write the run's statistics as JSON ('-': stdout)");
    app.add_option("--field-log", fieldLogPath,
                   "Write one JSON line per field as it goes out: index, time, the pose it is "
                   "warped to, the stick sampled for it, its frame");
    app.add_option("--fov", fovDeg, "Horizontal field of view, degrees")->capture_default_str();
    app.add_option("--margin", margin, "Pixels rendered beyond the window on every side")
        ->capture_default_str();
    app.add_flag("--fixed-margin", fixedMargin,
                 "Keep --margin as it is (default: widen it with the roll so the rolled window "
                 "stays inside the rendered frame)");
    app.add_option("--render-threads", renderThreads,
                   "Renderer worker threads (0: every core for a renderer process; all cores but "
                   "one, which the field loop keeps, for a renderer thread)")
        ->capture_default_str();
    app.add_option("--renderer", rendererText,
                   "process (its own process, restarted if it crashes, hangs or sends garbage) "
                   "| thread (a thread of the field process)")
        ->capture_default_str();
    app.add_option("--prefetch-s", prefetchSeconds,
                   "With a database paged beyond --cache-mb: how far ahead along the motion and "
                   "the turn the renderer prefetches tiles, seconds (0..10)")
        ->capture_default_str();
    app.add_option("--tile-loaders", tileLoaders,
                   "With a database paged beyond --cache-mb: the renderer's threads reading "
                   "tiles (1..16)")
        ->capture_default_str();
    app.add_option("--place-budget-ms", placeBudgetMs,
                   "With a database paged beyond --cache-mb: where writing a frame's tiles into "
                   "the map would take longer than this, the frame is drawn at lower detail "
                   "(coarser levels nearer, fewer level-0 tiles), down to --min-detail; "
                   "0: always full detail")
        ->capture_default_str();
    app.add_option("--min-detail", minDetail,
                   "With --place-budget-ms: the lowest detail, as a fraction of the focal length "
                   "the levels are chosen by (0.25..1)")
        ->capture_default_str();
    app.add_option("--render-timeout-ms", renderTimeoutMs,
                   "Renderer process silent this long is killed and restarted (0: 500 ms, on "
                   "the simulated clock 5 s, or eight renders, whichever is longer; a restarted "
                   "renderer gets ten times that for its first frame, the first renderer of the "
                   "run at least 30 s, over a paged --db 60 s)")
        ->capture_default_str();
    app.add_option("--hold-after-ms", holdAfterMs,
                   "Fields extrapolate a frame's motion up to this age, then hold it (0: never)")
        ->capture_default_str();
    app.add_option("--inject-renderer-fault", faultText,
                   "Test a renderer failure once: crash@T | segv@T | exception@T | hang@T | "
                   "stall@T:MS | garbage@T (T seconds into the run; renderer process only)");
    app.add_option("--caster", casterText,
                   "Renderer: fast (per-ray column caster) | span (per terrain sample; steep "
                   "frames by the fast caster) | naive | reference (exact per-pixel casters, "
                   "slow: small sizes)")
        ->capture_default_str();
    app.add_option("--levels", levelsText,
                   "Renderer: coarser levels where a voxel shrinks below a pixel, auto (the "
                   "multiresolution caster) | 0 (single level, exact)")
        ->capture_default_str();
    app.add_option("--scene", scenePath,
                   "Scene file (JSON): voxel objects over the terrain, moving ones stamped at "
                   "each frame's instant (every caster)");
    app.add_option("--truth", truthPath,
                   "Per-field ground truth of the scene's objects, JSON lines (needs --scene)");
    app.add_flag("--no-restamp", noRestamp,
                 "Leave the scene's moving objects where each frame shows them (default: each "
                 "field re-stamps them where they are at the field's instant)");
    app.add_flag("--terrain-points-only", terrainPointsOnly,
                 "Fit the warp to terrain control points only (default: sky directions too)");
    app.add_option("--edge-fill", edgeFillText,
                   "Where a field samples beyond the rendered frame: sky (the sky colour above "
                   "the horizon, the edge pixel below) | sky-haze (the haze colour below) | "
                   "repeat (the edge pixel)")
        ->capture_default_str();
    app.add_flag("--agc", agc, "Automatic gain control");
    app.add_flag("--anti-twitter", antiTwitter, "Vertical filter against interlace twitter");
    app.add_flag("--quiet", quiet, "No progress line");
    app.add_flag("--overwrite", overwrite,
                 "png:DIR may be a folder that is not empty (its frames are replaced)");
    CLI11_PARSE(app, argc, argv);

    std::unique_ptr<io::FrameSink> sink;
    return ig::runProgram("flythrough", [&]() -> int {
        // SIGINT/SIGTERM, from here on (loading included), end the run after the field in
        // hand; the outputs are finished below.
        io::installStopSignals();
        // Flags first, so a mistake is reported before anything is loaded or opened.
        if (duration && !(*duration > 0.0 && *duration <= 86400.0)) {
            throw ig::InputError("--duration: must be more than 0 and at most 86400 seconds");
        }
        if (!(renderHz == 0.0 || (renderHz >= 0.01 && renderHz <= 1000.0))) {
            throw ig::InputError("--render-hz " + base::number(renderHz) +
                                 ": must be 0 (uncapped) or 0.01 .. 1000");
        }
        if (!(fovDeg > 0.0 && fovDeg < 179.0)) {
            throw ig::InputError("--fov: must be between 0 and 179 degrees");
        }
        if (margin < 0 || margin > 2048) throw ig::InputError("--margin: must be 0..2048 pixels");
        if (renderThreads < 0 || renderThreads > 1024) {
            throw ig::InputError("--render-threads: must be 0..1024");
        }
        if (rendererText != "process" && rendererText != "thread") {
            throw ig::InputError("--renderer " + base::quoted(rendererText) +
                                 ": expected process or thread");
        }
        std::optional<sim::StereoOutput> stereo;
        if (stereoSeparation) {
            if (!(std::isfinite(*stereoSeparation) && *stereoSeparation >= 0.0 &&
                  *stereoSeparation <= 1000.0)) {
                throw ig::InputError("--stereo " + base::number(*stereoSeparation) +
                                     ": eye separation must be 0..1000 metres");
            }
            const std::optional<sim::StereoLayout> layout =
                sim::parseStereoLayout(stereoLayoutText);
            if (!layout) {
                throw ig::InputError("--stereo-layout " + base::quoted(stereoLayoutText) +
                                     ": expected sbs, tb or anaglyph");
            }
            stereo = sim::StereoOutput{*stereoSeparation, *layout};
        } else if (app.count("--stereo-layout") > 0) {
            throw ig::InputError("--stereo-layout needs --stereo SEPARATION_M");
        }
        const bool rendererProcess = rendererText == "process";
        if (!(renderTimeoutMs >= 0.0 && renderTimeoutMs <= 600000.0)) {
            throw ig::InputError("--render-timeout-ms " + base::number(renderTimeoutMs) +
                                 ": must be 0 (automatic) .. 600000");
        }
        if (tileLoaders < 1 || tileLoaders > 16) {
            throw ig::InputError("--tile-loaders " + std::to_string(tileLoaders) +
                                 ": expected 1..16 threads");
        }
        if (!(placeBudgetMs >= 0.0 && placeBudgetMs <= 60000.0)) {
            throw ig::InputError("--place-budget-ms " + base::number(placeBudgetMs) +
                                 ": must be 0 (always full detail) .. 60000");
        }
        if (!(minDetail >= 0.25 && minDetail <= 1.0)) {
            throw ig::InputError("--min-detail " + base::number(minDetail) + ": must be 0.25..1");
        }
        if (!(prefetchSeconds >= 0.0 && prefetchSeconds <= 10.0)) {
            throw ig::InputError("--prefetch-s " + base::number(prefetchSeconds) +
                                 ": must be 0..10 seconds");
        }
        if (!(holdAfterMs >= 0.0 && holdAfterMs <= 3600000.0)) {
            throw ig::InputError("--hold-after-ms " + base::number(holdAfterMs) +
                                 ": must be 0 (never) .. 3600000");
        }
        // CIGI: every flag checked before anything is loaded.
        const bool cigi = !cigiBind.empty();
        sim::CigiOptions cigiOptions;
        if (cigi) {
            if (!stickSpec.empty()) throw ig::InputError("--cigi: cannot be used with --stick");
            if (const std::string bad =
                    io::parseUdpEndpoint(cigiBind, true, true, cigiOptions.bind);
                !bad.empty()) {
                throw ig::InputError("--cigi " + base::quoted(cigiBind) + ": " + bad +
                                     " (expected [ADDR:]PORT)");
            }
            if (cigiHost.empty()) {
                throw ig::InputError("--cigi-host: needed with --cigi (ADDR:PORT of the host)");
            }
            if (const std::string bad =
                    io::parseUdpEndpoint(cigiHost, false, false, cigiOptions.host);
                !bad.empty()) {
                throw ig::InputError("--cigi-host " + base::quoted(cigiHost) + ": " + bad);
            }
            // Without --cigi-origin: the map's georeference (once it is loaded).
            if (!cigiOrigin.empty())
                cigiOptions.origin = sim::parseGeoOrigin(cigiOrigin, "--cigi-origin");
            if (cigiView < 0 || cigiView > 65535) {
                throw ig::InputError("--cigi-view " + std::to_string(cigiView) +
                                     ": must be a view id 0..65535");
            }
            if (!(cigiTimeout > 0.0 && cigiTimeout <= 3600.0)) {
                throw ig::InputError("--cigi-timeout " + base::number(cigiTimeout) +
                                     ": must be more than 0 and at most 3600 seconds");
            }
            if (!(cigiExtrapolate >= 0.0 && cigiExtrapolate <= 3600.0)) {
                throw ig::InputError("--cigi-extrapolate " + base::number(cigiExtrapolate) +
                                     ": must be 0 .. 3600 seconds");
            }
            cigiOptions.viewId = cigiView;
            cigiOptions.hostTimeout = cigiTimeout;
            cigiOptions.extrapolateLimit = cigiExtrapolate;
            if (!(cigiWait >= 0.0 && cigiWait <= 3600.0)) {
                throw ig::InputError("--cigi-wait " + base::number(cigiWait) +
                                     ": must be 0 .. 3600 seconds");
            }
        } else if (!cigiEntities.empty()) {
            throw ig::InputError("--cigi-entity: only with --cigi [ADDR:]PORT");
        } else if (!cigiHost.empty() || !cigiOrigin.empty()) {
            throw ig::InputError(std::string(cigiHost.empty() ? "--cigi-origin" : "--cigi-host") +
                                 ": only with --cigi [ADDR:]PORT");
        }
        std::optional<sim::RendererFault> fault;
        if (!faultText.empty()) {
            if (!rendererProcess) {
                throw ig::InputError("--inject-renderer-fault needs --renderer process");
            }
            fault = sim::parseRendererFault(faultText, "--inject-renderer-fault");
        }
        ig::RenderOptions renderOptions;
        renderOptions.levels = ig::parseLevels(levelsText);
        const ig::CasterKind casterKind = ig::parseCasterKind(casterText);
        if (!truthPath.empty() && scenePath.empty()) {
            throw ig::InputError("--truth: give a --scene whose objects it describes");
        }
        if (!truthPath.empty() && stereoSeparation) {
            throw ig::InputError(
                "--truth: not with --stereo (the truth describes one eye's fields)");
        }
        if (stereoSeparation && casterKind != ig::CasterKind::Fast) {
            throw ig::InputError(
                "--stereo: the stereo renderer draws the left eye with the fast "
                "caster (--caster fast)");
        }
        const auto [width, height] = ig::parseSize(sizeText);
        const std::optional<prp::PixelFormat> prpFormat = prp::parsePixelFormat(formatText);
        if (!prpFormat) {
            throw ig::InputError("--format '" + formatText + "': expected uyvy, y8 or rgb8");
        }
        const std::optional<prp::WarpModel> warp = prp::parseWarpModel(warpText);
        if (!warp) {
            throw ig::InputError("--warp '" + warpText +
                                 "': expected auto, poly, affine, homography, depth or hold");
        }
        if (!(autoThreshold > 0.0 && autoThreshold <= 1e6)) {
            throw ig::InputError("--auto-threshold: must be a positive number of pixels");
        }
        if (clockText != "wall" && clockText != "simulated") {
            throw ig::InputError("--clock '" + clockText + "': expected wall or simulated");
        }
        const bool simulated = clockText == "simulated";
        io::VideoFormat format;
        format.width = width;
        format.height = height;
        format.format = *prpFormat;
        if (stereo) {
            if (stereo->layout == sim::StereoLayout::TopBottom && height % 2 != 0) {
                throw ig::InputError("--size " + sizeText +
                                     ": top-bottom stereo needs an even height per eye");
            }
            sim::stereoOutputSize(stereo->layout, width, height, format.width, format.height);
        }
        if (const std::string bad = io::checkVideoFormat(format); !bad.empty()) {
            throw ig::InputError("--size " + sizeText + ": " + bad);
        }

        std::string error;
        sink = io::makeSink(outSpec, &error, overwrite);
        if (!sink) throw ig::InputError("--out " + error);

        // Outputs: the default paths live in ./out, created here; other paths must exist.
        if (outSpec == kDefaultOut || contactPath == kDefaultContact) {
            std::error_code ec;
            std::filesystem::create_directories("out", ec);
            if (ec) throw ig::InputError("out: cannot create the folder: " + ec.message());
        }
        // Every path of the run before anything is loaded: inputs are never overwritten, no two
        // outputs share a file, standard output carries one of them at most.
        const bool wantContact = contactPath != "none" && !contactPath.empty();
        const std::string stickFile =
            stickSpec.rfind("script:", 0) == 0 ? stickSpec.substr(7) : std::string();
        const std::vector<io::PathUse> paths = {
            {"--height", terrain.height, io::PathRole::Input},
            {"--color", terrain.color, io::PathRole::Input},
            {"--trajectory", trajectoryPath, io::PathRole::Input},
            {"--stick", stickFile, io::PathRole::Input},
            {"--out", io::sinkPath(outSpec),
             io::sinkWritesFolder(outSpec) ? io::PathRole::OutputFolder : io::PathRole::Output},
            {"--contact", wantContact ? contactPath : std::string(), io::PathRole::Output},
            {"--json", jsonPath, io::PathRole::Output},
            {"--scene", scenePath, io::PathRole::Input},
            {"--truth", truthPath, io::PathRole::Output},
            {"--field-log", fieldLogPath, io::PathRole::Output}};
        io::checkRunPaths(paths);
        // Where things went: standard output, unless an output is written there.
        std::FILE* report = io::usesStdout(paths) ? stderr : stdout;

        // A database over --cache-mb is paged by the view (ig/paged_terrain.hpp): the renderer
        // places each frame's tiles; this process holds a small paged map of its own for the
        // ground under the start and the trajectory, read before the run.
        std::optional<ig::TerrainDb> pagedDb;
        // With the database's insets (ig/paged_insets.hpp); pagedGround is its global map.
        std::unique_ptr<ig::PagedNestedTerrain> pagedNested;
        ig::PagedTerrain* pagedGround = nullptr;
        bool pagedInsets = false;
        // The flight model's ground over the insets of a paged database.
        std::unique_ptr<ig::PagedNestedGround> nestedFloor;
        // The flight model's ground over a paged map (a stick or the default scenario).
        std::unique_ptr<ig::PagedGround> fieldGround;
        // A CIGI host's height and line-of-sight queries over a paged map (a thread of their
        // own, sim/terrain_queries.hpp).
        std::unique_ptr<sim::PagedTerrainQueries> terrainQueries;
        // The ground the processor's re-stamped moving objects stand on over a paged map (it
        // follows the objects asked about).
        std::unique_ptr<ig::PagedGround> sceneGround;
        // Over a paged database's insets, their grounds over sceneGround.
        std::unique_ptr<ig::PagedNestedGround> sceneInsetGround;
        if (!terrain.db.empty()) {
            ig::checkDatabaseOptions(terrain);
            pagedDb.emplace(ig::TerrainDb::open(terrain.db));
            if (ig::databaseNeedsPaging(terrain, *pagedDb)) {
                if (casterKind == ig::CasterKind::Span) {
                    throw ig::InputError(
                        terrain.db + " is over --cache-mb and is paged: a flight " +
                        "over it takes a --trajectory, a stick, --cigi or the default scenario, " +
                        "with or without a --scene or --stereo, " +
                        "with --caster fast, naive or reference, not --caster span" +
                        " (or give a larger --cache-mb)");
                }
                ig::PagedTerrain::Options ground;
                ground.cache.budgetBytes =
                    static_cast<std::size_t>(std::min(terrain.cacheMb, 64.0) * 1048576.0);
                pagedNested = std::make_unique<ig::PagedNestedTerrain>(*pagedDb, ground);
                pagedGround = &pagedNested->global();
                pagedInsets = pagedNested->insetCount() > 0;
            } else {
                pagedDb.reset();
            }
        }
        // Insets (docs/design/insets.md): the renderer draws the nested terrain; the flight
        // model, the trajectory's clearance and the start fly over a ground on or above it.
        std::optional<ig::NestedTerrain> nested;
        // Insets from the flags, or held by a database loaded whole.
        const bool nesting = insets.any() || (!pagedGround && ig::databaseHasInsets(terrain));
        if (nesting && !insets.any()) {
            if (casterKind == ig::CasterKind::Span) {
                throw ig::InputError(terrain.db + " holds insets: not with --caster span");
            }
        }
        if (insets.any()) {
            const char* why = pagedGround ? "a --db paged beyond --cache-mb"
                              : casterKind == ig::CasterKind::Span ? "--caster span"
                                                                   : nullptr;
            if (why) throw ig::InputError(std::string("--inset: not with ") + why);
        }
        ig::TerrainMap loadedMap =
            pagedGround ? ig::TerrainMap() : ig::loadTerrainFromOptions(terrain);
        // The nested surface, where a scene's objects stand over insets held in memory.
        std::optional<ig::NestedGround> insetGround;
        // Its maps, the surface a CIGI host's queries read.
        std::optional<ig::NestedMaps> nestedMaps;
        if (nesting) {
            nested.emplace(ig::loadNestedTerrain(std::move(loadedMap), terrain, insets));
            loadedMap = nested->upperGround();
            nestedMaps.emplace(nested->maps());
            insetGround.emplace(*nestedMaps);
        }
        // The paged map is written only by pagedGround's own placing, here before the run.
        ig::TerrainMap& map =
            pagedGround ? const_cast<ig::TerrainMap&>(pagedGround->map()) : loadedMap;
        if (!cigiBind.empty() && cigiOrigin.empty()) {
            const auto geo = ig::geodeticOrigin(map.georeference());
            if (!geo) {
                throw ig::InputError(
                    "--cigi-origin: needed with --cigi over a map without a georeference "
                    "(LAT,LON[,ALT] of the map's origin)");
            }
            cigiOptions.origin.latDeg = (*geo)[0];
            cigiOptions.origin.lonDeg = (*geo)[1];
        }
        // A paged map draws the database's colours: the lit ramp needs the whole map.
        if (pagedGround && look.colors == "auto") look.colors = "image";
        const ig::Appearance appearance = ig::parseAppearance(look, terrain, map);
        if (pagedGround && (appearance.ramp || appearance.shade)) {
            throw ig::InputError(std::string(appearance.ramp ? "--colors ramp" : "--shade") +
                                 ": not with a database paged beyond --cache-mb");
        }
        if (nested) {
            ig::applyAppearance(appearance, *nested, renderOptions);
        } else {
            ig::applyAppearance(appearance, map, renderOptions);
        }
        // A ground of the field process's own over a paged map (ig/paged_ground.hpp), its tiles
        // around (x, y) loaded before the run.
        ig::PagedGround::Options groundOptions;
        groundOptions.budgetBytes =
            static_cast<std::size_t>(std::min(terrain.cacheMb, 16.0) * 1048576.0);
        const auto pagedGroundAt = [&](double x, double y) {
            auto ground = std::make_unique<ig::PagedGround>(*pagedDb, groundOptions);
            ground->waitAround(x, y);
            return ground;
        };
        // The flight model's ground over a paged map, placed around (x, y): fieldGround, and
        // over the database's insets nestedFloor on it, whose surface it returns.
        const auto pagedFloorAt = [&](double x, double y) -> const ig::Ground* {
            fieldGround = pagedGroundAt(x, y);
            if (!pagedInsets) return fieldGround.get();
            nestedFloor =
                std::make_unique<ig::PagedNestedGround>(*fieldGround, *pagedDb, groundOptions);
            nestedFloor->waitAround(x, y);
            return nestedFloor.get();
        };
        // Where the default scenario (or --start) begins; over a paged map the ground there is
        // placed first.
        const auto scenarioStart = [&](const sim::Scenario& scenario) {
            if (pagedGround) pagedGround->placeAround(0.25 * map.extentX(), 0.25 * map.extentY());
            sim::FlightState start = ig::usesShippedMap(terrain)
                                         ? scenario.start
                                         : sim::startOverMap(map, scenario.limits);
            if (!startText.empty()) {
                start = parseStart(startText, map, scenario.limits, pagedGround);
            }
            return start;
        };
        // The scene: the static layer once, the moving objects per frame (the renderer).
        std::optional<ig::Scene> scene;
        std::optional<sim::SceneMotion> motion;
        if (!scenePath.empty()) {
            // Over a paged map the placements stand on the database's ground, read tile by
            // tile as the scene asks (before the run).
            std::optional<ig::PlacingGround> placing;
            std::optional<ig::PlacingNestedGround> placingNested;
            const ig::Ground* placeOn = nullptr;
            if (pagedInsets) {
                placeOn = &placingNested.emplace(*pagedNested);
            } else if (pagedGround) {
                placeOn = &placing.emplace(*pagedGround);
            } else if (nested) {
                placeOn = &*insetGround;  // the nested surface (`map` is the upper ground)
            }
            scene.emplace(ig::loadScene(scenePath, map, true, placeOn));
            motion.emplace(*scene);
            // Over a paged map the processor's re-stamped moving objects and the truth stand on
            // a ground of the field process's own: it follows the truth's field pose, or else
            // the objects asked about. Only those read it: a static scene without truth needs
            // none.
            const bool standing =
                !scene->moving.empty() || !truthPath.empty() || !cigiEntities.empty();
            if (pagedDb && standing) {
                const std::vector<ig::Placement> at = motion->placementsAt(motion->startTime());
                sceneGround =
                    pagedGroundAt(at.empty() ? 0.0 : at.front().x, at.empty() ? 0.0 : at.front().y);
                for (std::size_t i = 1; i < at.size(); ++i)
                    sceneGround->waitAround(at[i].x, at[i].y);
                if (pagedInsets) {
                    sceneInsetGround = std::make_unique<ig::PagedNestedGround>(
                        *sceneGround, *pagedDb, groundOptions);
                    for (const ig::Placement& p : at)
                        sceneInsetGround->waitAround(p.x, p.y);
                }
            }
        }
        // The objects a CIGI host's lines of sight meet (the session's, so declared before it).
        std::optional<sim::TruthScene> lineOfSightScene;

        // Where the aircraft is: a trajectory, a stick, or the default scenario's script.
        std::unique_ptr<sim::PoseSource> poses;
        double flightSeconds = 10.0;
        std::string flightName;
        sim::CigiPoseSource* cigiSource = nullptr;
        const RecordingStick* loggedStick = nullptr;
        if (cigi) {
            const sim::Scenario scenario = sim::defaultScenario();
            const sim::FlightState start = scenarioStart(scenario);
            if (pagedGround) {
                // The ownship and the host's entities stand on a ground that follows the view;
                // HAT/HOT and lines of sight are answered on a thread of their own.
                // Over the database's insets, their surface (the queries' thread reads their
                // tiles too).
                cigiOptions.ground = pagedFloorAt(start.position.x, start.position.y);
                sim::PagedTerrainQueries::Options qo;
                qo.budgetBytes =
                    static_cast<std::size_t>(std::min(terrain.cacheMb, 64.0) * 1048576.0);
                qo.maxOutstanding = cigiOptions.maxPendingRequests + 256;
                terrainQueries = std::make_unique<sim::PagedTerrainQueries>(*pagedDb, qo);
                cigiOptions.terrainQueries = terrainQueries.get();
            } else if (nested) {
                // Over insets the ownship, the entities and the host's queries meet the nested
                // surface.
                cigiOptions.ground = &*insetGround;
                cigiOptions.surface = &*nestedMaps;
            }
            cigiOptions.startPose.position = start.position;
            cigiOptions.startPose.yaw = start.heading;
            cigiOptions.startTime = 0.0;
            cigiOptions.windowWidth = width;  // sensor gates are worked out in the output window
            cigiOptions.windowHeight = height;
            if (scene) {
                lineOfSightScene.emplace(
                    *scene, *motion,
                    nestedFloor   ? static_cast<const ig::Ground&>(*nestedFloor)
                    : fieldGround ? static_cast<const ig::Ground&>(*fieldGround)
                    : insetGround ? static_cast<const ig::Ground&>(*insetGround)
                                  : static_cast<const ig::Ground&>(map));
                cigiOptions.objects = &*lineOfSightScene;
            }
            if (!cigiEntities.empty()) {
                if (!scene) throw ig::InputError("--cigi-entity: needs a --scene with the models");
                for (const std::string& text : cigiEntities) {
                    sim::EntityTypeModel m =
                        sim::parseEntityTypeModel(text, "--cigi-entity", scene->modelNames);
                    const ig::VoxModel& grid =
                        scene->models[static_cast<std::size_t>(m.model)]->grid;
                    m.sizeX = grid.sizeX;  // the sensors' gates
                    m.sizeY = grid.sizeY;
                    m.sizeZ = grid.sizeZ;
                    cigiOptions.entityTypes.push_back(m);
                }
                for (const ig::MovingObject& m : scene->moving)
                    cigiOptions.reservedIds.push_back(m.id);
                for (const ig::PlacedObject& o : scene->staticLayer->objects())
                    cigiOptions.reservedIds.push_back(o.id);
            }
            auto source = std::make_unique<sim::CigiPoseSource>(map, cigiOptions);
            if (source->open(&error) != 0) throw ig::InputError("--cigi " + error);
            std::fprintf(stderr, "flythrough: CIGI on %s, Start of Frame to %s\n",
                         io::toString(source->session().localEndpoint()).c_str(),
                         io::toString(cigiOptions.host).c_str());
            if (cigiWait > 0.0) {
                const bool heard = source->waitForHost(cigiWait);
                std::fprintf(stderr, "flythrough: %s\n",
                             heard ? "the host's first Entity Control arrived"
                                   : "no Entity Control from the host yet: starting at the "
                                     "start pose");
            }
            flightName = "CIGI host " + io::toString(cigiOptions.host);
            flightSeconds = scenario.duration;
            cigiSource = source.get();
            poses = std::move(source);
        } else if (!trajectoryPath.empty()) {
            sim::Trajectory trajectory = sim::Trajectory::loadCsv(trajectoryPath);
            std::function<double(double, double)> ground;
            if (pagedGround) {
                // Over an inset, its surface (the nested caster's).
                ground = [&](double x, double y) {
                    pagedNested->placeAround(x, y);
                    return pagedNested->maps().surfaceHeight(x, y);
                };
            }
            sim::checkTrajectoryClearance(
                trajectory, map, trajectoryPath, 1.0, 0.05,
                duration.value_or(trajectory.endTime() - trajectory.startTime()), ground);
            flightSeconds = trajectory.endTime() - trajectory.startTime();
            flightName = "trajectory " + trajectoryPath;
            poses = std::make_unique<sim::TrajectoryPoses>(std::move(trajectory));
        } else {
            const sim::Scenario scenario = sim::defaultScenario();
            std::unique_ptr<io::StickInput> stick;
            if (stickSpec.empty()) {
                stick = io::makeScriptedStick(scenario.stickScript, "default.stick", &error);
                flightName = "default scenario";
            } else {
                stick = io::makeStick(stickSpec, &error);
                flightName = "stick " + stickSpec;
            }
            if (!stick) throw ig::InputError("--stick: " + error);
            if (!fieldLogPath.empty()) {
                auto recording = std::make_unique<RecordingStick>(std::move(stick));
                loggedStick = recording.get();
                stick = std::move(recording);
            }
            // Over a paged map the start's ground is placed first, and the flight model stands
            // on a ground of its own that follows the aircraft (ig/paged_ground.hpp).
            const sim::FlightState start = scenarioStart(scenario);
            flightSeconds = scenario.duration;
            const ig::Ground* floor = &map;
            if (pagedGround) floor = pagedFloorAt(start.position.x, start.position.y);
            poses =
                std::make_unique<sim::StickFlight>(std::move(stick), start, scenario.limits, floor);
        }
        const RecordingPoses* loggedPoses = nullptr;
        if (!fieldLogPath.empty()) {
            auto recording = std::make_unique<RecordingPoses>(std::move(poses));
            loggedPoses = recording.get();
            poses = std::move(recording);
        }
        if (duration) flightSeconds = *duration;
        if (!(flightSeconds > 0.0)) {
            throw ig::InputError("--trajectory " + trajectoryPath +
                                 ": spans no time; give --duration");
        }

        if (sink->open(format, &error) != 0) throw ig::InputError("--out " + error);
        const io::VideoFormat opened = sink->format();  // a copy: it outlives the sink

        sim::PipelineOptions options;
        options.duration = flightSeconds;
        options.clock = simulated ? sim::ClockMode::Simulated : sim::ClockMode::Wall;
        options.renderHz = renderHz;
        options.renderThreads = renderThreads;
        options.rendererMode =
            rendererProcess ? sim::RendererMode::Process : sim::RendererMode::Thread;
        options.renderTimeout = renderTimeoutMs * 1e-3;
        // A renderer process over a paged database reads its first view's tiles (and the view
        // all round) before its first frame: on a cold, slow disk, seconds.
        if (pagedDb) options.startTimeout = std::max(60.0, 10.0 * options.renderTimeout);
        options.fault = fault;
        options.prp.holdAfter = holdAfterMs * 1e-3;
        options.prp.model = *warp;
        options.prp.autoThresholdPx = autoThreshold;
        // On the wall clock only: the simulated clock has no deadline, and its choice of
        // warp stays a function of the frame and the pose (the same run to run).
        if (!(autoDepthBudgetMs >= 0.0 && autoDepthBudgetMs <= 1e6)) {
            throw ig::InputError("--auto-depth-budget-ms " + base::number(autoDepthBudgetMs) +
                                 ": must be 0 (no limit) or a positive number of ms");
        }
        options.prp.autoDepthBudget = simulated ? 0.0 : autoDepthBudgetMs * 1e-3;
        options.stereo = stereo;
        options.prp.agc = agc;
        options.prp.antiTwitter = antiTwitter;
        // Sky control points are directions: exact for the sky, and they keep a full
        // quadratic fit when the horizon is in view (terrain alone may leave too few points).
        options.prp.useSky = !terrainPointsOnly;
        // Beyond the rendered frame's edge: the casters' sky and haze colours.
        options.prp.sky = renderOptions.sky;
        const std::optional<prp::EdgeFill> edgeFill = prp::parseEdgeFill(edgeFillText);
        if (!edgeFill) {
            throw ig::InputError("--edge-fill: expected sky, sky-haze or repeat, got '" +
                                 edgeFillText + "'");
        }
        options.prp.edgeFill = *edgeFill;

        // Contact sheet: twelve woven frames spread evenly over the run (only the fields of
        // the chosen frames are woven).
        constexpr int kSheetColumns = 4, kSheetRows = 3;
        std::unique_ptr<io::ContactSheet> sheet;
        std::unique_ptr<io::FieldWeaver> weaver;
        const std::uint64_t fields =
            static_cast<std::uint64_t>(std::round(flightSeconds / prp::kFieldPeriod));
        const std::uint64_t sheetEvery = std::max<std::uint64_t>(
            1, ((fields + 1) / 2 + kSheetColumns * kSheetRows - 1) / (kSheetColumns * kSheetRows));
        if (wantContact) {
            sheet = std::make_unique<io::ContactSheet>(kSheetColumns, kSheetRows, 240);
            weaver = std::make_unique<io::FieldWeaver>(opened);
        }
        // The field log is written and flushed line by line, so a reader can follow the run.
        std::unique_ptr<std::FILE, int (*)(std::FILE*)> fieldLog(nullptr, std::fclose);
        if (!fieldLogPath.empty()) {
            fieldLog.reset(std::fopen(fieldLogPath.c_str(), "w"));
            if (!fieldLog) {
                throw ig::InputError("--field-log " + fieldLogPath + ": cannot write (" +
                                     std::strerror(errno) + ")");
            }
        }
        if (sheet || fieldLog) {
            options.onField = [&](const prp::Field& field, const io::FieldBuffer& buffer) {
                if (fieldLog) {
                    const std::string line = fieldLogLine(field, loggedPoses->last(), loggedStick);
                    std::fputs(line.c_str(), fieldLog.get());
                    std::fflush(fieldLog.get());
                }
                if (!sheet || (buffer.index / 2) % sheetEvery != 0) return;
                weaver->add(buffer, [&](const std::uint8_t* frame, std::size_t stride) {
                    sheet->offer(opened, frame, stride);
                });
            };
        }
        const bool live = !quiet && isatty(STDERR_FILENO);
        if (live) {
            options.progress = [](const std::string& line) {
                std::fprintf(stderr, "\r%s\033[K", line.c_str());
            };
        }

        // The rendered frame: the output window at --fov plus margins, square pixels. The
        // renderer's threads live in the pipeline's own arena (--render-threads).
        sim::RenderGeometry geometry;
        geometry.windowWidth = width;  // per eye
        geometry.windowHeight = height;
        geometry.hfov = ig::degToRad(fovDeg);
        if (cigiSource) {
            // The host's View Definition, when one came before the run, sets the field of view.
            if (cigiSource->session().viewHfov() > 0.0) {
                geometry.hfov = cigiSource->session().viewHfov();
                std::fprintf(stderr, "flythrough: view %d: %.3f degrees wide (View Definition)\n",
                             cigiView, ig::radToDeg(geometry.hfov));
            }
            cigiSource->session().freezeFieldOfView(geometry.hfov);
            // Its far plane is the draw distance.
            geometry.farM = cigiSource->session().viewFar();
            if (std::isfinite(geometry.farM)) {
                std::fprintf(stderr, "flythrough: view %d: drawn to %.1f m (View Definition)\n",
                             cigiView, geometry.farM);
            }
            cigiSource->session().freezeFar(geometry.farM);
            // Its near plane: nothing nearer is drawn.
            geometry.nearM = cigiSource->session().viewNear();
            if (geometry.nearM > 0.0) {
                std::fprintf(stderr,
                             "flythrough: view %d: clipped nearer than %.2f m (View "
                             "Definition)\n",
                             cigiView, geometry.nearM);
            }
            cigiSource->session().freezeNear(geometry.nearM);
        }
        geometry.margin = margin;
        geometry.coverRoll = !fixedMargin;
        const ig::Intrinsics level = sim::renderIntrinsics(geometry, ig::Pose{});
        options.maxFramePixels = sim::maxFramePixels(geometry);
        // The host's entities at each frame's instant: asked of the session on the renderer's
        // thread, or, for a renderer process, on the field thread with each request, which
        // carries them to the process (sim::requestObjects()).
        sim::ExtraObjects hostObjects;
        if (cigiSource && !cigiEntities.empty()) {
            if (options.rendererMode == sim::RendererMode::Process) {
                options.requestObjects = [cigiSource](double t,
                                                      std::vector<sim::ExtraObject>& out) {
                    cigiSource->objectsAt(t, out);
                };
                hostObjects = [](double, std::vector<sim::ExtraObject>& out) {
                    const std::span<const sim::ExtraObject> carried = sim::requestObjects();
                    out.assign(carried.begin(), carried.end());
                };
            } else {
                hostObjects = [cigiSource](double t, std::vector<sim::ExtraObject>& out) {
                    cigiSource->objectsAt(t, out);
                };
            }
        }
        std::shared_ptr<sim::PagingLog> pagingLog;
        ig::PagedTerrain::Options pagedOptions;
        if (pagedDb) {
            pagingLog = std::make_shared<sim::PagingLog>();
            pagedOptions.cache.budgetBytes = static_cast<std::size_t>(terrain.cacheMb * 1048576.0);
            pagedOptions.cache.loaderThreads = tileLoaders;
            pagedOptions.lookahead = prefetchSeconds;
            pagedOptions.placeBudgetMs = placeBudgetMs;
            pagedOptions.minDetail = minDetail;
        }
        // Over a paged map the paged renderer draws the scene or the stereo pairs (the fast
        // caster's, as in memory).
        sim::FrameRenderer renderer =
            pagedDb
                ? sim::makePagedRenderer(
                      *pagedDb, pagedOptions, geometry, stereo ? ig::CasterKind::Fast : casterKind,
                      renderOptions, pagingLog,
                      scene ? sim::PagedScene{&*scene, &*motion, hostObjects} : sim::PagedScene{},
                      stereo ? stereo->separation : 0.0)
            : stereo && scene ? sim::makeStereoSceneRenderer(
                                    map, geometry, stereo->separation, renderOptions, *scene,
                                    *motion, hostObjects, nested ? &*nested : nullptr)
            : stereo && nested
                ? sim::makeStereoRenderer(*nested, geometry, stereo->separation, renderOptions)
            : stereo ? sim::makeStereoRenderer(map, geometry, stereo->separation, renderOptions)
            : scene  ? sim::makeSceneRenderer(map, geometry, casterKind, renderOptions, *scene,
                                              *motion, hostObjects, nested ? &*nested : nullptr)
            : nested ? sim::makeNestedRenderer(*nested, geometry, casterKind, renderOptions)
                     : sim::makeCasterRenderer(map, geometry, casterKind, renderOptions);
        options.objectIds = scene.has_value();
        // The ground the processor's re-stamped objects and the truth stand on: the nested
        // surface over insets, a paged map's ground of the field process, or the map.
        const auto objectGround = [&]() -> const ig::Ground& {
            if (sceneInsetGround) return *sceneInsetGround;
            if (sceneGround) return *sceneGround;
            if (insetGround) return *insetGround;
            return map;
        };
        // Ground truth: written from a thread of its own into a file renamed into place when
        // the run is complete.
        std::optional<sim::TruthScene> truthScene;
        io::OutputFile truthFile;
        std::unique_ptr<sim::TruthWriter> truth;
        if (!truthPath.empty()) {
            if (truthFile.open(truthPath, &error) != 0) throw ig::InputError("--truth " + error);
            truthScene.emplace(*scene, *motion, objectGround());
            sim::TruthCamera camera;
            camera.window = level.window();
            camera.outWidth = opened.width;
            camera.outHeight = opened.height;
            truth = std::make_unique<sim::TruthWriter>(*truthScene, camera, truthFile.get(),
                                                       opened.width, (opened.height + 1) / 2,
                                                       simulated);
            options.truth = truth.get();
            if (cigiSource) {
                // The host's entities at each field's instant, from the session (field thread).
                options.truthObjects = [cigiSource](double t, std::vector<sim::ExtraObject>& out) {
                    cigiSource->session().objectsAt(t, out);
                };
            }
        }
        // Moving objects re-stamped at each field's instant by the processor.
        // A CIGI host's entities too, each where the session dead-reckons it at both instants.
        std::optional<sim::TruthScene> motionScene;
        std::optional<sim::ObjectMotionBetween> motionBetween;
        std::vector<sim::ExtraObject> entitiesAtFrame, entitiesAtField;
        const bool hostEntities = cigiSource && !cigiEntities.empty();
        if (scene && (!scene->moving.empty() || hostEntities) && !noRestamp) {
            motionScene.emplace(*scene, *motion, objectGround());
            motionBetween.emplace(*motionScene);
            entitiesAtFrame.reserve(sim::TruthWriter::kMaxExtraObjects);
            entitiesAtField.reserve(sim::TruthWriter::kMaxExtraObjects);
            options.objectMotion = [&motionBetween, &entitiesAtFrame, &entitiesAtField, cigiSource](
                                       double frameTime, double fieldTime) {
                if (cigiSource) {
                    cigiSource->session().objectsAt(frameTime, entitiesAtFrame);
                    cigiSource->session().objectsAt(fieldTime, entitiesAtField);
                }
                return motionBetween->between(frameTime, fieldTime, entitiesAtFrame,
                                              entitiesAtField);
            };
        }
        std::unique_ptr<io::FieldClock> clock =
            simulated ? io::makeSimulatedClock() : io::makeWallClock();

        std::fprintf(stderr,
                     "flythrough: %s over %s, %.2f s, %dx%d %s fields, renders %dx%d level%s\n",
                     flightName.c_str(), ig::describeTerrain(map).c_str(), flightSeconds,
                     opened.width, opened.height, io::pixelFormatName(opened.format), level.width,
                     level.height, geometry.coverRoll ? " (wider when banked)" : "");

        if (stereo) {
            std::fprintf(stderr, "flythrough: stereo %s, eyes %dx%d %.3f m apart (renderer %s)\n",
                         std::string(sim::stereoLayoutName(stereo->layout)).c_str(), width, height,
                         stereo->separation, rendererText.c_str());
        }
        options.stop = &io::stopFlag();
        // On the wall clock the field process keeps its memory resident: no field waits on a
        // page fault (the renderer process, forked later, does not inherit the lock).
        io::MemoryLock memoryLock;
        if (pagedDb) {
            // Locking every mapping would fault in the whole of the paged map's address range.
            memoryLock.error = "not locked: the terrain database is paged";
        } else if (!simulated) {
            memoryLock = io::lockAllMemory();
            if (!memoryLock.locked) {
                std::fprintf(stderr, "flythrough: memory not locked: %s\n",
                             memoryLock.error.c_str());
            }
        }
        sim::Pipeline pipeline(*poses, std::move(renderer), *sink, *clock, options);
        const sim::PipelineResult result = pipeline.run();
        if (live) std::fprintf(stderr, "\n");
        if (truth) {
            const std::string bad = truth->finish();
            if (!bad.empty()) throw std::runtime_error("--truth " + truthPath + ": " + bad);
        }

        // A failed run drops its output (the sink discards it); a good one is closed, and a
        // file appears only when it is complete.
        if (!result.ok()) throw std::runtime_error("--out " + outSpec + ": " + result.error);
        if (fieldLog && (std::ferror(fieldLog.get()) || std::fclose(fieldLog.release()) != 0)) {
            throw std::runtime_error("--field-log " + fieldLogPath + ": write failed");
        }
        const int closed = sink->close(&error);
        sink.reset();
        if (closed != 0) throw std::runtime_error(error);
        if (result.stopped) {
            std::fprintf(stderr, "flythrough: stopped by signal %d after %zu fields\n",
                         io::stopSignalNumber(), static_cast<std::size_t>(result.stats.fields));
        }
        std::fprintf(stderr, "%s", sim::formatSummary(result.stats).c_str());
        nlohmann::json pagingJson;
        if (pagingLog) {
            pagingJson = pagingSummary(*pagingLog, terrain.cacheMb, rendererProcess);
            std::fprintf(
                stderr,
                "paging%s: %zu frames, %zu tiles drawn from a coarser level in %zu frames "
                "(%zu after the first second), %llu tiles read (%.0f a second), placing "
                "%.2f ms mean, %.2f ms max; %zu frames at lower detail (down to %.2f); "
                "peak RSS %.0f MB%s (--cache-mb %g)\n",
                rendererProcess ? " (renderer process)" : "",
                pagingJson["frames"].get<std::size_t>(),
                pagingJson["substituted_tiles"].get<std::size_t>(),
                pagingJson["frames_with_substitutions"].get<std::size_t>(),
                pagingJson["frames_with_substitutions_after_1s"].get<std::size_t>(),
                static_cast<unsigned long long>(pagingJson["tiles_read"].get<std::uint64_t>()),
                pagingJson["tiles_read_per_s"].get<double>(),
                pagingJson["page_ms_mean"].get<double>(), pagingJson["page_ms_max"].get<double>(),
                pagingJson["frames_reduced_detail"].get<std::size_t>(),
                pagingJson["detail_min"].get<double>(), pagingJson["peak_rss_mb"].get<double>(),
                rendererProcess ? " (field and renderer processes)" : "", terrain.cacheMb);
            std::fprintf(stderr,
                         "paging: the renderer's longest silence %.0f ms (%s, t = %.2f s; "
                         "first frames apart), p99 of frames %.0f ms\n",
                         pagingJson["renderer_silence_ms_max"].get<double>(),
                         pagingJson["renderer_silence_max_between"].get<std::string>().c_str(),
                         pagingJson["renderer_silence_max_time"].get<double>(),
                         pagingJson["renderer_silence_ms_p99"].get<double>());
            for (const std::string& m : pagingLog->failures())
                std::fprintf(stderr, "paging: %s (drawn from a coarser level)\n", m.c_str());
            if (fieldGround) {
                // The flight model's ground: its answers from a resident tile, and the bounds
                // it gave where the tile was not (yet) resident.
                const ig::PagedGround::Stats g = fieldGround->stats();
                pagingJson["ground"] = {{"exact", g.exact},
                                        {"bounded", g.bounded},
                                        {"outside", g.outside},
                                        {"tiles_read", fieldGround->cache().stats().tilesRead}};
                std::fprintf(stderr,
                             "paging: the flight model's ground: %llu answers from its tiles, "
                             "%llu bounds where a tile was not resident\n",
                             static_cast<unsigned long long>(g.exact),
                             static_cast<unsigned long long>(g.bounded + g.outside));
            }
            if (terrainQueries) {
                const sim::PagedTerrainQueries::Stats q = terrainQueries->stats();
                pagingJson["host_queries"] = {
                    {"asked", q.asked},          {"answered", q.answered},
                    {"unknown", q.unknown},      {"refused", q.refused},
                    {"tiles_read", q.tilesRead}, {"max_answer_ms", q.maxAnswerMs}};
            }
        }
        if (cigiSource) {
            const sim::CigiStats& c = cigiSource->session().stats();
            std::fprintf(stderr,
                         "cigi: %llu datagrams (%llu refused), %llu entity and %llu rate updates, "
                         "%llu answers, %llu Start of Frame sent (%llu send errors), last host "
                         "frame %u, %llu poses lifted above the terrain\n",
                         static_cast<unsigned long long>(c.datagrams),
                         static_cast<unsigned long long>(c.badDatagrams),
                         static_cast<unsigned long long>(c.entityUpdates),
                         static_cast<unsigned long long>(c.rateUpdates),
                         static_cast<unsigned long long>(c.answers),
                         static_cast<unsigned long long>(c.framesSent),
                         static_cast<unsigned long long>(c.sendErrors), c.lastHostFrame,
                         static_cast<unsigned long long>(c.clampedPoses));
            if (c.droppedByKernel > 0 || c.cappedPolls > 0) {
                std::fprintf(stderr,
                             "cigi: flooded: %llu datagrams dropped by the kernel, %llu fields "
                             "took their maximum, longest poll %.2f ms\n",
                             static_cast<unsigned long long>(c.droppedByKernel),
                             static_cast<unsigned long long>(c.cappedPolls), c.maxPollMs);
            }
            if (terrainQueries) {
                const sim::PagedTerrainQueries::Stats q = terrainQueries->stats();
                std::fprintf(stderr,
                             "cigi: over the paged map, %llu answers waited for their tiles "
                             "(at most %llu fields, %.1f ms), %llu with a tile unreadable; "
                             "%llu tiles read; the ownship's ground: %llu answers from its "
                             "tiles, %llu bounds\n",
                             static_cast<unsigned long long>(c.deferredAnswers),
                             static_cast<unsigned long long>(c.maxAnswerFields), q.maxAnswerMs,
                             static_cast<unsigned long long>(c.unknownTerrain),
                             static_cast<unsigned long long>(q.tilesRead),
                             static_cast<unsigned long long>(fieldGround->stats().exact),
                             static_cast<unsigned long long>(fieldGround->stats().bounded +
                                                             fieldGround->stats().outside));
            }
            for (const sim::HostOutage& o : c.outages) {
                std::fprintf(stderr,
                             "cigi: host silent from %.3f s for %.3f s%s (%llu fields "
                             "extrapolated, %llu held)\n",
                             o.lastMessage, o.length, o.ongoing ? " to the end" : "",
                             static_cast<unsigned long long>(o.fieldsExtrapolated),
                             static_cast<unsigned long long>(o.fieldsHeld));
            }
            for (const std::string& e : c.firstErrors) {
                std::fprintf(stderr, "cigi: %s\n", e.c_str());
            }
        }
        const std::string videoPath = io::sinkPath(outSpec);
        std::fprintf(report, "video: %s\n",
                     videoPath.empty() ? outSpec.c_str() : videoPath.c_str());
        if (truth) {
            if (truthFile.commit(&error) != 0) throw std::runtime_error("--truth " + error);
            std::fprintf(report, "truth: %s (%llu fields, %llu late, %llu lost)\n",
                         truthPath.c_str(), static_cast<unsigned long long>(truth->written()),
                         static_cast<unsigned long long>(truth->late()),
                         static_cast<unsigned long long>(truth->lost()));
        }
        if (sheet) {
            if (sheet->write(contactPath, &error) != 0) throw std::runtime_error(error);
            std::fprintf(report, "contact sheet: %s (%d frames)\n", contactPath.c_str(),
                         sheet->count());
        }
        if (!jsonPath.empty()) {
            nlohmann::json j = sim::toJson(result.stats);
            j["output"] = outSpec;
            j["width"] = opened.width;
            j["height"] = opened.height;
            j["render_width_level"] = level.width;
            j["render_height_level"] = level.height;
            j["renderer"] = rendererText;
            j["margin"] = margin;
            j["roll_margin"] = geometry.coverRoll;
            j["warp"] = warpText;
            if (stereo) {
                j["stereo"] = {{"separation_m", stereo->separation},
                               {"layout", sim::stereoLayoutName(stereo->layout)},
                               {"eye_width", width},
                               {"eye_height", height}};
            }
            if (scene) {
                j["scene"] = {{"file", scenePath},
                              {"static_objects", scene->staticLayer->objects().size()},
                              {"moving_objects", scene->moving.size()},
                              {"caster", casterText}};
            }
            if (truth) {
                j["truth"] = {{"file", truthPath},
                              {"fields", truth->written()},
                              {"late_fields", truth->late()},
                              {"lost_fields", truth->lost()}};
            }
            j["render_hz_cap"] = renderHz;
            j["stopped_by_signal"] = result.stopped ? io::stopSignalNumber() : 0;
            if (pagingLog) j["paging"] = pagingJson;
            j["memory_locked"] = memoryLock.locked;
            j["memory_lock_error"] = memoryLock.error;
            j["memory_locked_mib"] = static_cast<double>(io::lockedBytes()) / (1 << 20);
            if (cigiSource) {
                const sim::CigiStats& c = cigiSource->session().stats();
                j["cigi"] = sim::toJson(c);
                j["cigi"]["view"] = cigiView;
                j["fov_deg"] = ig::radToDeg(geometry.hfov);
            }
            io::writeTextOutput("--json", jsonPath, j.dump(2) + "\n");
        }
        return result.stopped ? io::exitStatusForStop() : 0;
    });
}
