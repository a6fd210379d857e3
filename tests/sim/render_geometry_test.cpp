#include "sim/pipeline.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

namespace {

// True when the window rolled by `roll` about the frame centre lies inside the rendered frame.
bool rolledWindowInside(int w, int h, int margin, double roll) {
    const double c = std::cos(roll), s = std::sin(roll);
    for (double x : {-0.5 * w, 0.5 * w}) {
        for (double y : {-0.5 * h, 0.5 * h}) {
            const double rx = c * x - s * y, ry = s * x + c * y;
            if (std::abs(rx) > 0.5 * w + margin + 1e-9 || std::abs(ry) > 0.5 * h + margin + 1e-9) {
                return false;
            }
        }
    }
    return true;
}

TEST(RenderGeometry, RollMarginKeepsTheRolledWindowInside) {
    for (auto [w, h] : {std::pair{720, 486}, std::pair{160, 120}, std::pair{486, 720}}) {
        for (double deg = -180.0; deg <= 180.0; deg += 2.5) {
            const double roll = ig::degToRad(deg);
            const int m = sim::marginForRoll(w, h, roll, 0.05, 0);
            EXPECT_EQ(m % 8, 0);
            for (double d : {-0.05, 0.0, 0.05}) {
                EXPECT_TRUE(rolledWindowInside(w, h, m, roll + d)) << w << "x" << h << " " << deg;
            }
        }
    }
}

TEST(RenderGeometry, RollMarginAddsToTheMotionMarginAndIsBounded) {
    const int w = 720, h = 486;
    const double full = 0.5 * std::hypot(w, h) - 0.5 * h;
    // The need grows until the window's diagonal stands upright (atan(w / h)), then shrinks.
    const double peak = std::atan2(w, h);
    int last = 0;
    for (double deg = 0.0; deg <= 90.0; deg += 5.0) {
        const double roll = ig::degToRad(deg);
        const int m = sim::marginForRoll(w, h, roll, 0.0, 48);
        EXPECT_GE(m, 48);
        EXPECT_LE(m, 48 + static_cast<int>(std::ceil(full)) + 8);
        if (roll <= peak) {
            EXPECT_GE(m, last) << deg;
        } else {
            EXPECT_LE(m, last) << deg;
        }
        last = m;
    }
    EXPECT_EQ(sim::marginForRoll(w, h, 0.0, 0.0, 48), 48);
    EXPECT_EQ(sim::marginForRoll(w, h, peak, 0.0, 48),
              (48 + static_cast<int>(std::ceil(full)) + 7) / 8 * 8);
}

TEST(RenderGeometry, IntrinsicsKeepTheWindowAndWidenOnlyTheMargin) {
    sim::RenderGeometry g;
    ig::Pose level, banked;
    banked.roll = ig::degToRad(45.0);
    const ig::Intrinsics a = sim::renderIntrinsics(g, level);
    const ig::Intrinsics b = sim::renderIntrinsics(g, banked);
    EXPECT_EQ(a.windowWidth(), g.windowWidth);
    EXPECT_EQ(b.windowWidth(), g.windowWidth);
    EXPECT_EQ(b.windowHeight(), g.windowHeight);
    EXPECT_NEAR(a.focal, b.focal, 1e-9);  // same field of view
    EXPECT_GT(b.margin, a.margin);
    g.coverRoll = false;
    EXPECT_EQ(sim::renderIntrinsics(g, banked).margin, g.margin);
}

}  // namespace
