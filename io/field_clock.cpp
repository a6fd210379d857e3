#include "io/field_clock.hpp"

#include <time.h>

#include <cerrno>
#include <cmath>

namespace io {
namespace {

constexpr std::int64_t kNsPerSecond = 1000000000;

class WallClock final : public FieldClock {
  public:
    WallClock() : originNs_(monotonicNs()) {}

    double now() override { return static_cast<double>(monotonicNs() - originNs_) * 1e-9; }

    void sleepUntil(double t) override {
        if (!(t > 0.0) && !(t <= 0.0)) return;  // NaN: nothing sensible to wait for
        const std::int64_t target = originNs_ + std::llround(t * 1e9);
        timespec ts{};
        ts.tv_sec = static_cast<time_t>(target / kNsPerSecond);
        ts.tv_nsec = static_cast<long>(target % kNsPerSecond);
        while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr) == EINTR) {
        }
    }

  private:
    std::int64_t originNs_;
};

}  // namespace

std::int64_t monotonicNs() {
    timespec ts{};
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return static_cast<std::int64_t>(ts.tv_sec) * kNsPerSecond + ts.tv_nsec;
}

std::unique_ptr<FieldClock> makeWallClock() {
    return std::make_unique<WallClock>();
}

std::unique_ptr<FieldClock> makeSimulatedClock() {
    return std::make_unique<SimulatedClock>();
}

FieldWake FieldPacer::wait(std::uint64_t index) {
    FieldWake w;
    w.deadline = deadline(index);
    w.late = clock_.now() > w.deadline;
    if (!w.late) clock_.sleepUntil(w.deadline);
    w.woke = clock_.now();
    w.lateness = w.woke - w.deadline;
    return w;
}

}  // namespace io
