#include "io/frame_sink.hpp"

#include <charconv>

#include "io/file_sinks.hpp"
#include "io/v4l2_sink.hpp"

namespace io {
namespace {

constexpr int kDefaultPngEvery = 30;  // one woven frame a second at NTSC rates

}  // namespace

std::unique_ptr<FrameSink> makeSink(const std::string& spec, std::string* error, bool overwrite) {
    auto bad = [&](const std::string& why) -> std::unique_ptr<FrameSink> {
        if (error) {
            *error = "output '" + spec + "': " + why +
                     " (expected y4m:PATH, v4l2:/dev/videoN, png:DIR[:EVERY_N] or null)";
        }
        return nullptr;
    };
    const std::size_t colon = spec.find(':');
    const std::string kind = spec.substr(0, colon);
    const std::string rest = colon == std::string::npos ? std::string() : spec.substr(colon + 1);
    if (kind == "null") {
        if (colon != std::string::npos) return bad("null takes no argument");
        return std::make_unique<NullSink>();
    }
    if (colon == std::string::npos || rest.empty()) {
        if (kind == "y4m" || kind == "v4l2" || kind == "png") return bad("missing path");
        return bad("unknown output kind '" + kind + "'");
    }
    if (kind == "y4m") return std::make_unique<Y4mSink>(rest);
    if (kind == "v4l2") return std::make_unique<V4l2Sink>(rest, makeSystemV4l2Device());
    if (kind == "png") {
        std::string dir = rest;
        int every = kDefaultPngEvery;
        const std::size_t last = rest.rfind(':');
        if (last != std::string::npos) {
            const std::string tail = rest.substr(last + 1);
            int n = 0;
            const auto [end, ec] = std::from_chars(tail.data(), tail.data() + tail.size(), n);
            if (ec != std::errc() || end != tail.data() + tail.size() || n < 1) {
                return bad("EVERY_N '" + tail + "' is not a positive whole number");
            }
            dir = rest.substr(0, last);
            every = n;
            if (dir.empty()) return bad("missing directory");
        }
        return std::make_unique<PngSink>(dir, every, overwrite);
    }
    return bad("unknown output kind '" + kind + "'");
}

std::string sinkPath(const std::string& spec) {
    if (spec.rfind("y4m:", 0) == 0) return spec.substr(4);
    if (spec.rfind("png:", 0) == 0) {
        const std::string rest = spec.substr(4);
        const std::size_t last = rest.rfind(':');
        if (last != std::string::npos && last + 1 < rest.size() &&
            rest.find_first_not_of("0123456789", last + 1) == std::string::npos) {
            return rest.substr(0, last);
        }
        return rest;
    }
    return {};
}

bool sinkWritesFolder(const std::string& spec) {
    return spec.rfind("png:", 0) == 0;
}

}  // namespace io
