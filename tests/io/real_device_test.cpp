// The V4L2 sink and the gpiod stick against real kernel drivers: vivid's output looped back to
// its capture node, and a simulated GPIO chip driven through debugfs. The device tests' virtual
// machine (scripts/device-tests.sh) names the devices in the environment; elsewhere these skip.
#include <fcntl.h>
#include <linux/videodev2.h>
#include <sys/ioctl.h>
#include <sys/mman.h>
#include <time.h>
#include <unistd.h>

#include <gtest/gtest.h>

#include <cerrno>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

#include "base/video_timing.hpp"
#include "io/field_clock.hpp"
#include "io/gpio_stick.hpp"
#include "io/v4l2_sink.hpp"
#include "io_test_util.hpp"

namespace io {
namespace {

using test::TestField;

std::string env(const char* name) {
    const char* v = std::getenv(name);
    return v ? v : "";
}

void sleepNs(std::int64_t ns) {
    timespec ts{static_cast<time_t>(ns / 1000000000), static_cast<long>(ns % 1000000000)};
    while (nanosleep(&ts, &ts) != 0 && errno == EINTR) {
    }
}

int xioctl(int fd, unsigned long request, void* arg) {
    int rc;
    do {
        rc = ::ioctl(fd, request, arg);
    } while (rc != 0 && errno == EINTR);
    return rc == 0 ? 0 : -errno;
}

// A plain mmap capture stream on the loop-back node, in the sink's negotiated format.
class Capture {
  public:
    ~Capture() { stop(); }

    // 0 or a message naming the step that failed.
    std::string start(const std::string& path, const VideoFormat& format) {
        fd_ = ::open(path.c_str(), O_RDWR | O_NONBLOCK);
        if (fd_ < 0) return path + ": " + std::strerror(errno);
        v4l2_format fmt{};
        fmt.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
        fmt.fmt.pix.width = static_cast<std::uint32_t>(format.width);
        fmt.fmt.pix.height = static_cast<std::uint32_t>(format.height / 2);
        fmt.fmt.pix.pixelformat = V4L2_PIX_FMT_UYVY;
        fmt.fmt.pix.field = V4L2_FIELD_ALTERNATE;
        if (const int rc = xioctl(fd_, VIDIOC_S_FMT, &fmt); rc != 0)
            return "capture S_FMT: " + std::string(std::strerror(-rc));
        if (fmt.fmt.pix.pixelformat != V4L2_PIX_FMT_UYVY ||
            fmt.fmt.pix.field != V4L2_FIELD_ALTERNATE ||
            static_cast<int>(fmt.fmt.pix.width) != format.width ||
            static_cast<int>(fmt.fmt.pix.height) != format.height / 2) {
            return "capture S_FMT answered " + std::to_string(fmt.fmt.pix.width) + "x" +
                   std::to_string(fmt.fmt.pix.height) + " field " +
                   std::to_string(fmt.fmt.pix.field);
        }
        bytesPerLine_ = fmt.fmt.pix.bytesperline;
        v4l2_requestbuffers req{};
        req.count = 8;
        req.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
        req.memory = V4L2_MEMORY_MMAP;
        if (const int rc = xioctl(fd_, VIDIOC_REQBUFS, &req); rc != 0 || req.count < 2)
            return "capture REQBUFS: " + std::string(std::strerror(-rc));
        for (unsigned i = 0; i < req.count; ++i) {
            v4l2_buffer b{};
            b.index = i;
            b.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
            b.memory = V4L2_MEMORY_MMAP;
            if (xioctl(fd_, VIDIOC_QUERYBUF, &b) != 0) return "capture QUERYBUF";
            void* p =
                ::mmap(nullptr, b.length, PROT_READ | PROT_WRITE, MAP_SHARED, fd_, b.m.offset);
            if (p == MAP_FAILED) return "capture mmap";
            maps_.push_back({p, b.length});
            if (xioctl(fd_, VIDIOC_QBUF, &b) != 0) return "capture QBUF";
        }
        int type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
        if (const int rc = xioctl(fd_, VIDIOC_STREAMON, &type); rc != 0)
            return "capture STREAMON: " + std::string(std::strerror(-rc));
        streaming_ = true;
        return "";
    }

    struct Field {
        std::vector<std::uint8_t> bytes;  // lines packed, no padding
        std::uint32_t field = 0, sequence = 0;
        std::int64_t timestampUs = 0;
    };

