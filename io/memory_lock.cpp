#include "io/memory_lock.hpp"

#include <sys/mman.h>
#include <sys/resource.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <string>

namespace io {

namespace {

#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
constexpr bool kSanitized = true;
#elif defined(__has_feature)
#if __has_feature(address_sanitizer) || __has_feature(thread_sanitizer) || \
    __has_feature(memory_sanitizer)
constexpr bool kSanitized = true;
#else
constexpr bool kSanitized = false;
#endif
#else
constexpr bool kSanitized = false;
#endif

}  // namespace

MemoryLock lockAllMemory() {
    MemoryLock result;
    if (kSanitized) {
        result.error = "not attempted under a sanitizer";
        return result;
    }
    if (mlockall(MCL_CURRENT | MCL_FUTURE) == 0) {
        result.locked = true;
        return result;
    }
    const int err = errno;
    result.error = std::strerror(err);
    rlimit limit{};
    if (getrlimit(RLIMIT_MEMLOCK, &limit) == 0 && limit.rlim_cur != RLIM_INFINITY) {
        char buf[64];
        std::snprintf(buf, sizeof buf, " (RLIMIT_MEMLOCK %llu KiB)",
                      static_cast<unsigned long long>(limit.rlim_cur / 1024));
        result.error += buf;
    }
    return result;
}

long long lockedBytes() {
    std::ifstream in("/proc/self/status");
    std::string line;
    while (std::getline(in, line)) {
        long long kib = 0;
        if (std::sscanf(line.c_str(), "VmLck: %lld kB", &kib) == 1) return kib * 1024;
    }
    return -1;
}

}  // namespace io
