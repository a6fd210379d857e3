// Decoding a CIGI datagram into a Message that has grown once allocates nothing: every
// allocation in this test binary goes through the counting operator new
// (tests/common/counting_new.cpp).
#include <gtest/gtest.h>

#include "common/counting_new.hpp"

#include <atomic>
#include <cstdlib>
#include <new>
#include <string>

#include "cigi_samples.hpp"
#include "io/cigi.hpp"

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
