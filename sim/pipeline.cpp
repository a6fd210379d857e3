#include "sim/pipeline.hpp"

#include "base/check.hpp"
#include "ig/error.hpp"
#include "ig/paged_ground.hpp"
#include "ig/paged_insets.hpp"
#include "ig/shading.hpp"
#include "ig/stereo.hpp"
#include "ig/terrain_db_build.hpp"
#include "sim/stereo_output.hpp"

#include <pthread.h>
#include <sched.h>
#include <sys/resource.h>
#include <tbb/task_arena.h>
#include <tbb/task_scheduler_observer.h>
#include <time.h>
#include <unistd.h>
#include <glm/geometric.hpp>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <numbers>
#include <stdexcept>
#include <thread>

namespace sim {

// Why it is built this way (docs/design/pipeline.md has the long form):
// - The renderer publishes complete frames into a triple buffer; the field loop takes the newest
//   with one atomic exchange, so a field never waits for a frame and never sees a torn one.
// - Field slots are absolute clock times c0 + n * period (no drift from sleeping "a period").
// - The simulated clock runs the same field loop; the renderer runs inline instead of on its
//   own thread, with each render modelled as taking a fixed time, so every frame's
//   availability, and so every frame age, is reproducible.
// - Each render is aimed at the time it is expected to complete, so a fresh frame's age is
//   about zero and ages grow while the next render runs.

io::FieldBuffer toFieldBuffer(const prp::Field& field) {
    io::FieldBuffer b;
    b.index = field.index;
    b.parity = field.parity;
    b.time = field.time;
    b.data = field.pixels.data();
    b.stride = field.stride;
    b.lines = field.lines;
    return b;
}

int marginForRoll(int windowWidth, int windowHeight, double roll, double allowance, int margin) {
    // Half extents of the window rolled by phi: (W|cos| + H|sin|) / 2 and (W|sin| + H|cos|) / 2;
    // the worst phi within [|roll| - allowance, |roll| + allowance] (or any, past 90 degrees).
    const double w = windowWidth, h = windowHeight;
    const double a = std::abs(std::remainder(roll, std::numbers::pi));  // [0, pi/2]
    const double lo = std::max(a - allowance, 0.0);
    const double hi = std::min(a + allowance, std::numbers::pi / 2);
    auto need = [&](double phi) {
        const double c = std::cos(phi), s = std::sin(phi);
        return std::max(0.5 * (w * c + h * s) - 0.5 * w, 0.5 * (w * s + h * c) - 0.5 * h);
    };
    double extra = std::max(need(lo), need(hi));
    // The vertical need peaks inside the range where tan(phi) = w / h.
    const double peak = std::atan2(w, h);
    if (peak > lo && peak < hi) extra = std::max(extra, need(peak));
    const double full = 0.5 * std::hypot(w, h) - 0.5 * std::min(w, h);
    extra = std::min(extra, full);
    const int total = margin + static_cast<int>(std::ceil(std::max(extra, 0.0)));
    return (total + 7) / 8 * 8;
}

ig::Intrinsics renderIntrinsics(const RenderGeometry& geometry, const ig::Pose& pose) {
    const int margin = geometry.coverRoll
                           ? marginForRoll(geometry.windowWidth, geometry.windowHeight, pose.roll,
                                           geometry.rollAllowance, geometry.margin)
                           : geometry.margin;
    return ig::Intrinsics::fromFov(geometry.windowWidth, geometry.windowHeight, geometry.hfov,
                                   margin);
}

std::size_t maxFramePixels(const RenderGeometry& geometry) {
    // An allowance of half a turn covers every roll.
    const int margin = geometry.coverRoll
                           ? marginForRoll(geometry.windowWidth, geometry.windowHeight, 0.0,
                                           std::numbers::pi, geometry.margin)
                           : geometry.margin;
    return static_cast<std::size_t>(geometry.windowWidth + 2 * margin) *
           static_cast<std::size_t>(geometry.windowHeight + 2 * margin);
}

RenderGeometry viewed(const RenderGeometry& geometry, const RenderView& view) {
    RenderGeometry g = geometry;
    if (view.hfov > 0.0) g.hfov = view.hfov;
    if (view.farM > 0.0) g.farM = view.farM;
    if (view.nearM >= 0.0) g.nearM = view.nearM;
    return g;
}

double fieldFocal(const ig::RenderedFrame& frame, const RenderView& view) {
    if (!(view.hfov > 0.0)) return 0.0;
    // As renderIntrinsics computes it: a frame rendered with this view has this focal length
    // to the bit, so its fields warp exactly as without a view.
    return ig::Intrinsics::fromFov(frame.intrinsics.windowWidth(), frame.intrinsics.windowHeight(),
                                   view.hfov)
        .focal;
}

void clipBeyondFar(ig::RenderedFrame& frame, double farM, const ig::SkyModel& sky) {
    if (!(farM < std::numeric_limits<double>::infinity())) return;
    const ig::Camera camera(frame.pose, frame.intrinsics);
    const int w = frame.intrinsics.width, h = frame.intrinsics.height;
    const bool ids = frame.objectId.size() == frame.depth.size();
    for (int y = 0; y < h; ++y) {
        for (int x = 0; x < w; ++x) {
            const std::size_t i = static_cast<std::size_t>(y) * w + x;
            if (!(frame.depth[i] > farM) || frame.depth[i] == ig::kSkyDepth) continue;
            const glm::dvec3 d = glm::normalize(camera.rayDirection(x + 0.5, y + 0.5));
            frame.color[i] = ig::skyColor(sky, d.z);
            frame.depth[i] = ig::kSkyDepth;
            if (ids) frame.objectId[i] = 0;
        }
    }
    // A control point beyond the far plane sees the sky: its direction from the eye.
    for (ig::ControlPoint& c : frame.controlPoints) {
        if (c.world.w == 0.0) continue;
        const glm::dvec3 d = glm::dvec3(c.world) - frame.pose.position;
        if (glm::length(d) > farM) c.world = glm::dvec4(glm::normalize(d), 0.0);
    }
}

FrameRenderer makeCasterRenderer(const ig::TerrainMap& map, const RenderGeometry& geometry,
                                 ig::CasterKind kind, const ig::RenderOptions& options) {
    std::shared_ptr<const ig::Caster> caster = ig::makeCaster(kind, map, options);
    const ig::SkyModel sky = options.sky;
    return
        [caster, &map, geometry, sky](const ig::Pose& pose, double time, std::uint64_t sequence) {
            const RenderGeometry g = viewed(geometry, requestView());
            ig::Pose level = pose;
            level.roll = 0.0;  // the PRP applies roll
            ig::RenderedFrame frame = ig::renderFrame(
                *caster, map, level, renderIntrinsics(g, pose), time, sequence, g.nearM);
            clipBeyondFar(frame, g.farM, sky);
            return frame;
        };
}

FrameRenderer makeNestedRenderer(const ig::NestedTerrain& terrain, const RenderGeometry& geometry,
                                 ig::CasterKind kind, const ig::RenderOptions& options) {
    std::shared_ptr<const ig::Caster> caster = ig::makeNestedCaster(kind, terrain, options);
    const ig::SkyModel sky = options.sky;
    return [caster, &terrain, geometry, sky](const ig::Pose& pose, double time,
                                             std::uint64_t sequence) {
        const RenderGeometry g = viewed(geometry, requestView());
        ig::Pose level = pose;
        level.roll = 0.0;  // the PRP applies roll
        ig::RenderedFrame frame = ig::renderNestedFrame(
            *caster, terrain, level, renderIntrinsics(g, pose), time, sequence, g.nearM);
        clipBeyondFar(frame, g.farM, sky);
        return frame;
    };
}

FrameRenderer makePagedRenderer(const ig::TerrainDb& db, const ig::PagedTerrain::Options& paging,
                                const RenderGeometry& geometry, ig::CasterKind kind,
                                const ig::RenderOptions& options, std::shared_ptr<PagingLog> log,
                                PagedScene objects, double stereoSeparation) {
    CHECK(stereoSeparation == 0.0 || kind == ig::CasterKind::Fast)
        << "paged stereo pairs: the fast caster";
    ig::StereoOptions stereo;
    stereo.eyeSeparation = stereoSeparation;
    if (stereoSeparation > 0.0) ig::validateStereoOptions(stereo);
    ig::PagedTerrain::Options po = paging;
    po.pyramid = kind == ig::CasterKind::Fast;
    po.levels = options.levels;
    // A renderer process placing a frame's tiles for seconds is alive, not hung.
    po.progress = [](ig::PlacingStep step) {
        static_assert(static_cast<int>(RenderStep::StandIns) -
                          static_cast<int>(RenderStep::Footprint) ==
                      static_cast<int>(ig::PlacingStep::StandIns));
        noteRendererAlive(static_cast<RenderStep>(static_cast<int>(RenderStep::Footprint) +
                                                  static_cast<int>(step)));
    };
    // What one process renders with, and the last frame's pose and time (for the motion the
    // prefetch follows).
    struct State {
        pid_t pid = -1;
        // The map and the database's insets (ig/paged_insets.hpp); `paged` its global map.
        std::unique_ptr<ig::PagedNestedTerrain> nested;
        ig::PagedTerrain* paged = nullptr;
        std::shared_ptr<const ig::Caster> caster;
        ig::RenderOptions options;  // the caster's (the paged pyramid's)
        // A stereo pair with a scene: the caster draws the terrain alone, the objects are
        // drawn over both eyes afterwards with these.
        ig::RenderOptions withObjects;
        // A stereo pair's right eye over insets: each inset's passes (insetPassOptions).
        std::vector<ig::RenderOptions> insetPasses;
        // With a scene: the moving layer (replaced before each render; the caster holds its
        // address), the ground the moving objects stand on, the extra objects' scratch.
        std::shared_ptr<ig::ObjectLayer> moving;
        std::unique_ptr<ig::PagedGround> ground;
        // Over insets: their grounds over `ground` (the one the objects stand on then).
        std::unique_ptr<ig::PagedNestedGround> nestedGround;
        const ig::Ground* objectGround = nullptr;
        std::vector<ExtraObject> extra;
        bool have = false;
        ig::Pose pose;
        double time = 0.0;
    };
    auto state = std::make_shared<State>();
    const ig::SkyModel sky = options.sky;
    return [&db, po, kind, options, state, geometry, sky, log, objects, stereo](
               const ig::Pose& pose, double time, std::uint64_t sequence) {
        State& s = *state;
        noteRendererAlive(RenderStep::Request);
        (void)takeRendererSilence();  // the wait for this request is not the renderer's
        if (s.pid != ::getpid()) {
            // A forked copy's paged map and ground have no threads: left alone (never
            // destroyed, which would join them), and this process makes its own.
            s.caster.reset();
            (void)s.nested.release();
            (void)s.ground.release();
            (void)s.nestedGround.release();
            s.nested = std::make_unique<ig::PagedNestedTerrain>(db, po);
            s.paged = &s.nested->global();
            ig::RenderOptions o = options;
            o.pyramid = s.paged->pyramid();
            o.slopes = s.paged->slopes();
            if (objects.scene) {
                ig::PagedGround::Options go;
                go.budgetBytes = std::min(po.cache.budgetBytes / 8 + 1, go.budgetBytes);
                s.ground = std::make_unique<ig::PagedGround>(db, go);
                s.ground->follow(pose.position.x, pose.position.y);
                s.ground->waitAround(pose.position.x, pose.position.y);
                s.objectGround = s.ground.get();
                if (s.nested->insetCount() > 0) {
                    s.nestedGround = std::make_unique<ig::PagedNestedGround>(*s.ground, db, go);
                    s.nestedGround->follow(pose.position.x, pose.position.y);
                    s.nestedGround->waitAround(pose.position.x, pose.position.y);
                    s.objectGround = s.nestedGround.get();
                }
                s.moving = std::make_shared<ig::ObjectLayer>(
                    objects.motion->stamp(objects.motion->startTime(), s.objectGround));
                o.objects = {objects.scene->staticLayer.get(), s.moving.get()};
            }
            s.withObjects = o;
            // A pair's reprojection works on the terrain alone (ig::renderStereo).
            if (stereo.eyeSeparation > 0.0) o.objects.clear();
            s.caster = s.nested->insetCount() > 0 ? s.nested->makeCaster(kind, o)
                                                  : ig::makeCaster(kind, s.paged->map(), o);
            s.options = o;
            if (stereo.eyeSeparation > 0.0 && s.nested->insetCount() > 0) {
                s.insetPasses = ig::insetPassOptions(s.nested->maps(), s.nested->insetOptions(o));
            }
            s.pid = ::getpid();
            s.have = false;
        }
        const RenderGeometry g = viewed(geometry, requestView());
        ig::Pose level = pose;
        level.roll = 0.0;  // the PRP applies roll
        ig::Intrinsics intr = renderIntrinsics(g, pose);
        glm::dvec3 velocity(0.0);
        double yawRate = 0.0;
        if (s.have && time > s.time) {
            const double dt = time - s.time;
            velocity = (pose.position - s.pose.position) / dt;
            yawRate = std::remainder(pose.yaw - s.pose.yaw, 2.0 * std::numbers::pi) / dt;
            if (!std::isfinite(glm::dot(velocity, velocity)) || !std::isfinite(yawRate)) {
                velocity = glm::dvec3(0.0);
                yawRate = 0.0;
            }
        }
        const auto start = std::chrono::steady_clock::now();
        // A stereo pair is rendered from the left eye, and the right one is reprojected from it
        // with its holes cast: both eyes' tiles are placed.
        const bool pair = stereo.eyeSeparation > 0.0;
        const EyePoses eyes = eyePoses(level, pair ? stereo.eyeSeparation : 0.0);
        // The detail whose tiles the placing can write in its budget (full before the first
        // frame, which waits for its tiles).
        if (s.have) {
            intr.detail = s.paged->chooseDetail(ig::Camera(pair ? eyes.left : level, intr));
            noteRendererAlive(RenderStep::Detail);
        }
        const ig::Camera first(pair ? eyes.left : level, intr);
        const ig::Camera second(eyes.right, intr);
        // Before the first frame, the view all round: a turn from the start finds its tiles.
        if (!s.have) {
            s.paged->warmUp(first);
            noteRendererAlive(RenderStep::WarmUp);
        }
        const ig::PagedFrameStats st =
            s.nested->prepare(first, !s.have, velocity, yawRate, pair ? &second : nullptr);
        noteRendererAlive(RenderStep::Placed);
        const double pageMs =
            std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start)
                .count();
        s.have = true;
        s.pose = pose;
        s.time = time;
        // The frame's paging, logged once it is cast (with the renderer's longest silence).
        PagingLog::Frame logged;
        if (log) {
            ig::TileCacheStats cs = s.paged->cache().stats();
            std::size_t cacheBytes = s.paged->cache().residentBytes();
            std::size_t mapBytes = s.paged->placedBytes();
            for (std::size_t k = 0; k < s.nested->insetCount(); ++k) {
                const ig::TileCacheStats own = s.nested->inset(k).cache().stats();
                cs.tilesRead += own.tilesRead;
                cs.bytesRead += own.bytesRead;
                cacheBytes += s.nested->inset(k).cache().residentBytes();
                mapBytes += s.nested->inset(k).placedBytes();
            }
            rusage usage{};
            const bool rss = getrusage(RUSAGE_SELF, &usage) == 0;
            logged = PagingLog::Frame{
                .time = time,
                .required = st.required,
                .substituted = st.substituted,
                .failed = st.failed,
                .nodesMissing = st.nodesMissing,
                .pageMs = pageMs,
                .tilesRead = cs.tilesRead,
                .bytesRead = cs.bytesRead,
                .detail = intr.detail,
                .peakRssBytes = rss ? static_cast<std::uint64_t>(usage.ru_maxrss) * 1024 : 0,
                .cacheBytes = cacheBytes,
                .mapBytes = mapBytes,
                .pid = static_cast<std::int32_t>(s.pid)};
            for (const std::string& failure : st.failures)
                log->addFailure(failure);
        }
        const auto cast = [&] {
            noteRendererAlive(RenderStep::Cast);
            if (!log) return;
            logged.rssBytes = ig::residentBytes();
            const RendererSilence silence = takeRendererSilence();
            logged.silenceMs = silence.ms;
            logged.silenceAfter = silence.after;
            logged.silenceUntil = silence.until;
            log->add(logged);
        };
        if (objects.scene) {
            s.objectGround->follow(pose.position.x, pose.position.y);
            if (objects.extra) objects.extra(time, s.extra);
            *s.moving = objects.motion->stamp(time, s.extra, s.objectGround);
            noteRendererAlive(RenderStep::Objects);
        }
        if (pair) {
            // Over insets, both eyes on the nested surface.
            const bool nested = s.nested->insetCount() > 0;
            ig::RenderedFrame frame =
                nested ? ig::renderNestedFrame(*s.caster, s.nested->maps(), eyes.left, intr, time,
                                               sequence, g.nearM)
                       : ig::renderFrame(*s.caster, s.paged->map(), eyes.left, intr, time, sequence,
                                         g.nearM);
            std::vector<ig::RightPixelSource> source;
            ig::StereoStats stats;
            auto right = std::make_shared<ig::RenderedFrame>(
                nested ? ig::reprojectRightEye(s.nested->maps(), s.insetPasses, frame, stereo,
                                               s.options, source, stats,
                                               ig::nestedGlobalCaster(*s.caster))
                       : ig::reprojectRightEye(s.paged->map(), frame, stereo, s.options, source,
                                               stats, s.caster.get()));
            // A scene's objects over both eyes, as over a mono frame.
            const double objectsMs =
                objects.scene ? ig::drawStereoObjects(s.withObjects, frame, *right) : 0.0;
            // The view's draw distance, both eyes.
            clipBeyondFar(frame, g.farM, sky);
            clipBeyondFar(*right, g.farM, sky);
            right->sequence = sequence;
            right->time = time;
            frame.stats.renderMs += stats.rightMs + objectsMs;
            frame.right = std::move(right);
            cast();
            return frame;
        }
        ig::RenderedFrame frame =
            s.nested->insetCount() > 0
                ? ig::renderNestedFrame(*s.caster, s.nested->maps(), level, intr, time, sequence,
                                        g.nearM)
                : ig::renderFrame(*s.caster, s.paged->map(), level, intr, time, sequence, g.nearM);
        clipBeyondFar(frame, g.farM, sky);
        cast();
        return frame;
    };
}

