// Decoding a CIGI datagram into a Message that has grown once allocates nothing: every
// allocation in this test binary goes through the counting operator new below.
#include <gtest/gtest.h>

#include <atomic>
#include <cstdlib>
#include <new>
#include <string>

#include "cigi_samples.hpp"
#include "io/cigi.hpp"

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

namespace io::cigi {
namespace {

TEST(CigiAllocation, DecodingIntoAGrownMessageAllocatesNothing) {
    const auto host = encodeMessage(test::sampleHostPackets(), ByteOrder::Little);
    const auto ig = encodeMessage(test::sampleIgPackets(), ByteOrder::Big);
    Message message;
    std::string error;
    ASSERT_TRUE(decodeMessage(host, Sender::Host, message, &error)) << error;
    const std::size_t before = gAllocations.load();
    bool ok = true;
    for (int i = 0; i < 1000; ++i) {
        ok = ok && decodeMessage(host, Sender::Host, message, &error);
        ok = ok && decodeMessage(ig, Sender::ImageGenerator, message, &error);
    }
    const std::size_t after = gAllocations.load();
    EXPECT_TRUE(ok) << error;
    EXPECT_EQ(after - before, 0u);
}

}  // namespace
}  // namespace io::cigi