    // Appends every captured field waiting now; returns the first error.
    int drain(int width, int lines, std::vector<Field>* out) {
        for (;;) {
            v4l2_buffer b{};
            b.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
            b.memory = V4L2_MEMORY_MMAP;
            const int rc = xioctl(fd_, VIDIOC_DQBUF, &b);
            if (rc == -EAGAIN) return 0;
            if (rc != 0) return rc;
            Field f;
            f.field = b.field;
            f.sequence = b.sequence;
            f.timestampUs =
                static_cast<std::int64_t>(b.timestamp.tv_sec) * 1000000 + b.timestamp.tv_usec;
            const std::size_t row = static_cast<std::size_t>(width) * 2;
            const auto* src = static_cast<const std::uint8_t*>(maps_[b.index].first);
            for (int y = 0; y < lines; ++y) {
                const std::uint8_t* line = src + static_cast<std::size_t>(y) * bytesPerLine_;
                f.bytes.insert(f.bytes.end(), line, line + row);
            }
            out->push_back(std::move(f));
            if (const int q = xioctl(fd_, VIDIOC_QBUF, &b); q != 0) return q;
        }
    }

  private:
    void stop() {
        if (fd_ < 0) return;
        if (streaming_) {
            int type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
            xioctl(fd_, VIDIOC_STREAMOFF, &type);
        }
        for (auto& [p, n] : maps_)
            ::munmap(p, n);
        v4l2_requestbuffers req{};
        req.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
        req.memory = V4L2_MEMORY_MMAP;
        xioctl(fd_, VIDIOC_REQBUFS, &req);
        ::close(fd_);
        fd_ = -1;
    }

