// Frames between processes: what goes in comes out whole, garbage is refused, and a frame
// being written is never the one read.
#include "sim/frame_ring.hpp"

#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cmath>
#include <cstdint>
#include <limits>
#include <memory>
#include <string>

namespace {

ig::RenderedFrame patterned(std::uint64_t sequence, int width = 48, int height = 32) {
    ig::RenderedFrame f;
    f.sequence = sequence;
    f.time = 0.5 * static_cast<double>(sequence);
    f.pose.position = {1.0, 2.0, 300.0 + static_cast<double>(sequence)};
    f.intrinsics = ig::Intrinsics::fromFov(width - 8, height - 8, 1.0, 4);
    const std::size_t n = static_cast<std::size_t>(width) * height;
    const auto v = static_cast<std::uint8_t>(sequence * 37 + 11);
    f.color.assign(n, ig::Rgb8{v, static_cast<std::uint8_t>(v ^ 0x5a), 7});
    f.depth.assign(n, static_cast<float>(sequence));
    for (int i = 0; i < ig::kControlPointCount; ++i) {
        f.controlPoints[i].pixel = {i * 3.0, i * 2.0};
        f.controlPoints[i].world = {i * 10.0, 5.0, 1.0, 1.0};
    }
    f.stats.renderMs = 4.5;
    return f;
}

// True when every pixel of `f` is the one pattern its sequence number gives.
bool whole(const ig::RenderedFrame& f) {
    const ig::RenderedFrame want = patterned(f.sequence, f.intrinsics.width, f.intrinsics.height);
    return f.color == want.color && f.depth == want.depth &&
           f.pose.position.z == want.pose.position.z;
}

TEST(FrameRing, WhatIsPublishedIsFetchedOnce) {
    sim::FrameRing ring(48 * 32);
    ig::RenderedFrame got;
    std::string why;
    EXPECT_EQ(ring.fetch(got, &why), sim::FrameRing::Fetch::None);
    ASSERT_TRUE(ring.publish(patterned(1), 123));
    EXPECT_EQ(ring.published(), 1u);
    EXPECT_EQ(ring.lastPublishNs(), 123);
    ASSERT_EQ(ring.fetch(got, &why), sim::FrameRing::Fetch::New) << why;
    EXPECT_TRUE(whole(got));
    EXPECT_EQ(got.stats.renderMs, 4.5);
    EXPECT_EQ(got.controlPoints[8].world.x, 80.0);
    EXPECT_EQ(ring.fetch(got, &why), sim::FrameRing::Fetch::None);
    // Only the newest of several is fetched; its buffers are reused, not reallocated.
    const ig::Rgb8* buffer = got.color.data();
    ASSERT_TRUE(ring.publish(patterned(2), 0));
    ASSERT_TRUE(ring.publish(patterned(3), 0));
    ASSERT_EQ(ring.fetch(got, &why), sim::FrameRing::Fetch::New);
    EXPECT_EQ(got.sequence, 3u);
    EXPECT_TRUE(whole(got));
    EXPECT_EQ(got.color.data(), buffer);
    // A frame no newer than the one shown is not shown again.
    ASSERT_TRUE(ring.publish(patterned(3), 0));
    EXPECT_EQ(ring.fetch(got, &why), sim::FrameRing::Fetch::None);
    // Too large for a slot, or colour and depth of different sizes: not published.
    EXPECT_FALSE(ring.publish(patterned(4, 64, 32), 0));
    ig::RenderedFrame odd = patterned(4);
    odd.depth.pop_back();
    EXPECT_FALSE(ring.publish(odd, 0));
}

// A pair: the right eye as a frame of its own, its pixels from another pattern.
ig::RenderedFrame pair(std::uint64_t sequence) {
    ig::RenderedFrame left = patterned(sequence);
    auto right = std::make_shared<ig::RenderedFrame>(patterned(sequence + 1000));
    right->sequence = sequence;
    right->pose.position.x += 2.0;
    left.right = right;
    return left;
}

TEST(FrameRing, StereoSlotsCarryBothEyes) {
    sim::FrameRing ring(48 * 32, 2);
    EXPECT_EQ(ring.eyes(), 2);
    ig::RenderedFrame got;
    std::string why;
    // A stereo ring takes pairs only.
    EXPECT_FALSE(ring.publish(patterned(1), 0));
    ASSERT_TRUE(ring.publish(pair(1), 0));
    ASSERT_EQ(ring.fetch(got, &why), sim::FrameRing::Fetch::New) << why;
    EXPECT_TRUE(whole(got));
    ASSERT_TRUE(got.right);
    const ig::RenderedFrame want = patterned(1001);
    EXPECT_EQ(got.right->color, want.color);
    EXPECT_EQ(got.right->depth, want.depth);
    EXPECT_EQ(got.right->pose.position.x, 3.0);
    EXPECT_EQ(got.right->sequence, 1u);
    // Nothing else holds the right eye: the next pair is written into the same frame.
    const ig::RenderedFrame* right = got.right.get();
    ASSERT_TRUE(ring.publish(pair(2), 0));
    ASSERT_EQ(ring.fetch(got, &why), sim::FrameRing::Fetch::New);
    EXPECT_EQ(got.right.get(), right);
    EXPECT_EQ(got.right->color, patterned(1002).color);
    // A right eye still held elsewhere (a field being warped) is never written over.
    const std::shared_ptr<const ig::RenderedFrame> shown = got.right;
    ASSERT_TRUE(ring.publish(pair(3), 0));
    ASSERT_EQ(ring.fetch(got, &why), sim::FrameRing::Fetch::New);
    EXPECT_NE(got.right.get(), shown.get());
    EXPECT_EQ(shown->color, patterned(1002).color);
    EXPECT_EQ(got.right->color, patterned(1003).color);
    // A right eye too large for a slot, or of mismatched sizes: not published.
    ig::RenderedFrame big = pair(4);
    big.right = std::make_shared<ig::RenderedFrame>(patterned(4, 64, 32));
    EXPECT_FALSE(ring.publish(big, 0));
    ig::RenderedFrame odd = pair(4);
    auto oddRight = std::make_shared<ig::RenderedFrame>(*odd.right);
    oddRight->depth.pop_back();
    odd.right = oddRight;
    EXPECT_FALSE(ring.publish(odd, 0));
}

// A right eye that is garbage makes the whole pair bad, named as the right eye's, and leaves
// the frame fetched before untouched.
TEST(FrameRing, ABadRightEyeIsRefused) {
    sim::FrameRing ring(48 * 32, 2);
    ig::RenderedFrame got = patterned(0);
    std::string why;
    ig::RenderedFrame bad = pair(1);
    auto right = std::make_shared<ig::RenderedFrame>(*bad.right);
    right->controlPoints[3].world.x = std::numeric_limits<double>::quiet_NaN();
    bad.right = right;
    ASSERT_TRUE(ring.publish(bad, 0));
    EXPECT_EQ(ring.fetch(got, &why), sim::FrameRing::Fetch::Bad);
    EXPECT_NE(why.find("right eye"), std::string::npos) << why;
    EXPECT_EQ(got.sequence, 0u);
    EXPECT_FALSE(got.right);
}

TEST(FrameRing, GarbageIsRefusedWithItsReason) {
    sim::FrameRing ring(48 * 32);
    ig::RenderedFrame got = patterned(0);
    std::string why;
    ig::RenderedFrame bad = patterned(1);
    ring.publishRaw(bad, std::numeric_limits<std::uint64_t>::max());
    EXPECT_EQ(ring.fetch(got, &why), sim::FrameRing::Fetch::Bad);
    EXPECT_NE(why.find("pixels"), std::string::npos) << why;
    EXPECT_EQ(got.sequence, 0u);  // untouched
    bad.controlPoints[3].world.y = std::nan("");
    ring.publishRaw(bad, bad.color.size());
    EXPECT_EQ(ring.fetch(got, &why), sim::FrameRing::Fetch::Bad);
    EXPECT_NE(why.find("control point"), std::string::npos) << why;
    bad = patterned(2);
    bad.intrinsics.width = -5;
    ring.publishRaw(bad, 0);
    EXPECT_EQ(ring.fetch(got, &why), sim::FrameRing::Fetch::Bad);
    bad = patterned(3);
    bad.pose.yaw = std::numeric_limits<double>::infinity();
    ring.publishRaw(bad, bad.color.size());
    EXPECT_EQ(ring.fetch(got, &why), sim::FrameRing::Fetch::Bad);
    EXPECT_EQ(got.sequence, 0u);
}

TEST(FrameRing, RequestsCarryTheNewestPose) {
    sim::FrameRing ring(16);
    EXPECT_EQ(ring.latestRequest().generation, 0u);
    ig::Pose p;
    p.position = {1, 2, 3};
    p.roll = 0.25;
    ring.postRequest(p, 7.5, 11);
    p.position.x = 4;
    ring.postRequest(p, 8.0, 12);
    const sim::RenderRequest r = ring.latestRequest();
    EXPECT_EQ(r.generation, 2u);
    EXPECT_EQ(r.sequence, 12u);
    EXPECT_EQ(r.time, 8.0);
    EXPECT_EQ(r.pose.position.x, 4.0);
    EXPECT_EQ(r.pose.roll, 0.25);
}

// A writer that died in the middle of a frame: the next writer must not write the slot the
// reader holds or the one published.
TEST(FrameRing, ARestartedWriterNeverWritesWhatTheReaderMayHold) {
    sim::FrameRing ring(48 * 32);
    ig::RenderedFrame got;
    std::string why;
    ASSERT_TRUE(ring.publish(patterned(1), 0));
    ASSERT_EQ(ring.fetch(got, &why), sim::FrameRing::Fetch::New);
    ASSERT_TRUE(ring.publish(patterned(2), 0));  // published, not yet fetched
    ring.resetWriter();
    ASSERT_TRUE(ring.publish(patterned(3), 0));
    ASSERT_EQ(ring.fetch(got, &why), sim::FrameRing::Fetch::New);
    EXPECT_EQ(got.sequence, 3u);
    EXPECT_TRUE(whole(got));
}

// Another process publishes as fast as it can while this one fetches: every frame fetched is
// whole (one sequence's pattern throughout) and sequences only grow.
TEST(FrameRing, NoTornFrameAcrossProcesses) {
    constexpr int kW = 160, kH = 120;
    sim::FrameRing ring(kW * kH);
    constexpr std::uint64_t kFrames = 3000;
    const pid_t pid = fork();
    ASSERT_GE(pid, 0);
    if (pid == 0) {
        for (std::uint64_t s = 1; s <= kFrames; ++s)
            if (!ring.publish(patterned(s, kW, kH), 0)) _exit(2);
        _exit(0);
    }
    ig::RenderedFrame got;
    std::string why;
    std::uint64_t fetched = 0, last = 0, torn = 0;
    while (last < kFrames) {
        const sim::FrameRing::Fetch f = ring.fetch(got, &why);
        ASSERT_NE(f, sim::FrameRing::Fetch::Bad) << why;
        if (f == sim::FrameRing::Fetch::None) continue;
        ++fetched;
        ASSERT_GT(got.sequence, last);
        last = got.sequence;
        if (!whole(got)) ++torn;
    }
    int status = 0;
    ASSERT_EQ(waitpid(pid, &status, 0), pid);
    ASSERT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0);
    EXPECT_EQ(torn, 0u);
    EXPECT_GE(fetched, 1u);  // how many overlap depends on the machine's load
}

}  // namespace
