// The real-time loop: async renderer -> latest-frame mailbox -> field loop on deadlines -> sink.
#pragma once

#include "ig/caster.hpp"
#include "ig/frame.hpp"
#include "ig/inset.hpp"
#include "ig/paged_terrain.hpp"
#include "io/field_clock.hpp"
#include "io/frame_sink.hpp"
#include "prp/processor.hpp"
#include "sim/mailbox.hpp"
#include "sim/paging_log.hpp"
#include "sim/pose_source.hpp"
#include "sim/render_process.hpp"
#include "sim/scene_motion.hpp"
#include "sim/stats.hpp"
#include "sim/stereo_output.hpp"
#include "sim/truth.hpp"

#include <atomic>
#include <cstdint>
#include <exception>
#include <functional>
#include <limits>
#include <memory>
#include <mutex>
#include <optional>
#include <string>

namespace sim {

enum class ClockMode { Wall, Simulated };
// Thread: the renderer is a thread of the field process. Process: a process of its own, started
// and supervised by the field process, restarted whenever it ends, hangs or sends garbage.
enum class RendererMode { Thread, Process };

// What the renderer renders: the output window at a horizontal field of view, with margins.
struct RenderGeometry {
    int windowWidth = 720;
    int windowHeight = 486;
    double hfov = 1.0471975511965976;  // 60 degrees
    int margin = 48;                   // for motion between a frame and its fields
    // Widen the margin with |roll| so the rolled window stays inside the frame.
    bool coverRoll = true;
    double rollAllowance = 0.05;  // radians of roll change a frame should still cover
    // Draw distance (a CIGI View Definition's far plane, metres): what lies farther is drawn
    // as sky (sim::clipBeyondFar). Infinite: everything the caster hits.
    double farM = std::numeric_limits<double>::infinity();
    // Near clipping plane (a CIGI View Definition's, metres ahead along the view axis): what
    // lies nearer is not drawn (ig::renderFrame's nearM). 0: none.
    double nearM = 0.0;
};

// `geometry` with the view's field of view, draw distance and near plane where it sets them
// (field of view and draw distance non-zero, near plane not negative).
RenderGeometry viewed(const RenderGeometry& geometry, const RenderView& view);
// The focal length (window pixels) a field of `view` has over `frame`'s window, for
// prp::PostRenderingProcessor::process; 0 (the frame's own) when the view sets no field of view.
double fieldFocal(const ig::RenderedFrame& frame, const RenderView& view);

// Draws what lies farther than `farM` from the eye as sky: its pixels get the sky's colour
// along their ray, sky depth and object id 0; control points beyond it become directions.
// Nothing changes when farM is infinite. A per-frame pass over the pixels, no allocation.
void clipBeyondFar(ig::RenderedFrame& frame, double farM, const ig::SkyModel& sky);

// Margin that keeps a window rolled by up to |roll| + allowance inside the rendered frame, plus
// `margin` (rounded up to a multiple of 8; never more than covering every roll needs).
int marginForRoll(int windowWidth, int windowHeight, double roll, double allowance, int margin);
// Intrinsics a frame at `pose` gets.
ig::Intrinsics renderIntrinsics(const RenderGeometry& geometry, const ig::Pose& pose);
// Pixels of the largest frame `geometry` renders, whatever the roll.
std::size_t maxFramePixels(const RenderGeometry& geometry);

// A caster over `map` rendering `geometry` (the map must outlive the renderer), with the field
// of view and draw distance of requestView() (sim/render_process.hpp) at each render.
FrameRenderer makeCasterRenderer(const ig::TerrainMap& map, const RenderGeometry& geometry,
                                 ig::CasterKind kind = ig::CasterKind::Fast,
                                 const ig::RenderOptions& options = {});

// The same over a terrain with insets (ig/inset.hpp): the nested caster, the view checked and
// the control points cast on the nested surface. The terrain must outlive the renderer.
FrameRenderer makeNestedRenderer(const ig::NestedTerrain& terrain, const RenderGeometry& geometry,
                                 ig::CasterKind kind = ig::CasterKind::Fast,
                                 const ig::RenderOptions& options = {});

// More objects asked for at each frame's instant, on the renderer's thread (a CIGI host's
// entities).
using ExtraObjects = std::function<void(double t, std::vector<ExtraObject>& out)>;

// A scene for a paged renderer (makePagedRenderer): the static layer as loaded (its placements
// stood on the database's ground at load), the moving objects and `extra`'s stamped at each
// frame's instant on a ground of the renderer process's own (ig::PagedGround, following the
// frame's eye: exact where its tiles are resident, on or above the surface elsewhere).
struct PagedScene {
    const ig::Scene* scene = nullptr;
    const SceneMotion* motion = nullptr;
    ExtraObjects extra;
};

// A caster over a terrain database paged by the view (ig/paged_terrain.hpp): before each frame,
// on the renderer's thread, the tiles of that frame's footprint are placed and those along the
// motion (from the poses of the frames so far) prefetched. The first frame waits for its tiles;
// later ones never wait, drawing what is not resident yet from a coarser level. The fast
// caster renders on the paged pyramid (with `options.levels`), the others level 0. The paged
// map is made by the process that renders, at its first frame (a renderer process makes its
// own: a forked copy has no loader threads); `db` must outlive the renderer. `log`, when
// given, gets each frame's paging as that process sees it (the field process's only with the
// renderer in a thread). With `stereoSeparation` > 0 (metres; the fast caster) it renders
// stereo pairs as makeStereoRenderer does, the tiles of both eyes placed (over the database's
// insets, both eyes on the nested surface; a scene's objects drawn over both eyes after the
// reprojection of the terrain, as ig::renderStereo does).
FrameRenderer makePagedRenderer(const ig::TerrainDb& db, const ig::PagedTerrain::Options& paging,
                                const RenderGeometry& geometry, ig::CasterKind kind,
                                const ig::RenderOptions& options,
                                std::shared_ptr<PagingLog> log = nullptr, PagedScene objects = {},
                                double stereoSeparation = 0.0);

// Stereo pairs with a scene's objects: the left eye's terrain by the fast caster, the right eye
// reprojected from it (gaps cast by the same caster), then the objects (the moving ones and
// the host's extras stamped at the frame's instant) drawn over both eyes by the footprint pass,
// as over a mono frame (ig::drawStereoObjects): each eye carries its object ids. Over insets
// (`nested`), both eyes' terrain on the nested surface, where the moving objects stand.
// The map (or `nested`), scene and motion must outlive the renderer.
FrameRenderer makeStereoSceneRenderer(const ig::TerrainMap& map, const RenderGeometry& geometry,
                                      double separation, const ig::RenderOptions& options,
                                      const ig::Scene& scene, const SceneMotion& motion,
                                      ExtraObjects extra = {},
                                      const ig::NestedTerrain* nested = nullptr);

// A caster over `map` drawing `scene`'s objects: the static layer as loaded, and the moving
// objects stamped at each frame's instant into a layer of their own, which is all that changes
// from frame to frame (the caster is built once). Renders one frame at a time. The map, scene
// and motion must outlive the renderer; the caster must draw objects (reference or naive).
// `extra`, when given, is asked on the renderer's thread for more objects at each frame's
// instant (a CIGI host's entities) and stamped into the same layer. With `nested` (insets,
// whose global map `map` shares the grid of), the nested caster draws the frame and the moving
// objects stand on the nested surface.
FrameRenderer makeSceneRenderer(const ig::TerrainMap& map, const RenderGeometry& geometry,
                                ig::CasterKind kind, const ig::RenderOptions& options,
                                const ig::Scene& scene, const SceneMotion& motion,
                                ExtraObjects extra = {}, const ig::NestedTerrain* nested = nullptr);

// The renderer process's nice value when the run writes truth on the wall clock and no other
// is asked for: the truth writer is scheduled before it.
inline constexpr int kTruthRenderNice = 10;

struct PipelineOptions {
    double duration = 10.0;  // simulated seconds; fields = round(duration / field period)
    ClockMode clock = ClockMode::Wall;
    double renderHz = 0.0;  // cap on the render rate; 0: as fast as it can
    // Simulated clock with no cap: a render is modelled as taking 1 / simulatedRenderHz.
    double simulatedRenderHz = 12.0;
    // Worker threads of the renderer's own task arena; 0: every core but one (at least one),
    // so the field loop always has a core of its own.
    int renderThreads = 0;
    // Nice value for the renderer's threads (0: leave them be; a renderer process on the wall
    // clock with `truth` set: kTruthRenderNice).
    int renderNice = 0;
    // Wall clock: run the field loop at real-time priority (SCHED_FIFO) when the system allows
    // it, else at a raised nice when allowed; restored after the run.
    bool raiseFieldPriority = true;
    double startDelay = 0.05;  // wall clock: seconds from the first frame to the first field slot
    prp::PrpOptions prp;
    // Stereo: frames carry a right eye (makeStereoRenderer); each field warps each eye to its
    // own pose and the sink takes both in one frame (its size is the layout's). The renderer
    // must be a thread for now (the frame ring carries one eye).
    std::optional<StereoOutput> stereo;
    // Extra seconds render `sequence` takes (wall: it sleeps; simulated: added to its time).
    std::function<double(std::uint64_t sequence)> renderStall;
    // After the sink took a field (field thread).
    std::function<void(const prp::Field&, const io::FieldBuffer&)> onField;
    // About four times a second with a one-line status (field thread).
    std::function<void(const std::string&)> progress;
    // When set and true, the run ends after the field in hand (SIGINT/SIGTERM): the result is
    // a good run of the fields emitted so far, with `stopped` set. The renderer's waits end too.
    const std::atomic<bool>* stop = nullptr;

