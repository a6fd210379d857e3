#include "sim/mailbox.hpp"

#include <gtest/gtest.h>

#include <array>
#include <atomic>
#include <cstdint>
#include <thread>
#include <vector>

namespace {

struct Payload {
    std::uint64_t sequence = 0;
    std::array<std::uint64_t, 32> words{};  // every word == sequence when not torn
    std::vector<std::uint64_t> heap;        // as a frame's buffers: moved in, not copied
};

TEST(Mailbox, NothingToFetchBeforePublish) {
    sim::Mailbox<int> box;
    EXPECT_FALSE(box.fetch());
    EXPECT_FALSE(box.hasFront());
    box.back() = 5;
    box.publish();
    EXPECT_TRUE(box.fetch());
    EXPECT_TRUE(box.hasFront());
    EXPECT_EQ(box.front(), 5);
    EXPECT_FALSE(box.fetch());  // already taken
    EXPECT_EQ(box.front(), 5);  // and still there
}

TEST(Mailbox, ReaderGetsNewestAndDropsOlder) {
    for (int burst = 1; burst <= 6; ++burst) {
        sim::Mailbox<int> box;
        for (int i = 1; i <= burst; ++i) {
            box.back() = 100 * burst + i;
            box.publish();
        }
        ASSERT_TRUE(box.fetch());
        EXPECT_EQ(box.front(), 100 * burst + burst);
        EXPECT_EQ(box.published(), static_cast<std::uint64_t>(burst));
    }
}

TEST(Mailbox, WriterNeverTouchesTheFrontSlot) {
    sim::Mailbox<int> box;
    box.back() = 1;
    box.publish();
    ASSERT_TRUE(box.fetch());
    const int* front = &box.front();
    for (int i = 2; i < 50; ++i) {
        ASSERT_NE(&box.back(), front);
        box.back() = i;
        box.publish();
        ASSERT_EQ(*front, 1);
    }
    ASSERT_TRUE(box.fetch());
    EXPECT_EQ(box.front(), 49);
}

TEST(Mailbox, ConcurrentReaderSeesWholeValuesInOrder) {
    sim::Mailbox<Payload> box;
    constexpr std::uint64_t kCount = 20000;
    std::atomic<bool> go{false};
    std::thread writer([&] {
        while (!go.load()) {
        }
        for (std::uint64_t s = 1; s <= kCount; ++s) {
            Payload p;
            p.sequence = s;
            p.words.fill(s);
            p.heap.assign(8, s);
            box.back() = std::move(p);
            box.publish();
        }
    });
    go.store(true);
    // Read until the last value arrives (it always does: nothing is lost at the end).
    std::uint64_t last = 0;
    bool torn = false;
    while (last < kCount && !torn) {
        if (!box.fetch()) continue;
        const Payload& p = box.front();
        torn = p.sequence < last || p.heap.size() != 8;
        for (std::uint64_t w : p.words)
            torn = torn || w != p.sequence;
        for (std::uint64_t w : p.heap)
            torn = torn || w != p.sequence;
        last = p.sequence;
    }
    writer.join();
    EXPECT_FALSE(torn) << "at value " << last;
    EXPECT_EQ(last, kCount);
}

}  // namespace
