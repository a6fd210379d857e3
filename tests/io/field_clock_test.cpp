#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "io/field_clock.hpp"

namespace io {
namespace {

// A simulated loop that works a random amount after each wake: deadlines stay exactly on the
// t0 + n * period grid for a day of fields, while a loop that sleeps "period after the last
// wake" drifts by the work time.
TEST(FieldPacer, AbsoluteDeadlinesDoNotDrift) {
    SimulatedClock clock;
    clock.advance(0.25);
    const double t0 = 0.5;
    FieldPacer pacer(clock, t0);
    std::mt19937 rng(7);
    std::uniform_real_distribution<double> work(0.0, 0.9 * (1001.0 / 60000.0));
    const std::uint64_t kFields = 200000;
    double relativeWake = 0.0;
    for (std::uint64_t n = 0; n < kFields; ++n) {
        const FieldWake w = pacer.wait(n);
        ASSERT_FALSE(w.late) << n;
        ASSERT_EQ(w.woke, w.deadline) << n;
        ASSERT_EQ(w.deadline, base::fieldTime(t0, n));
        const double dt = work(rng);
        clock.advance(dt);
        relativeWake += 1001.0 / 60000.0 + dt;  // a relative-sleep loop's wake time
    }
    EXPECT_NEAR(clock.now() - t0, kFields * 1001.0 / 60000.0, 0.02);
    EXPECT_GT(relativeWake - (clock.now() - t0), 100.0);  // the relative loop is minutes behind
}

TEST(FieldPacer, ReportsLateFieldsWithoutSleeping) {
    SimulatedClock clock;
    FieldPacer pacer(clock, 0.0);
    EXPECT_FALSE(pacer.wait(0).late);
    clock.advance(0.05);  // a stall of three fields
    for (std::uint64_t n = 1; n <= 2; ++n) {
        const FieldWake w = pacer.wait(n);
        EXPECT_TRUE(w.late) << n;
        EXPECT_NEAR(w.lateness, 0.05 - base::fieldTime(0.0, n), 1e-12);
        EXPECT_EQ(w.woke, 0.05);
    }
    const FieldWake w3 = pacer.wait(3);
    EXPECT_FALSE(w3.late);
    EXPECT_EQ(w3.woke, base::fieldTime(0.0, 3));
}

TEST(SimulatedClock, NeverGoesBackwards) {
    auto clock = makeSimulatedClock();
    EXPECT_EQ(clock->now(), 0.0);
    clock->sleepUntil(2.0);
    EXPECT_EQ(clock->now(), 2.0);
    clock->sleepUntil(1.0);
    EXPECT_EQ(clock->now(), 2.0);
}

// The wall clock: only ordering is asserted (no timing).
TEST(WallClock, SleepsUntilAtLeastTheDeadline) {
    auto clock = makeWallClock();
    const double start = clock->now();
    EXPECT_GE(start, 0.0);
    double previous = start;
    for (int i = 1; i <= 3; ++i) {
        const double deadline = start + i * 0.001;
        clock->sleepUntil(deadline);
        const double now = clock->now();
        EXPECT_GE(now, deadline);
        EXPECT_GE(now, previous);
        previous = now;
    }
    clock->sleepUntil(previous - 1.0);  // a past deadline returns at once
    EXPECT_GE(clock->now(), previous);
}

}  // namespace
}  // namespace io