    RendererMode rendererMode = RendererMode::Thread;
    // Process: the largest frame the renderer makes, in pixels (maxFramePixels of its geometry).
    std::size_t maxFramePixels = 0;
    // Process: frames carry object ids (the frame ring gets an id plane per slot).
    bool objectIds = false;
    // Process: asked on the thread that posts each render request (the field thread) for
    // objects placed at the request's instant (a CIGI host's entities); they travel with the
    // request, and the renderer process's renderer reads them with requestObjects().
    std::function<void(double t, std::vector<ExtraObject>& out)> requestObjects;
    // Per-field ground truth: each field and the pose it was warped to (field thread).
    TruthWriter* truth = nullptr;
    // With `truth`: objects placed at each field's instant besides the scene's (a CIGI host's
    // entities), asked on the field thread and listed in the field's truth.
    std::function<void(double t, std::vector<ExtraObject>& out)> truthObjects;
    // The moving objects' own motion from a frame's instant to a field's (field thread), which
    // the processor re-stamps them by (prp/object_restamp.hpp); unset: none.
    std::function<std::span<const prp::ObjectMotion>(double frameTime, double fieldTime)>
        objectMotion;
    // Process: a renderer that publishes nothing for this many seconds (wall clock) is killed and
    // restarted; 0: 0.5 s (on the simulated clock kSimulatedRenderTimeout) or eight times the
    // running render time, whichever is longer.
    double renderTimeout = 0.0;
    static constexpr double kSimulatedRenderTimeout = 5.0;
    // Process: the seconds a renderer just started (or restarted) may take for its first frame
    // (its start, and over a paged database the tiles of its first view, read waiting); 0: ten
    // render timeouts for a restart, and at least kFirstStartSeconds for the run's first start,
    // which no field waits on (the field clock starts after it), so a loaded host is not taken
    // for a hung renderer.
    double startTimeout = 0.0;
    static constexpr double kFirstStartSeconds = 30.0;
    // Process, simulated clock: the seconds a restart is modelled as taking.
    double simulatedRestart = 0.25;
    // Process: a fault the renderer injects into itself once (tests, demonstrations).
    std::optional<RendererFault> fault;
};

struct PipelineResult {
    StatsSummary stats;
    int sinkError = 0;     // first error a sink call returned (-errno), 0 if none
    std::string error;     // what stopped the run early, empty when it ran to the end
    bool stopped = false;  // ended early by PipelineOptions::stop (not an error)
    bool ok() const { return error.empty(); }
};

// Renders asynchronously into a mailbox and emits round(duration / field period) fields, each
// warped to its own instant (docs/design/pipeline.md). One run per object.
class Pipeline {
  public:
    // `sink` must be open; its format is the output format (the PRP's size and pixel format
    // follow it). Nothing is started before run().
    Pipeline(PoseSource& poses, FrameRenderer renderer, io::FrameSink& sink, io::FieldClock& clock,
             const PipelineOptions& options);
    ~Pipeline();
    Pipeline(const Pipeline&) = delete;
    Pipeline& operator=(const Pipeline&) = delete;