FrameRenderer makeSceneRenderer(const ig::TerrainMap& map, const RenderGeometry& geometry,
                                ig::CasterKind kind, const ig::RenderOptions& options,
                                const ig::Scene& scene, const SceneMotion& motion,
                                ExtraObjects extra, const ig::NestedTerrain* nested) {
    // Over insets the moving objects stand on the nested surface.
    std::shared_ptr<const ig::NestedGround> ground;
    if (nested) ground = std::make_shared<const ig::NestedGround>(nested->maps());
    // The moving layer is replaced before each render; the caster holds its address.
    auto moving = std::make_shared<ig::ObjectLayer>(motion.stamp(motion.startTime(), ground.get()));
    ig::RenderOptions withObjects = options;
    withObjects.objects = {scene.staticLayer.get(), moving.get()};
    std::shared_ptr<const ig::Caster> caster =
        nested ? ig::makeNestedCaster(kind, *nested, withObjects)
               : ig::makeCaster(kind, map, withObjects);
    auto objects = std::make_shared<std::vector<ExtraObject>>();
    return [caster, moving, objects, extra, &map, &motion, geometry, withObjects, nested, ground](
               const ig::Pose& pose, double time, std::uint64_t sequence) {
        if (extra) extra(time, *objects);
        *moving = motion.stamp(time, *objects, ground.get());
        const RenderGeometry g = viewed(geometry, requestView());
        ig::Pose level = pose;
        level.roll = 0.0;  // the PRP applies roll
        const ig::Intrinsics intr = renderIntrinsics(g, pose);
        ig::RenderedFrame frame =
            nested ? ig::renderNestedFrame(*caster, *nested, level, intr, time, sequence, g.nearM)
                   : ig::renderFrame(*caster, map, level, intr, time, sequence, g.nearM);
        clipBeyondFar(frame, g.farM, withObjects.sky);
        return frame;
    };
}

