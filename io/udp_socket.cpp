#include "io/udp_socket.hpp"

#include <arpa/inet.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <sys/uio.h>
#include <unistd.h>

#include <cerrno>
#include <charconv>
#include <cstdio>
#include <cstring>
#include <utility>

namespace io {

namespace {

sockaddr_in toSockaddr(const UdpEndpoint& e) {
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_port = htons(e.port);
    a.sin_addr.s_addr = htonl(e.address);
    return a;
}

UdpEndpoint fromSockaddr(const sockaddr_in& a) {
    return {ntohl(a.sin_addr.s_addr), ntohs(a.sin_port)};
}

bool parsePort(std::string_view text, bool allowZero, std::uint16_t& port) {
    if (text.empty() || text.size() > 5) return false;
    unsigned value = 0;
    const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), value);
    if (ec != std::errc() || end != text.data() + text.size() || value > 65535) return false;
    if (value == 0 && !allowZero) return false;
    port = static_cast<std::uint16_t>(value);
    return true;
}

}  // namespace

std::string parseUdpEndpoint(std::string_view text, bool addressOptional, bool allowPortZero,
                             UdpEndpoint& out) {
    const std::size_t colon = text.rfind(':');
    std::string_view addressText, portText = text;
    if (colon != std::string_view::npos) {
        addressText = text.substr(0, colon);
        portText = text.substr(colon + 1);
    } else if (!addressOptional) {
        return "expected ADDR:PORT";
    }
    UdpEndpoint e;
    if (!parsePort(portText, allowPortZero, e.port)) {
        return allowPortZero ? "the port must be a number 0..65535"
                             : "the port must be a number 1..65535";
    }
    if (colon != std::string_view::npos) {
        if (addressText == "localhost") {
            e.address = INADDR_LOOPBACK;
        } else {
            const std::string address(addressText);
            in_addr a{};
            if (address.empty() || inet_pton(AF_INET, address.c_str(), &a) != 1) {
                return "the address must be a dotted IPv4 address such as 127.0.0.1";
            }
            e.address = ntohl(a.s_addr);
        }
    }
    out = e;
    return {};
}

std::string toString(const UdpEndpoint& e) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "%u.%u.%u.%u:%u", (e.address >> 24) & 255u,
                  (e.address >> 16) & 255u, (e.address >> 8) & 255u, e.address & 255u, e.port);
    return buf;
}

UdpSocket::~UdpSocket() {
    close();
}

UdpSocket::UdpSocket(UdpSocket&& other) noexcept
    : fd_(std::exchange(other.fd_, -1)), dropped_(std::exchange(other.dropped_, 0)) {}

UdpSocket& UdpSocket::operator=(UdpSocket&& other) noexcept {
    if (this != &other) {
        close();
        fd_ = std::exchange(other.fd_, -1);
        dropped_ = std::exchange(other.dropped_, 0);
    }
    return *this;
}

int UdpSocket::open(const UdpEndpoint& local, int receiveBufferBytes) {
    close();
    const int fd = ::socket(AF_INET, SOCK_DGRAM | SOCK_NONBLOCK | SOCK_CLOEXEC, 0);
    if (fd < 0) return -errno;
    const sockaddr_in a = toSockaddr(local);
    if (::bind(fd, reinterpret_cast<const sockaddr*>(&a), sizeof a) != 0) {
        const int err = errno;
        ::close(fd);
        return -err;
    }
    // The kernel counts the datagrams it drops for want of buffer room (SO_RXQ_OVFL) and
    // reports the total with each one received; a larger buffer rides out a burst. Both are
    // best effort: a system that refuses them still receives.
    const int one = 1;
    ::setsockopt(fd, SOL_SOCKET, SO_RXQ_OVFL, &one, sizeof one);
    if (receiveBufferBytes > 0) {
        ::setsockopt(fd, SOL_SOCKET, SO_RCVBUF, &receiveBufferBytes, sizeof receiveBufferBytes);
    }
    fd_ = fd;
    dropped_ = 0;
    return 0;
}

int UdpSocket::stampArrivals() {
    if (fd_ < 0) return -EBADF;
    const int one = 1;
    if (::setsockopt(fd_, SOL_SOCKET, SO_TIMESTAMPNS, &one, sizeof one) != 0) return -errno;
    return 0;
}

void UdpSocket::close() {
    if (fd_ >= 0) ::close(fd_);
    fd_ = -1;
}

UdpEndpoint UdpSocket::localEndpoint() const {
    sockaddr_in a{};
    socklen_t len = sizeof a;
    if (fd_ < 0 || ::getsockname(fd_, reinterpret_cast<sockaddr*>(&a), &len) != 0) return {};
    return fromSockaddr(a);
}

int UdpSocket::receiveBufferBytes() const {
    int bytes = 0;
    socklen_t len = sizeof bytes;
    if (fd_ < 0 || ::getsockopt(fd_, SOL_SOCKET, SO_RCVBUF, &bytes, &len) != 0) return 0;
    return bytes;
}

int UdpSocket::sendTo(std::span<const std::uint8_t> bytes, const UdpEndpoint& to) {
    if (fd_ < 0) return -EBADF;
    const sockaddr_in a = toSockaddr(to);
    const ssize_t n = ::sendto(fd_, bytes.data(), bytes.size(), MSG_DONTWAIT | MSG_NOSIGNAL,
                               reinterpret_cast<const sockaddr*>(&a), sizeof a);
    if (n < 0) return -errno;
    return 0;
}

long UdpSocket::receive(std::span<std::uint8_t> buffer, UdpEndpoint* from) {
    if (fd_ < 0) return -EBADF;
    sockaddr_in a{};
    iovec iov{buffer.data(), buffer.size()};
    alignas(cmsghdr) unsigned char
        control[CMSG_SPACE(sizeof(std::uint32_t)) + CMSG_SPACE(sizeof(timespec))];
    msghdr msg{};
    msg.msg_name = &a;
    msg.msg_namelen = sizeof a;
    msg.msg_iov = &iov;
    msg.msg_iovlen = 1;
    msg.msg_control = control;
    msg.msg_controllen = sizeof control;
    // MSG_TRUNC: the datagram's real length comes back even when it did not fit.
    const ssize_t n = ::recvmsg(fd_, &msg, MSG_DONTWAIT | MSG_TRUNC);
    if (n < 0) return errno == EWOULDBLOCK ? -EAGAIN : -errno;
    for (cmsghdr* c = CMSG_FIRSTHDR(&msg); c; c = CMSG_NXTHDR(&msg, c)) {
        if (c->cmsg_level == SOL_SOCKET && c->cmsg_type == SO_RXQ_OVFL &&
            c->cmsg_len >= CMSG_LEN(sizeof(std::uint32_t))) {
            std::uint32_t total = 0;
            std::memcpy(&total, CMSG_DATA(c), sizeof total);
            dropped_ = total;
        } else if (c->cmsg_level == SOL_SOCKET && c->cmsg_type == SCM_TIMESTAMPNS &&
                   c->cmsg_len >= CMSG_LEN(sizeof(timespec))) {
            timespec ts{};
            std::memcpy(&ts, CMSG_DATA(c), sizeof ts);
            arrivalNs_ = static_cast<std::int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
        }
    }
    if (from) *from = fromSockaddr(a);
    return static_cast<long>(n);
}

}  // namespace io
