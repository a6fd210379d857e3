#include "io/stop_signals.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <array>
#include <csignal>
#include <cstring>
#include <mutex>

namespace io {
namespace {

std::atomic<bool> gStop{false};
std::atomic<int> gSignal{0};
std::atomic<int> gCount{0};
std::atomic<bool> gEndAtOnce{false};

// The registry is read by the handler, so it is fixed-size and lock-free: a slot is claimed
// with a compare-exchange, filled, then published by setting `state` to kReady.
constexpr int kSlots = 16;
constexpr std::size_t kPathMax = 4096;
constexpr int kFree = 0, kFilling = 1, kReady = 2;

struct Slot {
    std::atomic<int> state{kFree};
    int fd = -1;
    std::uint64_t header = 0, record = 0;
    char part[kPathMax] = {};
    char final[kPathMax] = {};
};

std::array<Slot, kSlots> gSlots;

// Only async-signal-safe calls from here on.
void finishOutputsNow() {
    for (Slot& s : gSlots) {
        if (s.state.load(std::memory_order_acquire) != kReady) continue;
        if (s.record > 0 && s.fd >= 0) {
            struct stat st {};
            if (::fstat(s.fd, &st) == 0 && static_cast<std::uint64_t>(st.st_size) >= s.header) {
                const std::uint64_t whole =
                    s.header +
                    (static_cast<std::uint64_t>(st.st_size) - s.header) / s.record * s.record;
                if (::ftruncate(s.fd, static_cast<off_t>(whole)) == 0 && s.final[0] != '\0') {
                    ::rename(s.part, s.final);
                    continue;
                }
            }
        }
        if (s.part[0] != '\0') ::unlink(s.part);
    }
}

extern "C" void onStopSignal(int sig) {
    const int seen = gCount.fetch_add(1);
    if (seen == 0 && !gEndAtOnce.load()) {
        int none = 0;
        gSignal.compare_exchange_strong(none, sig);
        gStop.store(true);
        return;
    }
    int none = 0;
    gSignal.compare_exchange_strong(none, sig);
    finishOutputsNow();
    ::_exit(128 + gSignal.load());
}

}  // namespace

void installStopSignals(bool endAtOnce) {
    gEndAtOnce.store(endAtOnce);
    static std::once_flag once;
    std::call_once(once, [] {
        struct sigaction sa {};
        sa.sa_handler = onStopSignal;
        sigemptyset(&sa.sa_mask);
        sa.sa_flags = SA_RESTART;
        sigaction(SIGINT, &sa, nullptr);
        sigaction(SIGTERM, &sa, nullptr);
    });
}

bool stopRequested() {
    return gStop.load(std::memory_order_acquire);
}

const std::atomic<bool>& stopFlag() {
    return gStop;
}

int stopSignalNumber() {
    return gSignal.load();
}

int exitStatusForStop() {
    const int sig = gSignal.load();
    return sig == 0 ? 0 : 128 + sig;
}

void requestStop(int signal) {
    onStopSignal(signal);
}

void resetStopForTests() {
    gCount.store(0);
    gSignal.store(0);
    gStop.store(false);
}

int registerUnfinishedOutput(int fd, const char* partPath, const char* finalPath,
                             std::uint64_t headerBytes, std::uint64_t recordBytes) {
    const std::size_t partLen = partPath ? std::strlen(partPath) : 0;
    const std::size_t finalLen = finalPath ? std::strlen(finalPath) : 0;
    if (partLen >= kPathMax || finalLen >= kPathMax) return -1;
    for (int i = 0; i < kSlots; ++i) {
        Slot& s = gSlots[static_cast<std::size_t>(i)];
        int expected = kFree;
        if (!s.state.compare_exchange_strong(expected, kFilling)) continue;
        s.fd = fd;
        s.header = headerBytes;
        s.record = recordBytes;
        std::memcpy(s.part, partPath ? partPath : "", partLen + 1);
        std::memcpy(s.final, finalPath ? finalPath : "", finalLen + 1);
        s.state.store(kReady, std::memory_order_release);
        return i;
    }
    return -1;
}

void unregisterUnfinishedOutput(int slot) {
    if (slot < 0 || slot >= kSlots) return;
    gSlots[static_cast<std::size_t>(slot)].state.store(kFree, std::memory_order_release);
}

}  // namespace io
