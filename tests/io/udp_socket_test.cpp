#include "io/udp_socket.hpp"

#include <gtest/gtest.h>

#include <cerrno>
#include <chrono>
#include <cstdint>
#include <vector>

namespace {

constexpr std::uint32_t kLoopback = 0x7f000001;

// Loopback delivery is immediate on Linux, but allow the kernel a moment anyway.
long receiveWithin(io::UdpSocket& s, std::span<std::uint8_t> buffer, io::UdpEndpoint* from) {
    const auto until = std::chrono::steady_clock::now() + std::chrono::seconds(2);
    long n = -EAGAIN;
    while (n == -EAGAIN && std::chrono::steady_clock::now() < until)
        n = s.receive(buffer, from);
    return n;
}

TEST(UdpEndpoint, ParsesAddressAndPort) {
    io::UdpEndpoint e;
    EXPECT_EQ(io::parseUdpEndpoint("127.0.0.1:8004", false, false, e), "");
    EXPECT_EQ(e, (io::UdpEndpoint{kLoopback, 8004}));
    EXPECT_EQ(io::toString(e), "127.0.0.1:8004");
    EXPECT_EQ(io::parseUdpEndpoint("8005", true, false, e), "");
    EXPECT_EQ(e, (io::UdpEndpoint{0, 8005}));
    EXPECT_EQ(io::parseUdpEndpoint("localhost:0", true, true, e), "");
    EXPECT_EQ(e, (io::UdpEndpoint{kLoopback, 0}));
}

TEST(UdpEndpoint, RefusesWhatIsNotAnEndpoint) {
    io::UdpEndpoint e{1, 2};
    for (const char* bad : {"", "8004", ":8004", "1.2.3:80", "1.2.3.4:", "1.2.3.4:65536",
                            "1.2.3.4:-1", "1.2.3.4:80x", "host.example:80", "1.2.3.4:0"}) {
        EXPECT_NE(io::parseUdpEndpoint(bad, false, false, e), "") << bad;
    }
    EXPECT_NE(io::parseUdpEndpoint("x", true, false, e), "");
    EXPECT_EQ(e, (io::UdpEndpoint{1, 2})) << "a refused text leaves the endpoint as it was";
}

TEST(UdpSocket, SendsAndReceivesOverLoopbackWithoutWaiting) {
    io::UdpSocket a, b;
    ASSERT_EQ(a.open({kLoopback, 0}), 0);
    ASSERT_EQ(b.open({kLoopback, 0}), 0);
    const io::UdpEndpoint aEnd = a.localEndpoint(), bEnd = b.localEndpoint();
    EXPECT_EQ(aEnd.address, kLoopback);
    EXPECT_NE(aEnd.port, 0);

    std::vector<std::uint8_t> buffer(64);
    // Nothing waiting: answered at once.
    const auto before = std::chrono::steady_clock::now();
    EXPECT_EQ(b.receive(buffer), -EAGAIN);
    EXPECT_LT(std::chrono::steady_clock::now() - before, std::chrono::milliseconds(100));

    for (std::uint8_t i = 0; i < 5; ++i) {
        const std::uint8_t bytes[3] = {i, 7, 9};
        ASSERT_EQ(a.sendTo(bytes, bEnd), 0);
    }
    for (std::uint8_t i = 0; i < 5; ++i) {
        io::UdpEndpoint from;
        ASSERT_EQ(receiveWithin(b, buffer, &from), 3);
        EXPECT_EQ(buffer[0], i);
        EXPECT_EQ(from, aEnd);
    }
    EXPECT_EQ(b.receive(buffer), -EAGAIN);
}

TEST(UdpSocket, StampsArrivalsOnTheRealtimeClock) {
    io::UdpSocket a, b;
    ASSERT_EQ(a.open({kLoopback, 0}), 0);
    ASSERT_EQ(b.open({kLoopback, 0}), 0);
    std::vector<std::uint8_t> buffer(16);
    EXPECT_EQ(b.arrivalRealtimeNs(), 0);
    ASSERT_EQ(b.stampArrivals(), 0);
    const auto ns = [] {
        return std::chrono::duration_cast<std::chrono::nanoseconds>(
                   std::chrono::system_clock::now().time_since_epoch())
            .count();
    };
    const std::int64_t before = ns();
    ASSERT_EQ(a.sendTo(std::vector<std::uint8_t>{1, 2, 3}, b.localEndpoint()), 0);
    // Loopback may finish the delivery (and stamp it) just after sendto returns: wait for it.
    long n = -EAGAIN;
    for (int tries = 0; tries < 1000 && n == -EAGAIN; ++tries)
        n = b.receive(buffer);
    const std::int64_t after = ns();
    ASSERT_EQ(n, 3);
    // Stamped between sending and receiving.
    EXPECT_GE(b.arrivalRealtimeNs(), before);
    EXPECT_LE(b.arrivalRealtimeNs(), after);
}

TEST(UdpSocket, ReportsTheLengthOfACutDatagram) {
    io::UdpSocket a, b;
    ASSERT_EQ(a.open({kLoopback, 0}), 0);
    ASSERT_EQ(b.open({kLoopback, 0}), 0);
    const std::vector<std::uint8_t> big(1000, 0xab);
    ASSERT_EQ(a.sendTo(big, b.localEndpoint()), 0);
    std::vector<std::uint8_t> small(16);
    EXPECT_EQ(receiveWithin(b, small, nullptr), 1000);
    EXPECT_EQ(small[15], 0xab);
}

TEST(UdpSocket, ErrorsAreReturnedNotThrown) {
    io::UdpSocket a, b;
    std::vector<std::uint8_t> buffer(8);
    EXPECT_EQ(a.receive(buffer), -EBADF);
    EXPECT_EQ(a.sendTo(buffer, {kLoopback, 9}), -EBADF);
    ASSERT_EQ(a.open({kLoopback, 0}), 0);
    // The same port twice: refused with EADDRINUSE.
    EXPECT_EQ(b.open(a.localEndpoint()), -EADDRINUSE);
    EXPECT_FALSE(b.isOpen());
    // A moved socket keeps its descriptor.
    io::UdpSocket c = std::move(a);
    EXPECT_TRUE(c.isOpen());
    EXPECT_FALSE(a.isOpen());
}

}  // namespace

