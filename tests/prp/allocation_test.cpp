// After its first field the processor allocates nothing: every allocation in this test binary
// goes through the counting operator new below, and a run of fields must not move the count.
#include "prp/processor.hpp"

#include "prp/synthetic_frame.hpp"

#include <gtest/gtest.h>

#include <atomic>
#include <cstdlib>
#include <new>

namespace {
std::atomic<std::size_t> gAllocations{0};
}  // namespace

void* operator new(std::size_t size) {
    gAllocations.fetch_add(1, std::memory_order_relaxed);
    if (void* p = std::malloc(size == 0 ? 1 : size)) return p;
    throw std::bad_alloc();
}

void* operator new[](std::size_t size) {
    return ::operator new(size);
}

void* operator new(std::size_t size, std::align_val_t align) {
    gAllocations.fetch_add(1, std::memory_order_relaxed);
    const auto a = static_cast<std::size_t>(align);
    if (void* p = std::aligned_alloc(a, (size + a - 1) / a * a)) return p;
    throw std::bad_alloc();
}

void* operator new[](std::size_t size, std::align_val_t align) {
    return ::operator new(size, align);
}

void operator delete(void* p) noexcept {
    std::free(p);
}
void operator delete[](void* p) noexcept {
    std::free(p);
}
void operator delete(void* p, std::size_t) noexcept {
    std::free(p);
}
void operator delete[](void* p, std::size_t) noexcept {
    std::free(p);
}
void operator delete(void* p, std::align_val_t) noexcept {
    std::free(p);
}
void operator delete[](void* p, std::align_val_t) noexcept {
    std::free(p);
}
void operator delete(void* p, std::size_t, std::align_val_t) noexcept {
    std::free(p);
}
void operator delete[](void* p, std::size_t, std::align_val_t) noexcept {
    std::free(p);
}

namespace prp {
namespace {

TEST(ProcessorAllocation, NoneAfterTheFirstField) {
    const ig::Intrinsics in = ig::Intrinsics::fromFov(96, 72, 1.0, 12);
    const ig::Pose pose = test::lookingDown(-40.0);
    const ig::RenderedFrame frame = test::renderPlane(pose, in);
    for (const WarpModel model : {WarpModel::Poly, WarpModel::Affine, WarpModel::Homography,
                                  WarpModel::Depth, WarpModel::Hold}) {
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