    int fd_ = -1;
    bool streaming_ = false;
    std::uint32_t bytesPerLine_ = 0;
    std::vector<std::pair<void*, std::size_t>> maps_;
};

// Fields sent to the output come back on the capture node byte for byte (vivid loops UYVY to
// UYVY unconverted when sizes, standard and field order match): every captured field equals
// one sent field, they come back in the order sent, as the parity they were sent as, and the
// capture's sequence numbers and timestamps increase.
TEST(V4l2Sink, RealLoopback) {
    const std::string outPath = env("VIG_V4L2_OUTPUT"), capPath = env("VIG_V4L2_CAPTURE");
    if (outPath.empty() || capPath.empty())
        GTEST_SKIP() << "VIG_V4L2_OUTPUT / VIG_V4L2_CAPTURE not set (a vivid loop-back pair)";
    V4l2Sink sink(outPath, makeSystemV4l2Device());
    std::string error;
    ASSERT_EQ(sink.open({720, 486, PixelFormat::Uyvy}, &error), 0) << error;
    const VideoFormat format = sink.format();
    // NTSC at 720 wide: the 486 lines asked for, or 480 where the output has no scaler.
    EXPECT_EQ(format.width, 720);
    EXPECT_TRUE(format.height == 486 || format.height == 480) << format.height;
    EXPECT_TRUE(sink.stats().standardSet);
    Capture capture;
    const std::string started = capture.start(capPath, format);
    ASSERT_EQ(started, "") << started;

    const int lines = format.height / 2;
    constexpr int kFields = 60;
    std::vector<TestField> sent;
    for (int n = 0; n < kFields; ++n)
        sent.emplace_back(format, n, base::fieldTime(0.0, n));
    std::vector<Capture::Field> got;
    const std::int64_t t0 = monotonicNs();
    for (int n = 0; n < kFields; ++n) {
        // On the field grid, so vivid's output consumes about one field per field period.
        const std::int64_t due = t0 + static_cast<std::int64_t>(n) * 50050000 / 3;
        if (const std::int64_t now = monotonicNs(); due > now) sleepNs(due - now);
        const int rc = sink.writeField(sent[n].buffer);
        EXPECT_TRUE(rc == 0 || rc == -EAGAIN) << "field " << n << ": " << std::strerror(-rc);
        ASSERT_EQ(capture.drain(format.width, lines, &got), 0);
    }
    sleepNs(100000000);
    ASSERT_EQ(capture.drain(format.width, lines, &got), 0);
    EXPECT_EQ(sink.close(&error), 0) << error;
    EXPECT_EQ(sink.stats().fieldsQueued + sink.stats().fieldsDropped,
              static_cast<unsigned>(kFields));

    int matched = 0, unmatched = 0, lastIndex = -1, parityWrong = 0, order = 0;
    for (std::size_t i = 0; i < got.size(); ++i) {
        const Capture::Field& f = got[i];
        int index = -1;
        for (int n = 0; n < kFields && index < 0; ++n) {
            const std::vector<std::uint8_t>& p = sent[n].pixels;
            if (p.size() >= f.bytes.size() &&
                std::memcmp(p.data(), f.bytes.data(), f.bytes.size()) == 0)
                index = n;
        }
        if (index < 0) {
            // Before the first field arrives the capture shows vivid's own pattern or black.
            if (matched > 0) ++unmatched;
            continue;
        }
        ++matched;
        if (index < lastIndex) ++order;
        lastIndex = index;
        const std::uint32_t parity =
            fieldParity(index) == FieldParity::Top ? V4L2_FIELD_TOP : V4L2_FIELD_BOTTOM;
        if (f.field != parity) ++parityWrong;
        if (i > 0) {
            // vivid's loop-back repeats a sequence number when its capture thread catches up
            // (its documentation: not 100% accurate on the capture side), so only the order.
            const Capture::Field& prev = got[i - 1];
            EXPECT_GE(f.sequence, prev.sequence) << "capture buffer " << i;
            EXPECT_GT(f.timestampUs, prev.timestampUs) << "capture buffer " << i;
        }
    }
    std::printf(
        "loop-back at %dx%d: %zu fields captured, %d equal a sent field byte for byte, %d differ "
        "after the first match, parity differs on %d, out of order %d; queued %llu, "
        "dropped %llu\n",
        format.width, format.height, got.size(), matched, unmatched, parityWrong, order,
        static_cast<unsigned long long>(sink.stats().fieldsQueued),
        static_cast<unsigned long long>(sink.stats().fieldsDropped));
    if (matched == 0 && !got.empty()) {
        // Why: how far the last captured field is from the nearest sent one, and where.
        const Capture::Field& f = got.back();
        std::size_t best = f.bytes.size(), bestFirst = 0;
        int bestIndex = -1;
        for (int n = 0; n < kFields; ++n) {
            std::size_t diff = 0, first = f.bytes.size();
            for (std::size_t k = 0; k < f.bytes.size() && k < sent[n].pixels.size(); ++k) {
                if (f.bytes[k] != sent[n].pixels[k]) {
                    ++diff;
                    first = std::min(first, k);
                }
            }
            if (diff < best) best = diff, bestFirst = first, bestIndex = n;
        }
        std::printf(
            "last captured field: nearest sent field %d differs in %zu of %zu bytes, "
            "first at byte %zu; captured starts",
            bestIndex, best, f.bytes.size(), bestFirst);
        for (std::size_t k = 0; k < 16 && k < f.bytes.size(); ++k)
            std::printf(" %u", f.bytes[k]);
        std::printf("\n");
    }
    EXPECT_GE(matched, kFields / 2);
    EXPECT_EQ(unmatched, 0);
    EXPECT_EQ(order, 0);
    EXPECT_EQ(parityWrong, 0);
}

// Drives a simulated chip's lines from outside (VIG_GPIO_PULL: a file taking "OFFSET LEVEL",
// the vig_gpio_sim debugfs file) and reads them through libgpiod: every edge seen once, chatter
// shorter than the debounce ignored, a held button counted, the throttle integrated over the
// debounced interval.
class PulledChip {
  public:
    explicit PulledChip(const std::string& path) : fd_(::open(path.c_str(), O_WRONLY)) {}
    ~PulledChip() {
        if (fd_ >= 0) ::close(fd_);
    }
    bool ok() const { return fd_ >= 0; }
    void pull(int offset, int level) {
        const std::string s = std::to_string(offset) + " " + std::to_string(level) + "\n";
        ASSERT_EQ(::pwrite(fd_, s.data(), s.size(), 0), static_cast<ssize_t>(s.size()))
            << std::strerror(errno);
    }