    // Runs every field. A render that throws (ig::InputError for a bad pose) ends the run and
    // is rethrown here once the renderer has stopped.
    PipelineResult run();

    std::uint64_t fieldCount() const { return fieldCount_; }
    const StatsCollector& stats() const { return stats_; }

  private:
    void renderLoop();
    // Renderer process: start, frame 0, supervision (wall clock), one render (simulated clock).
    void startProcess();
    enum class Await { Frame, Ended, Bad, Silent };
    Await awaitFrame(ig::RenderedFrame& into, double timeout, std::string& why);
    void superviseLoop();
    // "silent for N ms", and after which step when the renderer's last sign of life came in
    // this frame (FrameRing::lastAliveStep).
    // With `unwatched`, the part of it the supervisor was not running (SilenceWatch).
    std::string silenceCause(double seconds, bool afterSignOfLife, double unwatched = 0.0) const;
    void restartProcess(const std::string& cause);
    double renderTimeout() const;
    double startTimeout() const;
    // The seconds the run's first renderer may take for frame 0, before the field clock starts.
    double firstStartTimeout() const;
    // The silence allowed the running renderer now: startTimeout() until its first frame.
    double silenceAllowed() const;
    // Field thread: gap accounting when a frame newer than the last one shown arrives.
    void noteFrameShown(const ig::RenderedFrame& frame, double clock);
    void noteField(double frameAge);
    bool stopAsked() const;
    // The renderer's waits: in steps of at most 50 ms, ended early by a stop.
    void renderSleepUntil(double t);
    void renderSimulatedUntil(double t);
    ig::RenderedFrame renderAt(double poseTime, std::uint64_t sequence);
    void publish(ig::RenderedFrame&& frame);