namespace {

// The calling thread's CPU time, ns.
std::int64_t threadCpuNs() {
    timespec ts{};
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
    return static_cast<std::int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
}

// Lowers the priority of every thread that works in the renderer's arena, so the field loop
// gets a processor as soon as it wakes, even with the renderer using every core.
class NiceObserver final : public tbb::task_scheduler_observer {
  public:
    NiceObserver(tbb::task_arena& arena, int nice)
        : tbb::task_scheduler_observer(arena), nice_(nice) {
        if (nice_ != 0) observe(true);
    }
    ~NiceObserver() override { observe(false); }
    void on_scheduler_entry(bool) override { setNice(nice_); }
    void on_scheduler_exit(bool worker) override {
        if (worker) setNice(0);  // workers may serve other arenas later (may be refused)
    }
    static void setNice(int nice) { setpriority(PRIO_PROCESS, static_cast<id_t>(gettid()), nice); }

  private:
    int nice_;
};

// Raises the calling thread's priority for the field loop and puts it back afterwards.
class FieldPriority {
  public:
    explicit FieldPriority(bool raise) {
        if (!raise) return;
        pthread_t self = pthread_self();
        if (pthread_getschedparam(self, &oldPolicy_, &oldParam_) == 0) {
            sched_param param{};
            param.sched_priority = std::min(20, sched_get_priority_max(SCHED_FIFO));
            if (pthread_setschedparam(self, SCHED_FIFO, &param) == 0) {
                realtime_ = true;
                return;
            }
        }
        errno = 0;
        oldNice_ = getpriority(PRIO_PROCESS, static_cast<id_t>(gettid()));
        if (errno == 0 && setpriority(PRIO_PROCESS, static_cast<id_t>(gettid()), -10) == 0) {
            niced_ = true;
        }
    }
    ~FieldPriority() {
        if (realtime_) pthread_setschedparam(pthread_self(), oldPolicy_, &oldParam_);
        if (niced_) setpriority(PRIO_PROCESS, static_cast<id_t>(gettid()), oldNice_);
    }
    FieldPriority(const FieldPriority&) = delete;
    FieldPriority& operator=(const FieldPriority&) = delete;

