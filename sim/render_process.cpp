#include "sim/render_process.hpp"

#include "base/error.hpp"
#include "base/fork_gate.hpp"
#include "base/text.hpp"
#include "io/field_clock.hpp"

#include <oneapi/tbb/global_control.h>
#include <oneapi/tbb/task_arena.h>
#include <signal.h>
#include <sys/prctl.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <charconv>
#include <cmath>
#include <cstring>
#include <exception>
#include <limits>
#include <stdexcept>

namespace sim {
namespace {

// The objects of the request being rendered (renderer process only).
std::vector<ExtraObject> gRequestObjects;
// The view of the render the calling thread is doing.
thread_local RenderView tRequestView;
// The renderer process's ring (null in any other process).
std::atomic<FrameRing*> gAliveRing{nullptr};
// noteRendererAlive's last sign of life (clock, ns; 0 before any) and step; the longest
// silence since takeRendererSilence (ns) and its steps (after << 8 | until).
std::atomic<std::int64_t> gLastAliveNs{0};
std::atomic<RenderStep> gLastAliveStep{RenderStep::Request};
std::atomic<std::int64_t> gSilenceNs{0};
std::atomic<std::uint16_t> gSilenceSteps{0};

void sleepSeconds(double s) {
    if (!(s > 0.0)) return;
    timespec ts{};
    ts.tv_sec = static_cast<time_t>(s);
    ts.tv_nsec = static_cast<long>((s - static_cast<double>(ts.tv_sec)) * 1e9);
    while (nanosleep(&ts, &ts) != 0 && errno == EINTR) {
    }
}

double parseSeconds(std::string_view text, std::string_view flag, std::string_view what) {
    double v = 0.0;
    const auto [ptr, ec] = std::from_chars(text.data(), text.data() + text.size(), v);
    if (text.empty() || ec != std::errc() || ptr != text.data() + text.size() ||
        !std::isfinite(v) || v < 0.0 || v > 1e9) {
        throw base::InputError(std::string(flag) + ": " + std::string(what) + " " +
                               base::quoted(text) + " is not a number from 0 to 1e9");
    }
    return v;
}

}  // namespace

std::span<const ExtraObject> requestObjects() {
    return gRequestObjects;
}

RenderView requestView() {
    return tRequestView;
}

void setRequestView(const RenderView& view) {
    tRequestView = view;
}

void noteRendererAlive(RenderStep step) {
    const std::int64_t now = io::monotonicNs();
    if (FrameRing* ring = gAliveRing.load(std::memory_order_relaxed)) ring->noteAlive(now, step);
    const std::int64_t last = gLastAliveNs.exchange(now, std::memory_order_relaxed);
    const RenderStep after = gLastAliveStep.exchange(step, std::memory_order_relaxed);
    if (last > 0 && now - last > gSilenceNs.load(std::memory_order_relaxed)) {
        gSilenceNs.store(now - last, std::memory_order_relaxed);
        gSilenceSteps.store(static_cast<std::uint16_t>(static_cast<unsigned>(after) << 8 |
                                                       static_cast<unsigned>(step)),
                            std::memory_order_relaxed);
    }
}

RendererSilence takeRendererSilence() {
    RendererSilence s;
    s.ms = static_cast<double>(gSilenceNs.exchange(0, std::memory_order_relaxed)) * 1e-6;
    const unsigned steps = gSilenceSteps.exchange(0, std::memory_order_relaxed);
    s.after = static_cast<RenderStep>(steps >> 8);
    s.until = static_cast<RenderStep>(steps & 0xffu);
    return s;
}

std::int64_t SilenceWatch::look(std::int64_t nowNs, std::int64_t sinceNs) {
    if (sinceNs != since_) {  // a sign of life since the last look: a new silence
        since_ = sinceNs;
        unwatched_ = 0;
    }
    const std::int64_t gap = nowNs - std::max(lastLook_, sinceNs);
    if (gap > kMaxLookGapNs) unwatched_ += gap - kMaxLookGapNs;
    lastLook_ = std::max(lastLook_, nowNs);
    return std::max<std::int64_t>(nowNs - sinceNs - unwatched_, 0);
}

RendererFault parseRendererFault(std::string_view text, std::string_view flag) {
    const std::size_t at = text.find('@');
    if (at == std::string_view::npos) {
        throw base::InputError(std::string(flag) +
                               ": expected KIND@SECONDS (crash, segv, "
                               "exception, hang, garbage) or stall@SECONDS:MS, "
                               "got " +
                               base::quoted(text));
    }
    const std::string_view kind = text.substr(0, at);
    std::string_view rest = text.substr(at + 1);
    RendererFault f;
    if (kind == "crash") {
        f.kind = RendererFault::Kind::Crash;
    } else if (kind == "segv") {
        f.kind = RendererFault::Kind::Segv;
    } else if (kind == "exception") {
        f.kind = RendererFault::Kind::Exception;
    } else if (kind == "hang") {
        f.kind = RendererFault::Kind::Hang;
    } else if (kind == "garbage") {
        f.kind = RendererFault::Kind::Garbage;
    } else if (kind == "stall") {
        f.kind = RendererFault::Kind::Stall;
        const std::size_t colon = rest.find(':');
        if (colon == std::string_view::npos) {
            throw base::InputError(std::string(flag) +
                                   ": stall needs its length, stall@SECONDS:MS, "
                                   "got " +
                                   base::quoted(text));
        }
        f.stallSeconds = parseSeconds(rest.substr(colon + 1), flag, "stall milliseconds") / 1e3;
        rest = rest.substr(0, colon);
    } else {
        throw base::InputError(std::string(flag) + ": unknown fault " + base::quoted(kind) +
                               " (crash, segv, exception, hang, stall, garbage)");
    }
    f.at = parseSeconds(rest, flag, "time");
    return f;
}

std::string describeRendererFault(const RendererFault& f) {
    const char* names[] = {"crash", "segv", "exception", "hang", "stall", "garbage"};
    std::string s = names[static_cast<int>(f.kind)];
    s.append(1, '@').append(base::number(f.at));
    if (f.kind == RendererFault::Kind::Stall) {
        s.append(1, ':').append(base::number(f.stallSeconds * 1e3));
    }
    return s;
}

RendererProcess::RendererProcess(const FrameRenderer& renderer, FrameRing& ring,
                                 const RendererProcessOptions& options)
    : renderer_(renderer), ring_(ring), options_(options) {}

RendererProcess::~RendererProcess() {
    if (pid_ <= 0) return;
    ring_.requestStop();
    for (int i = 0; i < 50 && pid_ > 0; ++i) {
        if (checkEnded()) break;
        sleepSeconds(0.01);
    }
    kill();
}

void RendererProcess::start() {
    if (pid_ > 0) kill();
    ring_.clearError();
    ring_.resetWriter();
    // A new renderer answers requests posted from now on only: the one its predecessor died
    // on is stale by the time it could answer it.
    skipGeneration_ = ring_.latestRequest().generation;
    const pid_t parent = getpid();
    pid_t pid = -1;
    {
        // No background thread of this process is in the middle of its work (holding the
        // allocator's or its own locks, which the child would find held for ever) while it
        // forks: base/fork_gate.hpp.
        const base::ForkGate::Closed quiet;
        // The scheduler's worker threads do not survive a fork: end them first, so the child
        // starts a whole scheduler of its own. The field process renders nothing itself.
        {
            tbb::task_scheduler_handle handle{tbb::attach{}};
            (void)tbb::finalize(handle, std::nothrow);
        }
        pid = fork();
        if (pid == 0) {
            base::ForkGate::resetInChild();
            prctl(PR_SET_PDEATHSIG, SIGKILL);
            if (getppid() != parent) _exit(1);
            childMain();
        }
    }
    if (pid < 0) throw std::runtime_error(std::string("fork: ") + std::strerror(errno));
    pid_ = pid;
}

void RendererProcess::childMain() {
    // The field process handles the terminal's and the user's signals; this process ends when
    // asked through the ring, or is killed.
    struct sigaction ignore {};
    ignore.sa_handler = SIG_IGN;
    sigaction(SIGINT, &ignore, nullptr);
    sigaction(SIGTERM, &ignore, nullptr);
    sigaction(SIGPIPE, &ignore, nullptr);
    sigset_t none;
    sigemptyset(&none);
    sigprocmask(SIG_SETMASK, &none, nullptr);
    // Threads inherit the nice value of the thread that starts them: set it before the arena's.
    if (options_.nice != 0) setpriority(PRIO_PROCESS, 0, options_.nice);
    gAliveRing.store(&ring_, std::memory_order_relaxed);
    try {
        tbb::task_arena arena(options_.threads > 0 ? options_.threads : tbb::task_arena::automatic);
        std::uint64_t lastGeneration = skipGeneration_;
        std::int64_t nextSlotNs = io::monotonicNs();
        const std::int64_t periodNs =
            options_.renderHz > 0.0 ? static_cast<std::int64_t>(1e9 / options_.renderHz) : 0;
        while (!ring_.stopRequested()) {
            const RenderRequest r = ring_.latestRequest(&gRequestObjects);
            if (r.generation == 0 || r.generation == lastGeneration) {
                sleepSeconds(0.0005);
                continue;
            }
            if (options_.paced && periodNs > 0) {
                const std::int64_t now = io::monotonicNs();
                if (nextSlotNs > now) {
                    sleepSeconds(static_cast<double>(nextSlotNs - now) * 1e-9);
                    continue;  // render the newest request once the slot comes
                }
                nextSlotNs = std::max(nextSlotNs + periodNs, now);
            }
            lastGeneration = r.generation;
            if (options_.fault && r.time >= options_.fault->at && ring_.claimFault()) {
                switch (options_.fault->kind) {
                    case RendererFault::Kind::Crash:
                        ::kill(getpid(), SIGKILL);
                        break;
                    case RendererFault::Kind::Segv: {
                        struct sigaction dfl {};
                        dfl.sa_handler = SIG_DFL;
                        sigaction(SIGSEGV, &dfl, nullptr);
                        ::kill(getpid(), SIGSEGV);
                        break;
                    }
                    case RendererFault::Kind::Exception:
                        throw std::runtime_error(
                            "injected renderer exception at t = " + base::number(r.time) + " s");
                    case RendererFault::Kind::Hang:
                        for (;;)
                            pause();
                    case RendererFault::Kind::Stall:
                        sleepSeconds(options_.fault->stallSeconds);
                        break;
                    case RendererFault::Kind::Garbage: {
                        ig::RenderedFrame bad;
                        bad.sequence = r.sequence;
                        bad.time = r.time;
                        bad.pose = r.pose;
                        bad.intrinsics = ig::Intrinsics::fromFov(64, 48, 1.0, 4);
                        bad.controlPoints[4].world.x = std::numeric_limits<double>::quiet_NaN();
                        ring_.publishRaw(bad, std::numeric_limits<std::uint64_t>::max());
                        continue;
                    }
                }
            }
            ig::RenderedFrame frame;
            setRequestView(r.view);
            arena.execute([&] { frame = renderer_(r.pose, r.time, r.sequence); });
            if (!ring_.publish(frame, io::monotonicNs())) {
                throw std::runtime_error("frame " + std::to_string(frame.sequence) + " of " +
                                         std::to_string(frame.color.size()) +
                                         " pixels does not fit the frame ring");
            }
        }
    } catch (const std::exception& e) {
        ring_.setError(e.what());
        _exit(3);
    } catch (...) {
        ring_.setError("unknown exception");
        _exit(3);
    }
    _exit(0);
}

std::optional<std::string> RendererProcess::checkEnded() {
    if (pid_ <= 0) return std::nullopt;
    int status = 0;
    const pid_t r = waitpid(pid_, &status, WNOHANG);
    if (r == 0) return std::nullopt;
    pid_ = -1;
    if (r < 0) return std::string("lost (waitpid: ") + std::strerror(errno) + ")";
    if (WIFSIGNALED(status)) {
        const int sig = WTERMSIG(status);
        return "killed by signal " + std::to_string(sig) + " (" + strsignal(sig) + ")";
    }
    std::string why = "exited with status " + std::to_string(WEXITSTATUS(status));
    if (const std::string last = ring_.error(); !last.empty()) why += ": " + last;
    return why;
}

void RendererProcess::kill() {
    if (pid_ <= 0) return;
    ::kill(pid_, SIGKILL);
    int status = 0;
    while (waitpid(pid_, &status, 0) < 0 && errno == EINTR) {
    }
    pid_ = -1;
}

}  // namespace sim
