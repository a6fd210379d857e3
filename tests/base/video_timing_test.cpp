#include "base/video_timing.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

TEST(FieldTime, IsExactForEveryIndex) {
    // 1001/60000 s = 50050000/3 ns: every third field lands on a whole nanosecond.
    for (std::uint64_t n :
         {0ull, 1ull, 2ull, 3ull, 59940ull, 3600ull * 60000 / 1001 * 24, 1ull << 33}) {
        EXPECT_EQ(base::fieldTimeNs(3 * n), static_cast<std::int64_t>(n * 50050000ull)) << n;
        const double t = base::fieldTime(0.0, 3 * n);
        EXPECT_NEAR(t, static_cast<double>(n) * 0.05005, 1e-15 * std::max(1.0, t) * 4) << n;
    }
    EXPECT_EQ(base::fieldTimeNs(1), 16683333);
    EXPECT_EQ(base::fieldTime(0.0, 60000), 1001.0);
    EXPECT_EQ(base::fieldTime(5.0, 0), 5.0);
    EXPECT_DOUBLE_EQ(base::kFieldPeriod, 1001.0 / 60000.0);
}

TEST(FieldTime, DoesNotDriftOverADay) {
    // A running sum of the period drifts; the instant from the index does not.
    const std::uint64_t day = 24ull * 3600 * 60000 / 1001;
    const double exact = static_cast<double>(day) * 1001.0 / 60000.0;
    EXPECT_EQ(base::fieldTime(0.0, day), exact);
}

TEST(FieldParity, BottomFirstThenAlternating) {
    EXPECT_EQ(base::fieldParity(0), base::FieldParity::Bottom);
    EXPECT_EQ(base::fieldParity(1), base::FieldParity::Top);
    EXPECT_EQ(base::fieldParity(1ull << 40), base::FieldParity::Bottom);
    EXPECT_EQ(base::fieldFirstLine(base::FieldParity::Top), 0);
    EXPECT_EQ(base::fieldFirstLine(base::FieldParity::Bottom), 1);
}

TEST(FieldLines, SplitEveryFrameHeight) {
    for (int h = 0; h < 10; ++h) {
        const int top = base::fieldLines(h, base::FieldParity::Top);
        const int bottom = base::fieldLines(h, base::FieldParity::Bottom);
        EXPECT_EQ(top + bottom, h) << h;
        EXPECT_GE(top, bottom) << h;
    }
    EXPECT_EQ(base::fieldLines(486, base::FieldParity::Bottom), 243);
    EXPECT_EQ(base::fieldLines(-3, base::FieldParity::Top), 0);
}

TEST(PixelFormat, NamesRoundTripAndSizes) {
    for (base::PixelFormat f :
         {base::PixelFormat::Uyvy, base::PixelFormat::Y8, base::PixelFormat::Rgb8}) {
        EXPECT_EQ(base::parsePixelFormat(base::pixelFormatName(f)), f);
    }
    EXPECT_EQ(base::bytesPerPixel(base::PixelFormat::Uyvy), 2);
    EXPECT_EQ(base::bytesPerPixel(base::PixelFormat::Y8), 1);
    EXPECT_EQ(base::bytesPerPixel(base::PixelFormat::Rgb8), 3);
    EXPECT_EQ(base::parsePixelFormat("grey"), base::PixelFormat::Y8);
    EXPECT_FALSE(base::parsePixelFormat("yuyv").has_value());
    EXPECT_FALSE(base::parsePixelFormat("").has_value());
}