  private:
    int oldPolicy_ = SCHED_OTHER;
    sched_param oldParam_{};
    int oldNice_ = 0;
    bool realtime_ = false, niced_ = false;
};

}  // namespace

Pipeline::Pipeline(PoseSource& poses, FrameRenderer renderer, io::FrameSink& sink,
                   io::FieldClock& clock, const PipelineOptions& options)
    : poses_(poses),
      renderer_(std::move(renderer)),
      sink_(sink),
      clock_(clock),
      options_(options),
      fieldCount_(static_cast<std::uint64_t>(
          std::max(0.0, std::round(options.duration / prp::kFieldPeriod)))) {
    truthObjects_.reserve(TruthWriter::kMaxExtraObjects);
    options_.prp.outWidth = sink.format().width;
    options_.prp.outHeight = sink.format().height;
    options_.prp.format = sink.format().format;
    if (options_.stereo) {
        // Each eye's processor makes the eye's part of the sink's frame.
        const StereoLayout layout = options_.stereo->layout;
        stereoEyeSize(layout, sink.format().width, sink.format().height, options_.prp.outWidth,
                      options_.prp.outHeight);
        int w = 0, h = 0;
        stereoOutputSize(layout, options_.prp.outWidth, options_.prp.outHeight, w, h);
        if (w != sink.format().width || h != sink.format().height ||
            (layout == StereoLayout::TopBottom && options_.prp.outHeight % 2 != 0)) {
            throw ig::InputError("stereo " + std::string(stereoLayoutName(layout)) + ": output " +
                                 std::to_string(sink.format().width) + "x" +
                                 std::to_string(sink.format().height) +
                                 " does not split into two equal eyes (top-bottom: of even "
                                 "height)");
        }
        options_.prp.format = StereoComposer(layout, options_.prp.format).eyeFormat();
    }
}

