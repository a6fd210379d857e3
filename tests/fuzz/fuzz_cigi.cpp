// Fuzz target: CIGI datagrams (io::cigi::decodeMessage), read as sent by the host and as sent by
// an image generator. What decodes must encode again to a datagram that decodes to the same
// packets; what is refused must say why in a bounded message.
#include <cstdint>
#include <cstdlib>
#include <span>
#include <string>
#include <vector>

#include "fuzz_check.hpp"
#include "io/cigi.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    using namespace io::cigi;
    const std::span<const std::uint8_t> datagram(data, size);
    Message message, again;
    std::string error;
    for (const Sender from : {Sender::Host, Sender::ImageGenerator}) {
        error.clear();
        if (!decodeMessage(datagram, from, message, &error)) {
            if (error.empty()) std::abort();
            fuzz::checkMessage(error, 300);
            continue;
        }
        if (message.packets.empty()) std::abort();
        const std::vector<std::uint8_t> bytes = encodeMessage(message.packets, message.byteOrder);
        if (!decodeMessage(bytes, from, again, &error) || again.packets != message.packets ||
            again.byteOrder != message.byteOrder || again.skippedPackets != 0)
            std::abort();
    }
    return 0;
}
