// After its first field the processor allocates nothing: every allocation in this test binary
// goes through the counting operator new (tests/common/counting_new.cpp), and a run of fields must
// not move the count.
#include "prp/processor.hpp"

#include "prp/synthetic_frame.hpp"

#include <gtest/gtest.h>

#include <vector>

#include "common/counting_new.hpp"

namespace prp {
namespace {

TEST(ProcessorAllocation, NoneAfterTheFirstField) {
    const ig::Intrinsics in = ig::Intrinsics::fromFov(96, 72, 1.0, 12);
    const ig::Pose pose = test::lookingDown(-40.0);
    const ig::RenderedFrame frame = test::renderPlane(pose, in);
    for (const WarpModel model : {WarpModel::Poly, WarpModel::Affine, WarpModel::Homography,
                                  WarpModel::Depth, WarpModel::Hold, WarpModel::Auto}) {
        for (const PixelFormat format : {PixelFormat::Uyvy, PixelFormat::Rgb8, PixelFormat::Y8}) {
            PrpOptions o;
            o.outWidth = in.windowWidth();
            o.outHeight = in.windowHeight();
            o.format = format;
            o.model = model;
            PostRenderingProcessor processor(o);
            Field field;
            processor.process(frame, pose, 0.0, 0, field);
            const std::size_t before = gAllocations.load();
            for (std::uint64_t i = 1; i < 8; ++i) {
                ig::Pose p = pose;
                p.yaw += 0.002 * static_cast<double>(i);
                p.roll = 0.01 * static_cast<double>(i % 3);
                processor.process(frame, p, fieldTime(0.0, i), i, field);
            }
            EXPECT_EQ(gAllocations.load(), before)
                << warpModelName(model) << " " << pixelFormatName(format);
            ASSERT_EQ(field.index, 7u);
        }
    }
}

// A banking flight: the renderer widens its frames of the same window as the roll grows (up to
// a margin covering any roll), and a processor warmed up on the level frame allocates nothing
// for the wider ones, the depth warp's and the anti-twitter filter's buffers included.
TEST(ProcessorAllocation, NoneForFramesWidenedForRollAfterWarmUp) {
    const int width = 96, height = 72;
    const ig::Pose pose = test::lookingDown(-40.0);
    // Margins from the level frame's to one covering every roll (half the window's diagonal
    // less half its shorter side more), as the renderer widens them.
    std::vector<ig::RenderedFrame> frames;
    std::uint64_t sequence = 0;
    for (const int margin : {12, 16, 24, 32, 40}) {
        frames.push_back(test::renderPlane(
            pose, ig::Intrinsics::fromFov(width, height, 1.0, margin), 0.0, sequence++));
    }
    for (const WarpModel model : {WarpModel::Depth, WarpModel::Auto}) {
        PrpOptions o;
        o.outWidth = width;
        o.outHeight = height;
        o.model = model;
        PostRenderingProcessor processor(o);
        processor.warmUp(frames.front());
        Field field;
        std::size_t before = 0;
        std::uint64_t index = 0;
        for (const ig::RenderedFrame& frame : frames) {
            for (int k = 0; k < 2; ++k, ++index) {
                ig::Pose p = pose;
                p.roll = 0.35 * static_cast<double>(index);  // to 3.15 rad
                processor.process(frame, p, fieldTime(0.0, index), index, field);
                // From the first field on (it sizes the field's own buffers, not the frame's).
                if (index == 0) before = gAllocations.load();
            }
        }
        EXPECT_EQ(gAllocations.load(), before) << warpModelName(model);
        EXPECT_EQ(field.index, index - 1);
    }
}

}  // namespace
}  // namespace prp