Pipeline::~Pipeline() = default;

ig::RenderedFrame Pipeline::renderAt(double poseTime, std::uint64_t sequence) {
    setRequestView(view());
    return renderer_(poses_.predict(poseTime), poseTime, sequence);
}

void Pipeline::setView(const RenderView& view) {
    viewHfov_.store(view.hfov, std::memory_order_relaxed);
    viewFar_.store(view.farM, std::memory_order_relaxed);
    viewNear_.store(view.nearM, std::memory_order_relaxed);
}

RenderView Pipeline::view() const {
    // Words read apart: a render starting while the view changes may take one part of each
    // (the next render takes all).
    return {viewHfov_.load(std::memory_order_relaxed), viewFar_.load(std::memory_order_relaxed),
            viewNear_.load(std::memory_order_relaxed)};
}

void Pipeline::publish(ig::RenderedFrame&& frame) {
    frames_.back() = std::move(frame);
    frames_.publish();
}

bool Pipeline::stopAsked() const {
    return options_.stop && options_.stop->load(std::memory_order_acquire);
}

void Pipeline::renderSleepUntil(double t) {
    constexpr double kStep = 0.05;
    for (double now = clock_.now(); now < t; now = clock_.now()) {
        if (stop_.load(std::memory_order_acquire) || stopAsked()) return;
        clock_.sleepUntil(std::min(t, now + kStep));
    }
}

void Pipeline::renderLoop() {
    // A renderer on every core starves the field loop now and then even at real-time priority
    // (stalls of up to ~100 ms were measured on 2 cores); one core is left to it by default.
    const int cores = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
    tbb::task_arena arena(options_.renderThreads > 0 ? options_.renderThreads
                                                     : std::max(1, cores - 1));
    arena.initialize();
    NiceObserver nice(arena, options_.renderNice);
    if (options_.renderNice != 0) NiceObserver::setNice(options_.renderNice);
    std::uint64_t sequence = 1;
    std::uint64_t slot = 1;
    try {
        while (!stop_.load(std::memory_order_acquire)) {
            double start = clock_.now();
            if (options_.renderHz > 0.0) {
                // Capped: renders start on a fixed grid of slots; an overrun skips to the next.
                const double period = 1.0 / options_.renderHz;
                const double behind = std::ceil((start - c0_) / period - 1e-9);
                slot = std::max<std::uint64_t>(slot,
                                               static_cast<std::uint64_t>(std::max(behind, 0.0)));
                const double at = c0_ + static_cast<double>(slot) * period;
                ++slot;
                if (at > start) {
                    renderSleepUntil(at);
                    if (stop_.load(std::memory_order_acquire) || stopAsked()) break;
                    start = clock_.now();
                }
            }
            const double poseTime = t0_ + (start - c0_) + renderEstimate_;
            ig::RenderedFrame frame;
            arena.execute([&] { frame = renderAt(poseTime, sequence); });
            if (options_.renderStall) {
                const double stall = options_.renderStall(sequence);
                if (stall > 0.0) renderSleepUntil(clock_.now() + stall);
            }
            const double took = clock_.now() - start;
            renderEstimate_ = 0.75 * renderEstimate_ + 0.25 * took;
            stats_.addFrame(took * 1e3);
            publish(std::move(frame));
            ++sequence;
        }
    } catch (...) {
        renderError_ = std::current_exception();
        renderFailed_.store(true, std::memory_order_release);
    }
    renderEndClock_ = clock_.now();
}

void Pipeline::renderSimulatedUntil(double t) {
    const double period =
        1.0 / (options_.renderHz > 0.0 ? options_.renderHz : options_.simulatedRenderHz);
    constexpr double kEps = 1e-9;
    for (;;) {
        if (pending_) {
            if (pendingCompletion_ > t + kEps) return;
            publish(std::move(pendingFrame_));
            pending_ = false;
            nextRenderStart_ = pendingCompletion_;
        }
        if (nextRenderStart_ > t + kEps) return;
        // A render starting now (simulated): aimed at its nominal completion; a stall makes
        // it late without the renderer knowing beforehand. One that could complete only after
        // the run's last field is never shown, so it is not rendered (a rate of 1e-6 Hz would
        // otherwise fly the pose source a million seconds ahead).
        const double aim = nextRenderStart_ + period;
        if (aim > runEnd_ + kEps) return;
        if (!(aim > nextRenderStart_)) return;  // times too large to step by a render period
        if (process_) {
            // The renderer process renders this one request while the simulated clock stands
            // still; a renderer that fails it costs a modelled restart, and the frame is lost.
            postRequest(poses_.predict(aim), aim, nextSequence_);
            requested_.store(nextSequence_, std::memory_order_relaxed);
            std::string why;
            Await got = awaitFrame(pendingFrame_, silenceAllowed(), why);
            while (got == Await::Frame && pendingFrame_.sequence < nextSequence_) {
                got = awaitFrame(pendingFrame_, silenceAllowed(), why);  // an older answer
            }
            ++nextSequence_;
            if (got != Await::Frame) {
                restartProcess(why);
                nextRenderStart_ = aim + std::max(options_.simulatedRestart, 0.0);
                continue;
            }
        } else {
            pendingFrame_ = renderAt(aim, nextSequence_);
            ++nextSequence_;
        }
        const double stall = options_.renderStall ? options_.renderStall(nextSequence_ - 1) : 0.0;
        pendingCompletion_ = aim + std::max(stall, 0.0);
        stats_.addFrame((pendingCompletion_ - nextRenderStart_) * 1e3);
        pending_ = true;
    }
}

double Pipeline::renderTimeout() const {
    if (options_.renderTimeout > 0.0) return options_.renderTimeout;
    // On the simulated clock no field waits on the renderer: a longer floor keeps a loaded host
    // from being taken for a hang, which would cost a modelled restart and change the run.
    const double floor =
        options_.clock == ClockMode::Simulated ? PipelineOptions::kSimulatedRenderTimeout : 0.5;
    return std::max(floor, 8.0 * renderSeconds_.load(std::memory_order_relaxed));
}

