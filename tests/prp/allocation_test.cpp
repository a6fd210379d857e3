// After its first field the processor allocates nothing: every allocation in this test binary
// goes through the counting operator new (tests/common/counting_new.cpp), and a run of fields must
// not move the count.
#include "prp/processor.hpp"

#include "prp/synthetic_frame.hpp"

#include <gtest/gtest.h>

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

}  // namespace
}  // namespace prp