namespace {

// The kernel's count of datagrams dropped for want of room reaches the socket: a burst far
// beyond a small receive buffer, then every datagram received plus every one dropped is every
// one sent.
TEST(UdpSocket, CountsTheDatagramsTheKernelDropped) {
    io::UdpSocket sender, receiver;
    ASSERT_EQ(sender.open({kLoopback, 0}), 0);
    ASSERT_EQ(receiver.open({kLoopback, 0}, 4096), 0);  // the kernel doubles it, with a floor
    EXPECT_GT(receiver.receiveBufferBytes(), 0);
    const io::UdpEndpoint to = receiver.localEndpoint();
    constexpr int kSent = 2000;
    const std::vector<std::uint8_t> bytes(200, 0x5a);
    int sent = 0;
    for (int i = 0; i < kSent; ++i)
        sent += sender.sendTo(bytes, to) == 0 ? 1 : 0;
    ASSERT_GT(sent, 1000);
    std::vector<std::uint8_t> buffer(256);
    long received = 0;
    while (receiver.receive(buffer) > 0)
        ++received;
    ASSERT_GT(received, 0);
    EXPECT_LT(received, sent) << "the buffer held them all: the test proves nothing";
    // The count travels with each datagram as it was when the datagram was queued: one sent
    // after the burst brings the whole of it.
    ASSERT_EQ(sender.sendTo(bytes, to), 0);
    ASSERT_EQ(receiveWithin(receiver, buffer, nullptr), 200);
    EXPECT_EQ(static_cast<std::uint64_t>(received) + receiver.droppedByKernel(),
              static_cast<std::uint64_t>(sent));
}

}  // namespace