double Pipeline::startTimeout() const {
    return options_.startTimeout > 0.0 ? options_.startTimeout : 10.0 * renderTimeout();
}

double Pipeline::firstStartTimeout() const {
    return options_.startTimeout > 0.0
               ? options_.startTimeout
               : std::max(PipelineOptions::kFirstStartSeconds, startTimeout());
}

double Pipeline::silenceAllowed() const {
    return processFresh_.load(std::memory_order_acquire) ? startTimeout() : renderTimeout();
}

void Pipeline::postRequest(const ig::Pose& pose, double time, std::uint64_t sequence) {
    requestObjects_.clear();
    if (options_.requestObjects) options_.requestObjects(time, requestObjects_);
    if (!ring_->postRequest(pose, time, sequence, requestObjects_, view()) && !requestObjectsCut_) {
        requestObjectsCut_ = true;
        std::fprintf(stderr,
                     "renderer process: %zu objects in one request; only the first %zu are "
                     "drawn\n",
                     requestObjects_.size(), kMaxRequestObjects);
    }
}

void Pipeline::startProcess() {
    // A stereo ring carries both eyes of every pair; a scene's frames carry object ids.
    ring_ = std::make_unique<FrameRing>(options_.maxFramePixels, options_.stereo ? 2 : 1,
                                        options_.objectIds);
    RendererProcessOptions po;
    po.threads = options_.renderThreads;
    po.renderHz = options_.clock == ClockMode::Simulated ? 0.0 : options_.renderHz;
    po.paced = options_.clock == ClockMode::Wall;
    po.fault = options_.fault;
    // The field process's threads come first: the field loop (real-time where allowed) and, on
    // the wall clock, the truth writer, which otherwise shares the cores evenly with a renderer
    // that takes all it is given and falls behind the field clock (docs/design/objects.md,
    // "When the truth falls behind").
    po.nice = options_.renderNice != 0                              ? options_.renderNice
              : options_.truth && options_.clock == ClockMode::Wall ? kTruthRenderNice
                                                                    : 0;
    process_ = std::make_unique<RendererProcess>(renderer_, *ring_, po);
    processFresh_.store(true, std::memory_order_release);
    process_->start();
}

Pipeline::Await Pipeline::awaitFrame(ig::RenderedFrame& into, double timeout, std::string& why) {
    const std::int64_t start = io::monotonicNs();
    for (;;) {
        const FrameRing::Fetch f = ring_->fetch(into, &why);
        if (f == FrameRing::Fetch::New) {
            processFresh_.store(false, std::memory_order_release);
            return Await::Frame;
        }
        if (f == FrameRing::Fetch::Bad) {
            why = "sent a bad frame (" + why + ")";
            return Await::Bad;
        }
        if (std::optional<std::string> ended = process_->checkEnded()) {
            why = *ended;
            return Await::Ended;
        }
        const std::int64_t alive = ring_->lastAliveNs();
        const std::int64_t since = std::max(start, alive);
        const double waited = static_cast<double>(io::monotonicNs() - since) * 1e-9;
        if (waited > timeout) {
            why = silenceCause(waited, alive >= start);
            return Await::Silent;
        }
        const timespec pause{0, 200000};
        nanosleep(&pause, nullptr);
    }
}

std::string Pipeline::silenceCause(double seconds, bool afterSignOfLife, double unwatched) const {
    std::string cause = "silent for " + std::to_string(std::lround(seconds * 1e3)) + " ms";
    // Where the render fell silent: the step of its last sign of life in this frame.
    if (afterSignOfLife) cause += std::string(" after ") + renderStepName(ring_->lastAliveStep());
    if (unwatched > 0.0) {
        cause += " (and " + std::to_string(std::lround(unwatched * 1e3)) +
                 " ms more while the supervisor itself did not run)";
    }
    return cause;
}

void Pipeline::restartProcess(const std::string& cause) {
    process_->kill();
    RendererRestart r;
    r.detected = clock_.now();
    r.detectedMonotonic = static_cast<double>(io::monotonicNs()) * 1e-9;
    r.cause = cause;
    restartAfter_.store(requested_.load(std::memory_order_relaxed), std::memory_order_relaxed);
    const std::int64_t before = io::monotonicNs();
    processFresh_.store(true, std::memory_order_release);
    process_->start();
    r.startSeconds = static_cast<double>(io::monotonicNs() - before) * 1e-9;
    {
        std::lock_guard lock(restartMutex_);
        stats_.restarts().push_back(std::move(r));
    }
    restarts_.fetch_add(1, std::memory_order_release);
}

void Pipeline::superviseLoop() {
    // Wall clock: this thread takes each new frame out of the ring as soon as it is published
    // (the copy never runs on the field thread, which takes frames from the in-process mailbox
    // as from a renderer thread), and looks after the renderer process at least every 2 ms.
    // A fork costs milliseconds, so restarts happen here too, never on the field thread.
    try {
        std::string why;
        while (!stop_.load(std::memory_order_acquire)) {
            ring_->waitForPublish(ring_->published(), 0.002);
            std::string cause;
            const FrameRing::Fetch got = ring_->fetch(frames_.back(), &why);
            if (got == FrameRing::Fetch::New) {
                processFresh_.store(false, std::memory_order_release);
                const double took = frames_.back().stats.renderMs * 1e-3;
                stats_.addFrame(frames_.back().stats.renderMs);
                renderSeconds_.store(
                    0.75 * renderSeconds_.load(std::memory_order_relaxed) + 0.25 * took,
                    std::memory_order_relaxed);
                frames_.publish();
            } else if (got == FrameRing::Fetch::Bad) {
                cause = "sent a bad frame (" + why + ")";
            }
            if (cause.empty()) {
                if (std::optional<std::string> ended = process_->checkEnded()) cause = *ended;
            }
            if (cause.empty()) {
                const std::int64_t nowNs = io::monotonicNs();
                // A sign of life between frames counts (a frame whose tiles take seconds to
                // place), one from before this process started does not.
                const std::int64_t alive = ring_->lastAliveNs();
                const std::int64_t since =
                    std::max({ring_->lastPublishNs(), alive, processStartNs_});
                // The time this thread itself did not run is not counted (SilenceWatch).
                const double silent = static_cast<double>(silence_.look(nowNs, since)) * 1e-9;
                if (silent > silenceAllowed()) {
                    cause = silenceCause(silent, alive == since,
                                         static_cast<double>(silence_.unwatchedNs()) * 1e-9);
                }
            }
            if (!cause.empty()) {
                restartProcess(cause);
                processStartNs_ = io::monotonicNs();
            }
        }
    } catch (...) {
        renderError_ = std::current_exception();
        renderFailed_.store(true, std::memory_order_release);
    }
}

