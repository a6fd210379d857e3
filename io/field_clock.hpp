// The field clock: absolute field deadlines on CLOCK_MONOTONIC, or simulated time for tests.
#pragma once

#include <cstdint>
#include <memory>

#include "base/video_timing.hpp"

namespace io {

// Seconds since the clock was created. sleepUntil() takes an absolute time, so a loop that
// sleeps until t0 + n * period never accumulates the time spent working or oversleeping.
class FieldClock {
  public:
    virtual ~FieldClock() = default;
    virtual double now() = 0;
    virtual void sleepUntil(double t) = 0;
};

// CLOCK_MONOTONIC in integer nanoseconds (the wall clock's time base, and the one the renderer
// process stamps its frames with).
std::int64_t monotonicNs();

// CLOCK_MONOTONIC; sleepUntil uses clock_nanosleep(TIMER_ABSTIME) and resumes after signals.
std::unique_ptr<FieldClock> makeWallClock();
// now() starts at 0 and jumps to the deadline in sleepUntil (never backwards); no wall time.
std::unique_ptr<FieldClock> makeSimulatedClock();

// The simulated clock, for callers that also model time spent working.
class SimulatedClock final : public FieldClock {
  public:
    double now() override { return now_; }
    void sleepUntil(double t) override {
        if (t > now_) now_ = t;
    }
    void advance(double seconds) {
        if (seconds > 0) now_ += seconds;
    }

  private:
    double now_ = 0.0;
};

// When a field actually left, against its deadline.
struct FieldWake {
    double deadline = 0.0;
    double woke = 0.0;      // clock time after the wait
    double lateness = 0.0;  // woke - deadline, >= 0 when the deadline had already passed
    bool late = false;      // the deadline had passed before the wait began
};

// Paces a field loop: wait(n) sleeps until field n's deadline, base::fieldTime(t0, n), the
// field's instant on this clock (computed from the index, so deadlines never drift).
class FieldPacer {
  public:
    FieldPacer(FieldClock& clock, double t0) : clock_(clock), t0_(t0) {}
    FieldWake wait(std::uint64_t index);
    double deadline(std::uint64_t index) const { return base::fieldTime(t0_, index); }
    double start() const { return t0_; }

  private:
    FieldClock& clock_;
    double t0_;
};

}  // namespace io
