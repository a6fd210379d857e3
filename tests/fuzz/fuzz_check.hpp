// What every fuzz target checks beyond "no crash": messages about bad input stay short.
#pragma once

#include <cstdio>
#include <cstdlib>
#include <string_view>

namespace fuzz {

// A message about bad input quotes at most a bounded part of it (base::quoted), however long or
// binary the input: one longer than `limit` bytes has echoed the input, and stops the run.
inline void checkMessage(std::string_view message, std::size_t limit = 1024) {
    if (message.size() <= limit) return;
    std::fprintf(stderr, "fuzz: a %zu-byte message (at most %zu expected): %.300s...\n",
                 message.size(), limit, std::string_view(message).data());
    std::abort();
}

}  // namespace fuzz
