// Consecutive frames over one pool of workers, the next frame's work starting while the last
// one's finishes (Cohen-Or sec. 3.2): a frame's work units (columns) are taken by idle workers
// one at a time; a worker that finds none left goes on to the next frame already submitted,
// instead of idling until the slowest column of the frame is done.
//
// The real-time loop (sim::Pipeline) does not use it: it renders one frame at a time with every
// worker, because on the machines measured the overlap gained nothing (docs/design/multires.md).
//
//   ig::FrameStream stream(caster, map, threads);
//   stream.submit(pose0, intrinsics, t0, 0);
//   for (;;) {
//       stream.help();                        // take units of the oldest frame until none left
//       stream.submit(nextPose, ...);         // freshest pose, while its last units finish
//       RenderedFrame f = stream.take();      // the oldest frame, complete
//   }
#pragma once

#include "ig/caster.hpp"

#include <tbb/task_arena.h>

#include <atomic>
#include <condition_variable>
#include <deque>
#include <memory>
#include <mutex>

namespace ig {

class FrameStream {
  public:
    // `threads` workers in all (0 or more than the cores: every core), the thread that calls
    // help() or take() included. The
    // caster and the map must outlive the stream.
    FrameStream(const Caster& caster, const TerrainMap& map, int threads = 0);
    ~FrameStream();  // waits for the frames in flight
    FrameStream(const FrameStream&) = delete;
    FrameStream& operator=(const FrameStream&) = delete;

    // Starts a frame: validates the view (InputError as renderFrame, and for a rolled pose
    // given to the fast caster, which renders roll = 0), allocates it and hands
    // its units to the workers, after those of the frames submitted before it.
    void submit(const Pose& pose, const Intrinsics& intrinsics, double time = 0.0,
                std::uint64_t sequence = 0);
    // The calling thread renders units of the oldest frame not yet taken until every unit of
    // it has been handed out. No-op when nothing is in flight.
    void help();
    // Renders what is left of the oldest frame's units with the other workers, waits for
    // every unit of it, casts its control points and returns it (as
    // renderFrame would have rendered it; stats.renderMs is submit-to-complete). CHECKs that a
    // frame is in flight; rethrows a worker's exception.
    RenderedFrame take();
    int inFlight() const;

  private:
    struct Job;
    void work(Job& job);

    const Caster& caster_;
    const TerrainMap& map_;
    int threads_;
    std::unique_ptr<tbb::task_arena> arena_;
    mutable std::mutex mutex_;
    std::condition_variable done_;
    std::deque<std::shared_ptr<Job>> jobs_;
    int outstanding_ = 0;  // enqueued worker loops not yet returned (guarded by mutex_)
};

}  // namespace ig
