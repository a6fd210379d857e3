// The renderer in a process of its own, started and supervised by the field process.
//
// The child is forked from the field process, so it shares the terrain (and every table built
// from it) copy-on-write: a restart costs a fork, never a reload. It renders the newest request
// the field process posted in the FrameRing and publishes each frame there; it never touches
// the field process's memory otherwise. Whatever it does (crash, hang, throw, write garbage),
// the field process goes on: it notices, kills what is left and starts another.
#pragma once

#include "sim/frame_ring.hpp"

#include <sys/types.h>

#include <cstdint>
#include <functional>
#include <optional>
#include <span>
#include <string>
#include <string_view>

namespace sim {

// Renders one frame for simulation time `time`. `pose` is the full predicted pose, roll
// included: the frame itself is rendered at roll 0 (the PRP applies roll), and the roll may
// size its margins. One thread at a time.
using FrameRenderer =
    std::function<ig::RenderedFrame(const ig::Pose& pose, double time, std::uint64_t sequence)>;

// A fault the renderer process injects into itself once per run, when it is first asked for a
// frame at simulation time `at` or later (--inject-renderer-fault).
struct RendererFault {
    enum class Kind { Crash, Segv, Exception, Hang, Stall, Garbage };
    Kind kind = Kind::Crash;
    double at = 0.0;            // simulation seconds
    double stallSeconds = 0.0;  // Stall only
};

// "crash@T" (SIGKILL), "segv@T" (SIGSEGV), "exception@T", "hang@T" (never answers again),
// "stall@T:MS" (MS milliseconds late, then renders on), "garbage@T" (publishes a frame with
// impossible sizes and NaN control points). T in seconds from the start of the run. Throws
// base::InputError naming `flag` and what is wrong.
RendererFault parseRendererFault(std::string_view text, std::string_view flag);
std::string describeRendererFault(const RendererFault& fault);

// In the renderer process, while its renderer runs: the objects the request being rendered
// carried (FrameRing::postRequest); empty in any other process.
std::span<const ExtraObject> requestObjects();

// On the thread that calls a FrameRenderer, while it runs: the view (field of view, draw
// distance) the render is asked for. The renderer process sets it from each request, the
// pipeline's renderer thread from the field thread's latest view; the geometry's own (all 0)
// on any other thread. The renderers of sim/ render with it.
RenderView requestView();
void setRequestView(const RenderView& view);

// While a renderer runs, `step` just done: in the renderer process, tells the supervisor that
// the render is still making progress (a frame whose tiles take seconds to place is not a
// hang: FrameRing::noteAlive). In any process, measures the renderer's silences (below). The
// renderer's thread.
void noteRendererAlive(RenderStep step);

// The longest time between two signs of life of this process's renderer since the last call
// (the first sign of a process excluded), with the step after which it fell silent and the one
// that ended the silence; the next call measures from there. A frame's renderer calls it at
// its first step (discarding the wait for the request) and after its last.
struct RendererSilence {
    double ms = 0.0;
    RenderStep after = RenderStep::Request;
    RenderStep until = RenderStep::Request;
};
RendererSilence takeRendererSilence();

struct RendererProcessOptions {
    int threads = 0;        // the renderer's worker threads; 0: every core
    double renderHz = 0.0;  // wall pacing of renders; 0: as fast as it can
    bool paced = true;      // false: render each request once, as soon as it is posted
    int nice = 0;           // the renderer process's nice value (0: as started)
    std::optional<RendererFault> fault;
};

// How long a renderer has been silent as its supervisor watched it: the time since its last
// sign of life, less the time the supervisor itself did not run. A look counts at most
// kMaxLookGapNs since the one before: a host that stops the supervising thread for half a
// second has not watched the renderer be silent for it (its renderer was most likely stopped
// as well). A supervisor looking every few milliseconds counts a hang in full.
class SilenceWatch {
  public:
    static constexpr std::int64_t kMaxLookGapNs = 50'000'000;
    // A look at `nowNs` when the last sign of life came at `sinceNs`: the silence watched (ns).
    std::int64_t look(std::int64_t nowNs, std::int64_t sinceNs);
    // Of the current silence, the time not watched (ns).
    std::int64_t unwatchedNs() const { return unwatched_; }

  private:
    std::int64_t since_ = 0;
    std::int64_t lastLook_ = 0;
    std::int64_t unwatched_ = 0;
};

class RendererProcess {
  public:
    // Nothing runs before start(). `renderer` and `ring` must outlive this object.
    RendererProcess(const FrameRenderer& renderer, FrameRing& ring,
                    const RendererProcessOptions& options);
    ~RendererProcess();  // asks the renderer to stop, kills it if it does not within 0.5 s
    RendererProcess(const RendererProcess&) = delete;
    RendererProcess& operator=(const RendererProcess&) = delete;

    // Forks a renderer. Throws std::runtime_error when the system refuses.
    void start();
    bool running() const { return pid_ > 0; }
    pid_t pid() const { return pid_; }

    // Without waiting: when the renderer has ended, reaps it and says why ("killed by signal 9
    // (Killed)", "exited with status 3: <its last words>"); empty while it runs.
    std::optional<std::string> checkEnded();
    // SIGKILL and reap (no-op when none runs).
    void kill();

  private:
    [[noreturn]] void childMain();

    const FrameRenderer& renderer_;
    FrameRing& ring_;
    RendererProcessOptions options_;
    pid_t pid_ = -1;
    std::uint64_t skipGeneration_ = 0;
};

}  // namespace sim
