// A CIGI host on loopback for the session tests: sends messages (IG Control first) and reads what
// the image generator sent.
#pragma once

#include "io/cigi.hpp"
#include "io/udp_socket.hpp"

#include <gtest/gtest.h>

#include <cerrno>
#include <cstdint>
#include <span>
#include <string>
#include <utility>
#include <vector>

namespace vig_test {

constexpr std::uint32_t kLoopback = 0x7f000001;

struct CigiHost {
    io::UdpSocket socket;
    io::UdpEndpoint ig;
    std::uint32_t frame = 0;

    CigiHost() { EXPECT_EQ(socket.open({kLoopback, 0}), 0); }

    void sendRaw(const std::vector<std::uint8_t>& bytes) { ASSERT_EQ(socket.sendTo(bytes, ig), 0); }
    std::vector<std::uint8_t> encode(std::vector<io::cigi::Packet> packets,
                                     io::cigi::IgMode mode = io::cigi::IgMode::Operate) {
        io::cigi::IgControl control;
        control.igMode = mode;
        control.hostFrameNumber = ++frame;
        control.timestamp = frame * 1000;
        control.timestampValid = true;
        packets.insert(packets.begin(), control);
        return io::cigi::encodeMessage(packets, io::cigi::ByteOrder::Big);
    }
    void send(std::vector<io::cigi::Packet> packets,
              io::cigi::IgMode mode = io::cigi::IgMode::Operate) {
        sendRaw(encode(std::move(packets), mode));
    }
    // Every datagram waiting (loopback delivers before sendto returns).
    std::vector<io::cigi::Message> receiveAll() {
        std::vector<io::cigi::Message> out;
        std::vector<std::uint8_t> buffer(65536);
        while (true) {
            const long n = socket.receive(buffer);
            if (n == -EAGAIN) break;
            EXPECT_GT(n, 0);
            if (n <= 0) break;
            io::cigi::Message m;
            std::string error;
            EXPECT_TRUE(io::cigi::decodeMessage(
                std::span<const std::uint8_t>(buffer.data(), static_cast<std::size_t>(n)),
                io::cigi::Sender::ImageGenerator, m, &error))
                << error;
            out.push_back(std::move(m));
        }
        return out;
    }
};

}  // namespace vig_test