    PoseSource& poses_;
    FrameRenderer renderer_;
    io::FrameSink& sink_;
    io::FieldClock& clock_;
    PipelineOptions options_;
    std::uint64_t fieldCount_;
    double t0_ = 0.0;              // simulation time of field 0
    double runEnd_ = 0.0;          // simulation time just after the last field
    double c0_ = 0.0;              // clock time of field 0's slot
    double renderEstimate_ = 0.0;  // seconds a render is expected to take (wall)
    StatsCollector stats_;
    Mailbox<ig::RenderedFrame> frames_;
    std::atomic<bool> stop_{false};
    std::exception_ptr renderError_;
    std::atomic<bool> renderFailed_{false};
    double renderStartClock_ = 0.0, renderEndClock_ = 0.0;

    // Renderer process.
    std::unique_ptr<FrameRing> ring_;
    std::unique_ptr<RendererProcess> process_;
    std::mutex restartMutex_;                     // guards stats_.restarts()
    std::atomic<std::uint64_t> restarts_{0};      // restarts so far
    std::uint64_t restartsClosed_ = 0;            // field thread: restarts whose gap is accounted
    std::atomic<std::uint64_t> requested_{0};     // the newest sequence asked of the renderer
    std::atomic<std::uint64_t> restartAfter_{0};  // at the last restart: frames after it are newer
    SilenceWatch silence_;                        // supervisor: the renderer's silence watched
    std::int64_t processStartNs_ = 0;         // supervisor: when the running renderer was started
    std::atomic<bool> processFresh_{false};   // the running renderer has sent no frame yet
    std::atomic<double> renderSeconds_{0.0};  // running render time (for the timeout)
    std::uint64_t lastShownSequence_ = ~std::uint64_t{0};
    double lastNewFrameClock_ = 0.0;
    std::uint64_t gapFields_ = 0, gapHeld_ = 0;

    // Posts a render request with options_.requestObjects's objects at `time` and the view.
    void postRequest(const ig::Pose& pose, double time, std::uint64_t sequence);
    // The view of the latest field (field thread writes, the renderer reads).
    void setView(const RenderView& view);
    RenderView view() const;
    std::atomic<double> viewHfov_{0.0}, viewFar_{0.0}, viewNear_{-1.0};
    std::vector<ExtraObject> requestObjects_;  // postRequest's scratch
    std::vector<ExtraObject> truthObjects_;    // the field loop's scratch for the truth
    bool requestObjectsCut_ = false;

    // Simulated clock renderer state.
    std::uint64_t nextSequence_ = 1;
    double nextRenderStart_ = 0.0;
    bool pending_ = false;
    double pendingCompletion_ = 0.0;
    ig::RenderedFrame pendingFrame_;
};

// A processed field as the output layer takes it (prp and io do not know each other).
io::FieldBuffer toFieldBuffer(const prp::Field& field);

}  // namespace sim
