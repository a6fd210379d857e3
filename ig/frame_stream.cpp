#include "ig/frame_stream.hpp"

#include "base/check.hpp"
#include "ig/caster_impl.hpp"
#include "ig/error.hpp"

#include <algorithm>
#include <chrono>
#include <exception>
#include <stdexcept>
#include <thread>

namespace ig {

struct FrameStream::Job {
    RenderedFrame frame;
    Camera camera;
    int units = 0;
    std::atomic<int> next{0};      // the next unit to hand out
    std::atomic<int> finished{0};  // units rendered
    std::atomic<std::uint64_t> steps{0}, restarts{0};
    std::exception_ptr error;  // guarded by the stream's mutex
    std::chrono::steady_clock::time_point start;

    Job(const Pose& pose, const Intrinsics& intrinsics) : camera(pose, intrinsics) {}
};

FrameStream::FrameStream(const Caster& caster, const TerrainMap& map, int threads)
    : caster_(caster), map_(map) {
    const int cores = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
    threads_ = threads > 0 ? std::min(threads, cores) : cores;
    // The caller of help() is one of the workers: the arena's other slots are for the pool's.
    arena_ = std::make_unique<tbb::task_arena>(threads_, 1);
    arena_->initialize();
}

FrameStream::~FrameStream() {
    // Units nobody took yet (with one thread, the pool has no workers of its own).
    std::deque<std::shared_ptr<Job>> jobs;
    {
        std::lock_guard lock(mutex_);
        jobs = jobs_;
    }
    for (const auto& job : jobs)
        arena_->execute([&] { work(*job); });
    std::unique_lock lock(mutex_);
    // Every unit rendered and every enqueued loop returned (a loop that starts after its
    // frame's units are gone still runs, finds none, and leaves): nothing touches the stream
    // once this returns.
    done_.wait(lock, [&] {
        return outstanding_ == 0 && std::all_of(jobs_.begin(), jobs_.end(), [](const auto& j) {
                   return j->finished.load() == j->units;
               });
    });
}

void FrameStream::submit(const Pose& pose, const Intrinsics& intrinsics, double time,
                         std::uint64_t sequence) {
    if (casterNeedsLevelRoll(caster_.kind()) && pose.roll != 0.0) {
        throw InputError("pose: the " + std::string(casterName(caster_.kind())) +
                         " caster renders roll = 0 (the PRP applies roll)");
    }
    auto job = std::make_shared<Job>(pose, intrinsics);
    job->frame = newFrame(map_, pose, intrinsics, time, sequence);
    job->units = caster_.workUnits(job->camera);
    job->start = std::chrono::steady_clock::now();
    {
        std::lock_guard lock(mutex_);
        jobs_.push_back(job);
        outstanding_ += threads_ - 1;
    }
    // One loop per pool worker; enqueued work runs in about the order it was enqueued, so a
    // worker reaches this frame's loop when the frames before it have no units left.
    for (int i = 1; i < threads_; ++i) {
        arena_->enqueue([this, job] {
            work(*job);
            // The last thing the loop does; the destructor waits for every loop to get here.
            std::lock_guard lock(mutex_);
            --outstanding_;
            done_.notify_all();
        });
    }
}

void FrameStream::work(Job& job) {
    UnitCounters counters;
    int rendered = 0;
    for (;;) {
        // Runs of adjacent units, shorter towards the end of the frame (guided): workers on
        // neighbouring units would share the cache lines of every image row they write.
        const int left = job.units - job.next.load(std::memory_order_relaxed);
        const int run = std::clamp(left / (4 * threads_), 1, 16);
        const int first = job.next.fetch_add(run, std::memory_order_relaxed);
        if (first >= job.units) break;
        const int last = std::min(first + run, job.units);
        for (int unit = first; unit < last; ++unit) {
            try {
                caster_.renderUnit(job.camera, job.frame, unit, counters);
            } catch (...) {
                std::lock_guard lock(mutex_);
                if (!job.error) job.error = std::current_exception();
            }
        }
        rendered += last - first;
    }
    job.steps.fetch_add(counters.steps, std::memory_order_relaxed);
    job.restarts.fetch_add(counters.restarts, std::memory_order_relaxed);
    if (rendered > 0 &&
        job.finished.fetch_add(rendered, std::memory_order_acq_rel) + rendered == job.units) {
        std::lock_guard lock(mutex_);
        done_.notify_all();
    }
}

void FrameStream::help() {
    std::shared_ptr<Job> job;
    {
        std::lock_guard lock(mutex_);
        if (jobs_.empty()) return;
        job = jobs_.front();
    }
    arena_->execute([&] { work(*job); });
}

RenderedFrame FrameStream::take() {
    std::shared_ptr<Job> job;
    {
        std::lock_guard lock(mutex_);
        CHECK(!jobs_.empty()) << "FrameStream::take: no frame in flight";
        job = jobs_.front();
    }
    arena_->execute([&] { work(*job); });  // the units still unclaimed, if any
    {
        std::unique_lock lock(mutex_);
        done_.wait(lock, [&] { return job->finished.load() == job->units; });
        jobs_.pop_front();
        if (job->error) std::rethrow_exception(job->error);
    }
    RenderedFrame& frame = job->frame;
    caster_.finishFrame(job->camera, frame);  // the sun lighting, once every unit is done
    frame.stats.renderMs =
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - job->start)
            .count();
    frame.stats.steps = job->steps.load();
    frame.stats.restarts = job->restarts.load();
    frame.stats.rays = static_cast<std::uint64_t>(frame.intrinsics.width) * frame.intrinsics.height;
    frame.stats.kernel = caster_.kernelName();
    castControlPoints(map_, job->camera, frame);
    return std::move(frame);
}

int FrameStream::inFlight() const {
    std::lock_guard lock(mutex_);
    return static_cast<int>(jobs_.size());
}

}  // namespace ig
