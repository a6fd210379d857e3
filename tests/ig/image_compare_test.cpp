// Error measures and the box filter used by the accuracy tests.
#include "ig/image_compare.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

namespace {

TEST(ImageCompare, MeanAbsErrorIsPercentOfFullScale) {
    const std::vector<ig::Rgb8> a(4, ig::Rgb8{0, 0, 0});
    std::vector<ig::Rgb8> b(4, ig::Rgb8{0, 0, 0});
    b[0] = ig::Rgb8{255, 255, 255};  // one pixel of four fully off
    EXPECT_NEAR(ig::meanAbsErrorPct(a, b), 25.0, 1e-12);
    EXPECT_EQ(ig::meanAbsErrorPct(a, a), 0.0);
}

TEST(ImageCompare, PsnrOfKnownNoiseAndIdenticalImages) {
    const std::vector<ig::Rgb8> a(16, ig::Rgb8{100, 100, 100});
    const std::vector<ig::Rgb8> b(16, ig::Rgb8{110, 90, 100});  // mse = (100 + 100 + 0) / 3
    EXPECT_NEAR(ig::psnrDb(a, b), 10.0 * std::log10(255.0 * 255.0 * 3.0 / 200.0), 1e-9);
    EXPECT_TRUE(std::isinf(ig::psnrDb(a, a)));
    EXPECT_DEATH(ig::psnrDb(a, std::vector<ig::Rgb8>(3)), "one size");
}

TEST(ImageCompare, BoxDownsampleAveragesBlocksWithRounding) {
    // 4x2 source -> 2x1 with f = 2: blocks {0, 1, 2, 3} -> 1.5 -> 2, {10, 10, 11, 11} -> 10.5
    // -> 11.
    const std::vector<ig::Rgb8> src = {{0, 0, 0}, {1, 0, 0}, {10, 0, 0}, {10, 0, 0},
                                       {2, 0, 0}, {3, 0, 0}, {11, 0, 0}, {11, 0, 0}};
    const auto out = ig::boxDownsample(src, 2, 1, 2);
    ASSERT_EQ(out.size(), 2u);
    EXPECT_EQ(out[0].r, 2);
    EXPECT_EQ(out[1].r, 11);
    EXPECT_DEATH(ig::boxDownsample(src, 3, 1, 2), "must hold");
}

}  // namespace
