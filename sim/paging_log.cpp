#include "sim/paging_log.hpp"

#include <sys/mman.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <new>
#include <stdexcept>
#include <type_traits>

namespace sim {

static_assert(std::is_trivially_copyable_v<PagingLog::Frame>);
static_assert(std::atomic<std::uint64_t>::is_always_lock_free,
              "the counters are shared between processes");

struct PagingLog::Shared {
    std::atomic<std::uint64_t> frames{0};    // published (kept while below kCapacity)
    std::atomic<std::uint64_t> failures{0};  // published (kept while below kMaxFailures)
    Frame frame[kCapacity];
    char failure[kMaxFailures][kFailureBytes];
};

PagingLog::PagingLog() {
    void* p =
        mmap(nullptr, sizeof(Shared), PROT_READ | PROT_WRITE, MAP_SHARED | MAP_ANONYMOUS, -1, 0);
    if (p == MAP_FAILED) {
        throw std::runtime_error(std::string("paging log: mmap of ") +
                                 std::to_string(sizeof(Shared)) +
                                 " shared bytes: " + std::strerror(errno));
    }
    // A fresh anonymous mapping reads as zeros, which is what both counters start at; only the
    // counters are constructed (the records are written before they are published).
    shared_ = static_cast<Shared*>(p);
    new (&shared_->frames) std::atomic<std::uint64_t>(0);
    new (&shared_->failures) std::atomic<std::uint64_t>(0);
}

PagingLog::~PagingLog() {
    if (shared_ != nullptr) munmap(shared_, sizeof(Shared));
}

void PagingLog::add(const Frame& frame) {
    const std::uint64_t n = shared_->frames.load(std::memory_order_relaxed);
    if (n < kCapacity) shared_->frame[n] = frame;
    shared_->frames.store(n + 1, std::memory_order_release);
}

void PagingLog::addFailure(std::string_view message) {
    const std::uint64_t n = shared_->failures.load(std::memory_order_relaxed);
    if (n < kMaxFailures) {
        char* to = shared_->failure[n];
        const std::size_t len = std::min(message.size(), kFailureBytes - 1);
        std::memcpy(to, message.data(), len);
        to[len] = '\0';
    }
    shared_->failures.store(n + 1, std::memory_order_release);
}

std::vector<PagingLog::Frame> PagingLog::frames() const {
    const std::uint64_t n =
        std::min<std::uint64_t>(shared_->frames.load(std::memory_order_acquire), kCapacity);
    return {shared_->frame, shared_->frame + n};
}

std::vector<std::string> PagingLog::failures() const {
    const std::uint64_t n =
        std::min<std::uint64_t>(shared_->failures.load(std::memory_order_acquire), kMaxFailures);
    std::vector<std::string> out;
    out.reserve(n);
    for (std::uint64_t i = 0; i < n; ++i)
        out.emplace_back(shared_->failure[i]);
    return out;
}

std::uint64_t PagingLog::dropped() const {
    const std::uint64_t n = shared_->frames.load(std::memory_order_acquire);
    return n > kCapacity ? n - kCapacity : 0;
}

}  // namespace sim
