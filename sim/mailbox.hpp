// Latest-value mailbox: a lock-free triple buffer between one writer and one reader.
#pragma once

#include <array>
#include <atomic>
#include <cstdint>
#include <utility>

namespace sim {

// The writer fills back() and publish()es it; the reader calls fetch() and then reads front(),
// which stays untouched by the writer until the reader's next fetch(). Three slots rotate
// through one atomic word (index + "fresh" bit), so neither side ever waits or sees a torn
// value, and the reader always gets the newest published one (older unread ones are dropped).
// One writer thread and one reader thread at a time.
template <class T>
class Mailbox {
  public:
    Mailbox() = default;
    Mailbox(const Mailbox&) = delete;
    Mailbox& operator=(const Mailbox&) = delete;

    // Writer side.
    T& back() { return slots_[back_]; }
    void publish() {
        const std::uint32_t old = middle_.exchange(back_ | kFresh, std::memory_order_acq_rel);
        back_ = old & kIndexMask;
        published_.fetch_add(1, std::memory_order_relaxed);
    }

    // Reader side: takes the newest published value if there is one not yet taken; true then.
    bool fetch() {
        if ((middle_.load(std::memory_order_acquire) & kFresh) == 0) return false;
        const std::uint32_t old = middle_.exchange(front_, std::memory_order_acq_rel);
        front_ = old & kIndexMask;
        hasFront_ = true;
        return true;
    }
    // The value last fetched; default-constructed before the first fetch.
    const T& front() const { return slots_[front_]; }
    T& front() { return slots_[front_]; }
    bool hasFront() const { return hasFront_; }

    // Values published so far (any thread; informational).
    std::uint64_t published() const { return published_.load(std::memory_order_relaxed); }

  private:
    static constexpr std::uint32_t kFresh = 4;
    static constexpr std::uint32_t kIndexMask = 3;

    std::array<T, 3> slots_{};
    alignas(64) std::atomic<std::uint32_t> middle_{1};
    std::atomic<std::uint64_t> published_{0};
    alignas(64) std::uint32_t back_ = 0;   // writer-owned
    alignas(64) std::uint32_t front_ = 2;  // reader-owned
    bool hasFront_ = false;
};

}  // namespace sim