  private:
    int fd_;
};

TEST(GpioStick, RealChipEdgesAndDebounce) {
    const std::string chip = env("VIG_GPIO_CHIP"), pullPath = env("VIG_GPIO_PULL");
    if (chip.empty() || pullPath.empty())
        GTEST_SKIP() << "VIG_GPIO_CHIP / VIG_GPIO_PULL not set (a simulated GPIO chip)";
    PulledChip lines(pullPath);
    ASSERT_TRUE(lines.ok()) << pullPath << ": " << std::strerror(errno);
    for (int o = 0; o < 7; ++o)
        lines.pull(o, 0);
    std::string error;
    auto config = parseGpioStickSpec(chip + ":0,1,2,3,4,5,6", &error);
    ASSERT_TRUE(config) << error;
    // 100 ms rather than the default 10: under an emulated CPU an interrupt thread can take
    // milliseconds to run, and the chatter below must stay within the debounce time.
    config->debounceS = 0.1;
    GpioStick stick(*config, makeGpiodChipPort());
    ASSERT_EQ(stick.open(&error), 0) << error;
    const std::int64_t debounceNs = 100000000, settleNs = 250000000;
    // Samples until the stick has seen `count` edges (or 20 ms have passed).
    auto awaitEdges = [&stick](std::uint64_t count) {
        const std::int64_t until = monotonicNs() + 20000000;
        while (stick.edgesSeen() < count && monotonicNs() < until) {
            stick.sample(0);
            sleepNs(200000);
        }
    };
    std::uint64_t edges = 0;

    // A clean press and release of "up".
    lines.pull(0, 1);
    ++edges;
    sleepNs(settleNs);
    EXPECT_EQ(stick.sample(0).pitch, 1.0);
    lines.pull(0, 0);
    ++edges;
    sleepNs(settleNs);
    EXPECT_EQ(stick.sample(0).pitch, 0.0);
    EXPECT_EQ(stick.edgesSeen(), edges);

    // "right" chatters five times within the debounce time, then holds: one press. Each edge
    // is pulled once the last one has been read: gpiolib's v1 line events (libgpiod 1.6) come
    // from a threaded interrupt that reads the level when it runs, so edges closer together
    // than the thread's wake-up merge (the burst below).
    std::int64_t start = monotonicNs();
    for (int i = 0; i < 6; ++i) {
        lines.pull(3, i % 2 == 0 ? 1 : 0);
        awaitEdges(++edges);
    }
    EXPECT_FALSE(stick.pressed(StickLine::Right)) << "a level counted before it held";
    lines.pull(3, 1);
    ++edges;
    const std::int64_t chatterNs = monotonicNs() - start;
    ASSERT_LT(chatterNs, debounceNs) << "the chatter took longer than the debounce time";
    sleepNs(settleNs);
    StickState s = stick.sample(0);
    EXPECT_EQ(s.roll, 1.0);
    EXPECT_EQ(stick.edgesSeen(), edges) << "every edge once, none doubled or lost";

    // A glitch on the trigger, shorter than the debounce: never a press.
    start = monotonicNs();
    lines.pull(4, 1);
    lines.pull(4, 0);
    edges += 2;
    ASSERT_LT(monotonicNs() - start, debounceNs);
    EXPECT_FALSE(stick.sample(0).trigger);
    sleepNs(settleNs);
    EXPECT_FALSE(stick.sample(0).trigger);
    EXPECT_FALSE(stick.pressed(StickLine::Trigger));

    // A burst with no gaps: edges may merge (see above) but are never doubled, and the level
    // it ends on is the one the stick settles to.
    const std::uint64_t beforeBurst = stick.edgesSeen();
    for (int i = 0; i < 8; ++i)
        lines.pull(2, i % 2 == 0 ? 1 : 0);
    lines.pull(2, 1);
    sleepNs(settleNs);
    EXPECT_EQ(stick.sample(0).roll, 0.0);  // left and right together cancel
    EXPECT_TRUE(stick.pressed(StickLine::Left));
    const std::uint64_t burstSeen = stick.edgesSeen() - beforeBurst;
    EXPECT_GE(burstSeen, 1u);
    EXPECT_LE(burstSeen, 9u);
    lines.pull(2, 0);
    sleepNs(settleNs);
    EXPECT_FALSE(stick.sample(0).trigger);
    EXPECT_FALSE(stick.pressed(StickLine::Left));
    edges = stick.edgesSeen();
    lines.pull(3, 0);
    ++edges;
    sleepNs(settleNs);
    EXPECT_EQ(stick.sample(0).roll, 0.0);

    // throttle+ held for about 200 ms: the throttle grows by 0.5/s over the time it was held,
    // bounded by the clock read on either side of each pull.
    const std::int64_t pressBefore = monotonicNs();
    lines.pull(5, 1);
    const std::int64_t pressAfter = monotonicNs();
    sleepNs(200000000);
    const std::int64_t releaseBefore = monotonicNs();
    lines.pull(5, 0);
    const std::int64_t releaseAfter = monotonicNs();
    edges += 2;
    sleepNs(settleNs);
    s = stick.sample(0);
    const double lo = 0.5 * static_cast<double>(releaseBefore - pressAfter) * 1e-9;
    const double hi = 0.5 * static_cast<double>(releaseAfter - pressBefore) * 1e-9;
    EXPECT_GE(s.throttle, lo - 1e-9);
    EXPECT_LE(s.throttle, hi + 1e-9);
    EXPECT_EQ(stick.edgesSeen(), edges);
    std::printf(
        "gpio: chatter of 7 edges in %.3f ms, all seen; a burst of 9 edges seen as %llu; "
        "throttle %.4f in [%.4f, %.4f]\n",
        chatterNs * 1e-6, static_cast<unsigned long long>(burstSeen), s.throttle, lo, hi);
}

}  // namespace
}  // namespace io
