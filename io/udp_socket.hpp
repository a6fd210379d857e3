// A non-blocking IPv4 UDP socket: bind, send a datagram, take the datagrams already waiting.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <string_view>

namespace io {

struct UdpEndpoint {
    std::uint32_t address = 0;  // IPv4, host byte order (0: any)
    std::uint16_t port = 0;
    bool operator==(const UdpEndpoint&) const = default;
};

// "ADDR:PORT" or, with `addressOptional`, "PORT" (address 0.0.0.0). ADDR is a dotted IPv4
// address ("localhost" is 127.0.0.1); PORT 0..65535 (0 only where `allowPortZero`). Returns an
// empty string, or what is wrong with the text.
std::string parseUdpEndpoint(std::string_view text, bool addressOptional, bool allowPortZero,
                             UdpEndpoint& out);
// "127.0.0.1:8004".
std::string toString(const UdpEndpoint& endpoint);

// Every call returns at once; errors come back as -errno, never as exceptions.
class UdpSocket {
  public:
    UdpSocket() = default;
    ~UdpSocket();
    UdpSocket(UdpSocket&& other) noexcept;
    UdpSocket& operator=(UdpSocket&& other) noexcept;
    UdpSocket(const UdpSocket&) = delete;
    UdpSocket& operator=(const UdpSocket&) = delete;

    // Opens a non-blocking socket bound to `local` (port 0: one the system picks), asking for a
    // receive buffer of `receiveBufferBytes` (0: the system's default; the system may give
    // less). 0 or -errno.
    int open(const UdpEndpoint& local, int receiveBufferBytes = 0);
    void close();
    bool isOpen() const { return fd_ >= 0; }
    // The address and port bound (after open).
    UdpEndpoint localEndpoint() const;

    // Sends one datagram. 0, or -errno (-EAGAIN when the send buffer is full: the datagram is
    // dropped, nothing waits).
    int sendTo(std::span<const std::uint8_t> bytes, const UdpEndpoint& to);

    // Takes one waiting datagram into `buffer`: its length in bytes (which may exceed the
    // buffer: the datagram was cut, and only buffer.size() bytes are there), -EAGAIN when none
    // waits, or another -errno.
    long receive(std::span<std::uint8_t> buffer, UdpEndpoint* from = nullptr);
    // Datagrams the kernel dropped since open() because the receive buffer was full, as it had
    // counted them when the last datagram received was queued (SO_RXQ_OVFL; drops after that
    // show with the next datagram; 0 where the system does not say).
    std::uint64_t droppedByKernel() const { return dropped_; }
    // The receive buffer the system granted, in bytes (0 when closed).
    int receiveBufferBytes() const;
    // Asks the kernel to stamp each datagram's arrival (SO_TIMESTAMPNS, CLOCK_REALTIME): 0 or
    // -errno. The stamp of the last datagram received is then arrivalRealtimeNs() (0 without).
    int stampArrivals();
    std::int64_t arrivalRealtimeNs() const { return arrivalNs_; }

  private:
    int fd_ = -1;
    std::uint64_t dropped_ = 0;
    std::int64_t arrivalNs_ = 0;
};

}  // namespace io