void Pipeline::noteFrameShown(const ig::RenderedFrame& frame, double clock) {
    if (frame.sequence == lastShownSequence_) return;
    lastShownSequence_ = frame.sequence;
    const std::uint64_t restarts = restarts_.load(std::memory_order_acquire);
    if (restarts > restartsClosed_ &&
        frame.sequence > restartAfter_.load(std::memory_order_relaxed)) {
        std::lock_guard lock(restartMutex_);
        RendererRestart& r = stats_.restarts().back();
        r.gapSeconds = clock - lastNewFrameClock_;
        r.recoverySeconds = clock - r.detected;
        r.firstFrameMonotonic = static_cast<double>(io::monotonicNs()) * 1e-9;
        r.fieldsExtrapolated = gapFields_ - gapHeld_;
        r.fieldsHeld = gapHeld_;
        restartsClosed_ = restarts;
    }
    lastNewFrameClock_ = clock;
    gapFields_ = gapHeld_ = 0;
}

void Pipeline::noteField(double frameAge) {
    ++gapFields_;
    if (options_.prp.holdAfter > 0.0 && frameAge > options_.prp.holdAfter) ++gapHeld_;
}

PipelineResult Pipeline::run() {
    PipelineResult result;
    const bool simulated = options_.clock == ClockMode::Simulated;
    const bool process = options_.rendererMode == RendererMode::Process;
    prp::PostRenderingProcessor processor(options_.prp);
    stats_.reserve(fieldCount_);
    // Stereo: the right eye's processor, the eyes' fields and the composer.
    const bool stereo = options_.stereo.has_value();
    std::optional<prp::PostRenderingProcessor> rightProcessor;
    std::optional<StereoComposer> composer;
    prp::Field leftField, rightField;
    std::uint64_t stereoDepthFields = 0;  // fields whose eyes took the depth model for rows
    if (stereo) {
        rightProcessor.emplace(options_.prp);
        composer.emplace(options_.stereo->layout, sink_.format().format);
    }

    // Frame 0 is rendered before the first slot, at the start pose, so field 0 has a frame.
    t0_ = poses_.startTime();
    runEnd_ = prp::fieldTime(t0_, fieldCount_);
    const double before = clock_.now();
    setView(poses_.view());
    if (process) {
        CHECK_GT(options_.maxFramePixels, 0u) << "a renderer process needs the largest frame size";
        startProcess();
        postRequest(poses_.predict(t0_), t0_, 0);
        std::string why;
        ig::RenderedFrame& first = frames_.back();
        // The first frame also pays for the renderer's start.
        if (awaitFrame(first, firstStartTimeout(), why) != Await::Frame) {
            throw std::runtime_error("the renderer process gave no first frame (" + why + ")");
        }
        frames_.publish();
        renderSeconds_.store(first.stats.renderMs * 1e-3, std::memory_order_relaxed);
    } else {
        publish(renderAt(t0_, 0));
    }
    frames_.fetch();
    const double firstWall = clock_.now() - before;
    stats_.addFrame(firstWall * 1e3);  // frame 0 counts among the frames rendered
    // The next renders are aimed as far ahead as frame 0's own render took. Its wall time also
    // holds what only a first frame waits for (a renderer process's start, a paged map's
    // tiles): aimed that far ahead, the first frames of a flight would show poses seconds
    // after their fields'.
    const double firstRender = frames_.front().stats.renderMs * 1e-3;
    renderEstimate_ = firstRender > 0.0 ? std::min(firstWall, firstRender) : firstWall;
    // The processors' buffers and frame 0's per-frame data, before the field clock starts.
    processor.warmUp(frames_.front());
    if (stereo && frames_.front().right) rightProcessor->warmUp(*frames_.front().right);
    c0_ = clock_.now() + (simulated ? 0.0 : options_.startDelay);
    nextRenderStart_ = t0_;
    renderStartClock_ = before;
    lastNewFrameClock_ = c0_;

    // The renderer thread (or the renderer process's supervisor) stops and is joined on every
    // way out of this function; the renderer process is stopped after it.
    struct RendererThread {
        std::atomic<bool>& stop;
        std::thread thread;
        ~RendererThread() { join(); }
        void join() {
            stop.store(true, std::memory_order_release);
            if (thread.joinable()) thread.join();
        }
    } renderer{stop_, {}};
    if (!simulated) {
        if (process) {
            processStartNs_ = io::monotonicNs();
            renderer.thread = std::thread([this] { superviseLoop(); });
        } else {
            renderer.thread = std::thread([this] { renderLoop(); });
        }
    }
    const FieldPriority priority(!simulated && options_.raiseFieldPriority);
    poses_.settle(t0_);

    prp::Field field;
    io::FieldPacer pacer(clock_, c0_);
    double nextProgress = c0_;
    std::uint64_t missed = 0;
    std::uint64_t requestSequence = 1;
    for (std::uint64_t n = 0; n < fieldCount_; ++n) {
        const double deadline = pacer.wait(n).deadline;
        const double wokeLateMs = simulated ? -1.0 : std::max(clock_.now() - deadline, 0.0) * 1e3;
        const std::int64_t wokeNs = simulated ? 0 : io::monotonicNs();
        const std::int64_t wokeCpuNs = simulated ? 0 : threadCpuNs();
        if (renderFailed_.load(std::memory_order_acquire)) break;
        if (stopAsked()) {
            result.stopped = true;
            break;
        }
        const double t = prp::fieldTime(t0_, n);
        if (simulated) renderSimulatedUntil(t);
        const ig::Pose pose = poses_.advanceTo(t);
        // The field's view from its own instant; renders asked from now on take it too.
        const RenderView fieldView = poses_.view();
        setView(fieldView);
        if (process && !simulated) {
            // Ask for the pose the next frame should show: when it will be ready, half a field
            // after this request on average.
            const double aim =
                t + renderSeconds_.load(std::memory_order_relaxed) + 0.5 * prp::kFieldPeriod;
            postRequest(poses_.predict(aim), aim, requestSequence);
            requested_.store(requestSequence++, std::memory_order_relaxed);
        }
        frames_.fetch();
        const ig::RenderedFrame& frame = frames_.front();
        noteFrameShown(frame, clock_.now());
        const double focal = fieldFocal(frame, fieldView);
        double rightWarpMs = -1.0, disparity = -1.0, firstDisparity = -1.0;
        prp::Fallback rightFallback = prp::Fallback::None;
        prp::WarpModel rightModel = prp::WarpModel::Poly;
        if (stereo) {
            if (!frame.right) {
                result.error = "stereo: frame " + std::to_string(frame.sequence) +
                               " has no right eye (the renderer is not a stereo renderer)";
                break;
            }
            // Each eye at the field instant, roll about the head; each warped by its own fit.
            const EyePoses eyes = eyePoses(pose, options_.stereo->separation);
            const std::span<const prp::ObjectMotion> motions =
                options_.objectMotion ? options_.objectMotion(frame.time, t)
                                      : std::span<const prp::ObjectMotion>{};
            processor.process(frame, eyes.left, t, n, leftField, std::nullopt, focal, motions);
            rightProcessor->process(*frame.right, eyes.right, t, n, rightField, std::nullopt, focal,
                                    motions);
            const prp::OutputGeometry geometry = prp::OutputGeometry::of(
                frame.intrinsics, options_.prp.outWidth, options_.prp.outHeight, focal);
            disparity = verticalDisparity(frame, *frame.right, leftField.warp, rightField.warp,
                                          eyes, geometry);
            firstDisparity = disparity;
            if (disparity > kMaxVerticalDisparityRows) {
                // The fits disagree on rows: the eyes warped by a quadratic take the depth
                // model, which puts every point on its own row.
                const double leftMs = leftField.warpMs, rightMs = rightField.warpMs;
                if (leftField.warp.model != prp::WarpModel::Depth) {
                    processor.process(frame, eyes.left, t, n, leftField, prp::WarpModel::Depth,
                                      focal, motions);
                    leftField.warpMs += leftMs;
                }
                if (rightField.warp.model != prp::WarpModel::Depth) {
                    rightProcessor->process(*frame.right, eyes.right, t, n, rightField,
                                            prp::WarpModel::Depth, focal, motions);
                    rightField.warpMs += rightMs;
                }
                disparity = verticalDisparity(frame, *frame.right, leftField.warp, rightField.warp,
                                              eyes, geometry);
                ++stereoDepthFields;
            }
            composer->compose(leftField, rightField, field);
            field.warpMs = leftField.warpMs;
            rightWarpMs = rightField.warpMs;
            rightFallback = rightField.warp.fallback;
            rightModel = rightField.warp.model;
        } else {
            const std::span<const prp::ObjectMotion> motions =
                options_.objectMotion ? options_.objectMotion(frame.time, t)
                                      : std::span<const prp::ObjectMotion>{};
            processor.process(frame, pose, t, n, field, std::nullopt, focal, motions);
            if (options_.truth) {
                truthObjects_.clear();
                if (options_.truthObjects) options_.truthObjects(t, truthObjects_);
                options_.truth->record(field, pose, focal, truthObjects_);
            }
        }
        noteField(field.frameAge);
        const io::FieldBuffer buffer = toFieldBuffer(field);
        const int rc = sink_.writeField(buffer);
        const double handoff = clock_.now();
        if (rc < 0) {
            result.sinkError = rc;
            result.error =
                "the output refused field " + std::to_string(n) + ": " + std::strerror(-rc);
            break;
        }
        // The time this thread was not running while it made the field (wall clock only).
        const double offCpuMs = simulated
                                    ? -1.0
                                    : std::max(static_cast<double>((io::monotonicNs() - wokeNs) -
                                                                   (threadCpuNs() - wokeCpuNs)) *
                                                   1e-6,
                                               0.0);
        stats_.addField({deadline, handoff, field.frameAge, field.warpMs, field.warp.fallback,
                         field.frameSequence, field.warp.model, field.warp.depthOverBudget,
                         field.warp.depthAbandoned, rightWarpMs, rightFallback, rightModel,
                         disparity, firstDisparity, offCpuMs, wokeLateMs});
        if (handoff > deadline + prp::kFieldPeriod) ++missed;
        if (options_.onField) options_.onField(field, buffer);
        if (options_.progress && handoff >= nextProgress) {
            nextProgress = handoff + 0.25;
            const std::size_t done = stats_.records().size();
            const double elapsed = std::max(handoff - c0_, 1e-9);
            char line[200];
            std::snprintf(line, sizeof line,
                          "field %zu/%llu  t %.2f s  missed %llu  frame age %.0f ms  "
                          "render %.1f fps  restarts %llu",
                          done, static_cast<unsigned long long>(fieldCount_), t - t0_,
                          static_cast<unsigned long long>(missed), field.frameAge * 1e3,
                          static_cast<double>(stats_.framesRendered()) / elapsed,
                          static_cast<unsigned long long>(restarts_.load()));
            options_.progress(line);
        }
    }

    renderer.join();
    if (process) {
        process_.reset();  // asks the renderer to stop; kills it if it does not
        renderEndClock_ = clock_.now();
    }
    if (renderError_) std::rethrow_exception(renderError_);
    if (simulated) renderEndClock_ = clock_.now();
    std::lock_guard lock(restartMutex_);
    result.stats = stats_.summarize(renderEndClock_ - renderStartClock_, simulated);
    result.stats.depthForRows = stereoDepthFields;
    return result;
}

}  // namespace sim
