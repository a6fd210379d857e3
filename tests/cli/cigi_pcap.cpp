// Writes the sample CIGI messages (tests/io/cigi_samples.hpp) the way they would cross a network,
// for tools that read them independently of our codec:
//
//   cigi-pcap FILE.pcap      a capture (Ethernet, IPv4, UDP: host 8005 -> IG 8004 and back) of
//                            four datagrams: host and image generator, big- and little-endian
//   cigi-pcap --corpus DIR   the same datagrams and one per packet kind, as raw files (the fuzz
//                            target's seeds)
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <initializer_list>
#include <string>
#include <vector>

#include "io/cigi.hpp"
#include "io/cigi_samples.hpp"

namespace {

using Bytes = std::vector<std::uint8_t>;
using namespace io::cigi;

void putLe32(Bytes& b, std::uint32_t v) {
    for (int i = 0; i < 4; ++i)
        b.push_back(static_cast<std::uint8_t>(v >> (8 * i)));
}
void put(Bytes& b, std::initializer_list<std::uint8_t> bytes) {
    for (const std::uint8_t c : bytes)
        b.push_back(c);
}
void putBe16(Bytes& b, std::uint16_t v) {
    b.push_back(static_cast<std::uint8_t>(v >> 8));
    b.push_back(static_cast<std::uint8_t>(v));
}

// One Ethernet frame holding `payload` in UDP over IPv4 (UDP checksum 0: none, as IPv4 allows).
Bytes frame(const Bytes& payload, std::uint16_t srcPort, std::uint16_t dstPort, bool fromHost) {
    // Host 10.0.0.1 (MAC 02:00:00:00:00:01), image generator 10.0.0.2 (MAC ...:02).
    const std::uint8_t src = fromHost ? 1 : 2, dst = fromHost ? 2 : 1;
    Bytes f;
    f.reserve(14 + 20 + 8 + payload.size());
    put(f, {0x02, 0, 0, 0, 0, dst, 0x02, 0, 0, 0, 0, src, 0x08, 0x00});  // Ethernet, IPv4
    const std::size_t ip = f.size();
    put(f, {0x45, 0x00});
    putBe16(f, static_cast<std::uint16_t>(20 + 8 + payload.size()));
    put(f, {0x00, 0x01, 0x40, 0x00, 64, 17, 0x00, 0x00, 10, 0, 0, src, 10, 0, 0, dst});
    std::uint32_t sum = 0;
    for (std::size_t i = 0; i < 20; i += 2)
        sum += (f[ip + i] << 8) | f[ip + i + 1];
    while (sum >> 16)
        sum = (sum & 0xffff) + (sum >> 16);
    f[ip + 10] = static_cast<std::uint8_t>(~sum >> 8);
    f[ip + 11] = static_cast<std::uint8_t>(~sum);
    putBe16(f, srcPort);
    putBe16(f, dstPort);
    putBe16(f, static_cast<std::uint16_t>(8 + payload.size()));
    putBe16(f, 0);
    for (const std::uint8_t c : payload)
        f.push_back(c);
    return f;
}

struct Datagram {
    std::string name;
    Bytes bytes;
    bool fromHost;
};

std::vector<Datagram> datagrams() {
    std::vector<Datagram> v;
    for (const ByteOrder order : {ByteOrder::Big, ByteOrder::Little}) {
        const std::string o = order == ByteOrder::Big ? "big" : "little";
        v.push_back({"host_" + o, encodeMessage(test::sampleHostPackets(), order), true});
        v.push_back({"ig_" + o, encodeMessage(test::sampleIgPackets(), order), false});
    }
    return v;
}

bool writeFile(const std::filesystem::path& path, const Bytes& b) {
    std::ofstream out(path, std::ios::binary);
    out.write(reinterpret_cast<const char*>(b.data()), static_cast<std::streamsize>(b.size()));
    return static_cast<bool>(out.flush());
}

}  // namespace

int main(int argc, char** argv) {
    if (argc == 3 && std::string(argv[1]) == "--corpus") {
        const std::filesystem::path dir = argv[2];
        std::filesystem::create_directories(dir);
        std::vector<Datagram> all = datagrams();
        for (const auto& [packets, host] : {std::pair{test::sampleHostPackets(), true},
                                            std::pair{test::sampleIgPackets(), false}}) {
            for (std::size_t i = 1; i < packets.size(); ++i) {
                const std::vector<Packet> two{packets[0], packets[i]};
                all.push_back({(host ? "host_" : "ig_") + std::to_string(i),
                               encodeMessage(two, i % 2 ? ByteOrder::Big : ByteOrder::Little),
                               host});
            }
        }
        for (const Datagram& d : all) {
            if (!writeFile(dir / (d.name + ".cigi"), d.bytes)) {
                std::fprintf(stderr, "cigi-pcap: cannot write %s\n", (dir / d.name).c_str());
                return 1;
            }
        }
        return 0;
    }
    if (argc != 2) {
        std::fprintf(stderr, "usage: cigi-pcap FILE.pcap | cigi-pcap --corpus DIR\n");
        return 2;
    }
    Bytes pcap;
    putLe32(pcap, 0xa1b2c3d4);  // microsecond timestamps, little-endian file
    put(pcap, {2, 0, 4, 0});    // version 2.4
    putLe32(pcap, 0);           // time zone
    putLe32(pcap, 0);           // accuracy
    putLe32(pcap, 65535);       // snapshot length
    putLe32(pcap, 1);           // Ethernet
    std::uint32_t t = 0;
    for (const Datagram& d : datagrams()) {
        const Bytes f =
            d.fromHost ? frame(d.bytes, 8005, 8004, true) : frame(d.bytes, 8004, 8005, false);
        putLe32(pcap, 1700000000u + t++);
        putLe32(pcap, 0);
        putLe32(pcap, static_cast<std::uint32_t>(f.size()));
        putLe32(pcap, static_cast<std::uint32_t>(f.size()));
        pcap.insert(pcap.end(), f.begin(), f.end());
    }
    if (!writeFile(argv[1], pcap)) {
        std::fprintf(stderr, "cigi-pcap: cannot write %s\n", argv[1]);
        return 1;
    }
    return 0;
}
