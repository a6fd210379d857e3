#include "base/text.hpp"

#include <cstdio>

namespace base {

std::string quoted(std::string_view text, std::size_t limit) {
    std::string out = "'";
    const std::size_t shown = text.size() < limit ? text.size() : limit;
    for (std::size_t i = 0; i < shown; ++i) {
        const auto c = static_cast<unsigned char>(text[i]);
        if (c >= 0x20 && c < 0x7f && c != '\'' && c != '\\') {
            out += static_cast<char>(c);
        } else {
            char buf[8];
            std::snprintf(buf, sizeof buf, "\\x%02x", c);
            out += buf;
        }
    }
    if (shown < text.size()) {
        out += "...' (" + std::to_string(text.size()) + " bytes)";
    } else {
        out += "'";
    }
    return out;
}

std::string number(double value, int digits) {
    char buf[64];
    std::snprintf(buf, sizeof buf, "%.*g", digits < 1 ? 1 : (digits > 17 ? 17 : digits), value);
    return buf;
}

}  // namespace base
