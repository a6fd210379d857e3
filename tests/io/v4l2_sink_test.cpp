#include <fcntl.h>
#include <linux/videodev2.h>
#include <sys/ioctl.h>
#include <unistd.h>

#include <gtest/gtest.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <filesystem>

#include "io/field_clock.hpp"
#include "io/v4l2_sim.hpp"
#include "io/v4l2_sink.hpp"
#include "io_test_util.hpp"

namespace io {
namespace {

using test::lineCode;
using test::TestField;

std::unique_ptr<V4l2Sink> makeSimSink(SimulatedV4l2Config config, SimulatedV4l2Device** device) {
    auto d = std::make_unique<SimulatedV4l2Device>(config);
    *device = d.get();
    return std::make_unique<V4l2Sink>("/dev/video-sim", std::move(d));
}

TEST(V4l2Sink, NegotiatesNtscAlternateUyvy) {
    SimulatedV4l2Device* dev = nullptr;
    auto sink = makeSimSink({}, &dev);
    std::string error;
    ASSERT_EQ(sink->open({720, 486, PixelFormat::Uyvy}, &error), 0) << error;
    const std::vector<std::string> want = {"open",  "QUERYCAP", "S_STD",
                                           "S_FMT", "G_FMT",    "REQBUFS"};
    ASSERT_GE(dev->calls().size(), want.size());
    EXPECT_TRUE(std::equal(want.begin(), want.end(), dev->calls().begin()));
    EXPECT_EQ(dev->calls().back(), "STREAMON");
    EXPECT_EQ(dev->standard(), static_cast<std::uint64_t>(V4L2_STD_NTSC));
    EXPECT_EQ(dev->requestedFourcc(), "UYVY");
    EXPECT_EQ(dev->requestedWidth(), 720);
    EXPECT_EQ(dev->requestedFieldLines(), 243);  // ALTERNATE: height is per field
    EXPECT_TRUE(dev->requestedAlternate());
    EXPECT_GE(dev->bufferCount(), 2);
    EXPECT_EQ(dev->liveMappings(), dev->bufferCount());
    EXPECT_TRUE(dev->streaming());
    EXPECT_TRUE(sink->stats().standardSet);
    EXPECT_EQ(sink->format().width, 720);
    EXPECT_EQ(sink->format().height, 486);
    ASSERT_EQ(sink->close(&error), 0) << error;
    EXPECT_FALSE(dev->streaming());
    EXPECT_EQ(dev->liveMappings(), 0);
    EXPECT_EQ(dev->bufferCount(), 0);
    EXPECT_FALSE(dev->isOpen());
}

TEST(V4l2Sink, BuffersAlternateBottomTopWithTimestampsAndPixels) {
    SimulatedV4l2Device* dev = nullptr;
    auto sink = makeSimSink({}, &dev);
    std::string error;
    const VideoFormat format{720, 486, PixelFormat::Uyvy};
    ASSERT_EQ(sink->open(format, &error), 0) << error;
    const int kFields = 10;  // more than the buffers: they must come back and be reused
    for (int i = 0; i < kFields; ++i) {
        TestField f(format, i, base::fieldTime(2.0, i));
        ASSERT_EQ(sink->writeField(f.buffer), 0) << "field " << i;
    }
    const auto& q = dev->queued();
    ASSERT_EQ(q.size(), static_cast<std::size_t>(kFields));
    for (int i = 0; i < kFields; ++i) {
        EXPECT_EQ(q[i].v4l2Field, i % 2 == 0 ? V4L2_FIELD_BOTTOM : V4L2_FIELD_TOP) << i;
        EXPECT_NEAR(q[i].timestampUs * 1e-6, base::fieldTime(2.0, i), 1e-6) << i;
        if (i > 0) {
            EXPECT_GT(q[i].timestampUs, q[i - 1].timestampUs);
        }
        EXPECT_EQ(q[i].bytesUsed, 720u * 243u * 2u);
        for (int line : {0, 100, 242}) {
            EXPECT_EQ(q[i].data[static_cast<std::size_t>(line) * 1440 + 1], lineCode(i, line));
        }
    }
    std::vector<int> indices;
    for (const auto& b : q)
        indices.push_back(b.index);
    std::sort(indices.begin(), indices.end());
    indices.erase(std::unique(indices.begin(), indices.end()), indices.end());
    // Buffers cycle: more fields than buffers went out through at least two of them.
    EXPECT_GE(indices.size(), 2u);
    EXPECT_LE(static_cast<int>(indices.size()), dev->bufferCount());
    EXPECT_EQ(sink->stats().fieldsQueued, static_cast<std::uint64_t>(kFields));
    EXPECT_GT(std::count(dev->calls().begin(), dev->calls().end(), "DQBUF"), 0);
    ASSERT_EQ(sink->close(&error), 0) << error;
    EXPECT_EQ(std::count(dev->calls().begin(), dev->calls().end(), "STREAMOFF"), 1);
}

TEST(V4l2Sink, StreamStartsWithBottomField) {
    SimulatedV4l2Device* dev = nullptr;
    auto sink = makeSimSink({}, &dev);
    std::string error;
    const VideoFormat format{64, 40, PixelFormat::Y8};
    ASSERT_EQ(sink->open(format, &error), 0) << error;
    for (std::uint64_t i = 1; i <= 5; ++i)
        ASSERT_EQ(sink->writeField(TestField(format, i).buffer), 0);
    ASSERT_EQ(dev->queued().size(), 4u);
    EXPECT_EQ(dev->queued().front().field, FieldParity::Bottom);
    EXPECT_EQ(sink->stats().leadingTopSkipped, 1u);
    ASSERT_EQ(sink->close(&error), 0) << error;
}

TEST(V4l2Sink, HonoursTheSizeTheDeviceReturns) {
    SimulatedV4l2Config config;
    config.fieldLines = 240;  // 720x480 digital NTSC
    config.bytesPerLinePadding = 64;
    SimulatedV4l2Device* dev = nullptr;
    auto sink = makeSimSink(config, &dev);
    std::string error;
    ASSERT_EQ(sink->open({720, 486, PixelFormat::Uyvy}, &error), 0) << error;
    EXPECT_EQ(sink->format().width, 720);
    EXPECT_EQ(sink->format().height, 480);
    // A field produced for the negotiated format lands line for line, padding skipped.
    TestField f(sink->format(), 0, 0.0);
    EXPECT_EQ(f.buffer.lines, 240);
    ASSERT_EQ(sink->writeField(f.buffer), 0);
    const auto& b = dev->queued().at(0);
    const std::size_t bpl = 720 * 2 + 64;
    EXPECT_EQ(b.bytesUsed, bpl * 240);
    for (int line : {0, 1, 239})
        EXPECT_EQ(b.data[line * bpl + 1], lineCode(0, line));
    // A field still at the old size is cropped, never written past the buffer.
    TestField old({720, 486, PixelFormat::Uyvy}, 2, 0.1);
    ASSERT_EQ(sink->writeField(old.buffer), 0);
    ASSERT_EQ(sink->close(&error), 0) << error;
}

TEST(V4l2Sink, MissingDeviceIsAClearError) {
    SimulatedV4l2Config config;
    config.exists = false;
    SimulatedV4l2Device* dev = nullptr;
    auto sink = makeSimSink(config, &dev);
    std::string error;
    EXPECT_EQ(sink->open({}, &error), -ENOENT);
    EXPECT_NE(error.find("/dev/video-sim"), std::string::npos) << error;
    EXPECT_NE(error.find("No such file"), std::string::npos) << error;
    EXPECT_EQ(sink->writeField(TestField({}, 0).buffer), -EBADF);
}

TEST(V4l2Sink, CaptureOnlyDeviceIsRefused) {
    SimulatedV4l2Config config;
    config.output = false;
    config.capture = true;
    SimulatedV4l2Device* dev = nullptr;
    auto sink = makeSimSink(config, &dev);
    std::string error;
    EXPECT_LT(sink->open({}, &error), 0);
    EXPECT_NE(error.find("capture device"), std::string::npos) << error;
    EXPECT_FALSE(dev->isOpen());
    EXPECT_EQ(std::count(dev->calls().begin(), dev->calls().end(), "S_FMT"), 0);
}

TEST(V4l2Sink, RefusedFormatsAreClearErrors) {
    struct Case {
        const char* what;
        SimulatedV4l2Config config;
        const char* expect;
    };
    std::vector<Case> cases;
    {
        Case c{"pixel format", {}, "offers YUYV"};
        c.config.acceptPixelFormat = false;
        cases.push_back(c);
    }
    {
        Case c{"field order", {}, "progressive"};
        c.config.acceptAlternate = false;
        cases.push_back(c);
    }
    {
        Case c{"S_FMT error", {}, "S_FMT"};
        c.config.formatErrno = EINVAL;
        cases.push_back(c);
    }
    {
        Case c{"one buffer", {}, "at least 2"};
        c.config.maxBuffers = 1;
        cases.push_back(c);
    }
    {
        Case c{"no streaming", {}, "streaming"};
        c.config.streaming = false;
        cases.push_back(c);
    }
    for (const Case& c : cases) {
        SimulatedV4l2Device* dev = nullptr;
        auto sink = makeSimSink(c.config, &dev);
        std::string error;
        EXPECT_LT(sink->open({720, 486, PixelFormat::Uyvy}, &error), 0) << c.what;
        EXPECT_NE(error.find(c.expect), std::string::npos) << c.what << ": " << error;
        EXPECT_NE(error.find("v4l2:/dev/video-sim"), std::string::npos) << error;
        EXPECT_EQ(dev->liveMappings(), 0) << c.what;
        EXPECT_FALSE(dev->isOpen()) << c.what;
    }
}

TEST(V4l2Sink, OutputWithoutStandardsStillStreams) {
    SimulatedV4l2Config config;
    config.standards = false;
    SimulatedV4l2Device* dev = nullptr;
    auto sink = makeSimSink(config, &dev);
    std::string error;
    ASSERT_EQ(sink->open({720, 486, PixelFormat::Uyvy}, &error), 0) << error;
    EXPECT_FALSE(sink->stats().standardSet);
    ASSERT_EQ(sink->close(&error), 0) << error;
}

TEST(V4l2Sink, StalledDeviceDropsFieldsInsteadOfBlocking) {
    SimulatedV4l2Config config;
    config.consumes = false;
    SimulatedV4l2Device* dev = nullptr;
    auto sink = makeSimSink(config, &dev);
    std::string error;
    const VideoFormat format{32, 8, PixelFormat::Y8};
    ASSERT_EQ(sink->open(format, &error), 0) << error;
    const int buffers = dev->bufferCount();
    for (int i = 0; i < buffers; ++i)
        ASSERT_EQ(sink->writeField(TestField(format, i).buffer), 0);
    EXPECT_EQ(sink->writeField(TestField(format, buffers).buffer), -EAGAIN);
    EXPECT_EQ(sink->stats().fieldsDropped, 1u);
    ASSERT_EQ(sink->close(&error), 0) << error;
}

// Runs a short session on a real V4L2 output device (e.g. the vivid driver) when one exists.
TEST(V4l2Sink, RealOutputDevice) {
    std::string found;
    std::error_code ec;
    for (const auto& entry : std::filesystem::directory_iterator("/dev", ec)) {
        const std::string name = entry.path().filename().string();
        if (name.rfind("video", 0) != 0) continue;
        const int fd = ::open(entry.path().c_str(), O_RDWR | O_NONBLOCK);
        if (fd < 0) continue;
        v4l2_capability cap{};
        const bool ok = ::ioctl(fd, VIDIOC_QUERYCAP, &cap) == 0;
        ::close(fd);
        const std::uint32_t caps =
            (cap.capabilities & V4L2_CAP_DEVICE_CAPS) ? cap.device_caps : cap.capabilities;
        if (ok && (caps & V4L2_CAP_VIDEO_OUTPUT) && (caps & V4L2_CAP_STREAMING)) {
            found = entry.path().string();
            break;
        }
    }
    if (found.empty()) GTEST_SKIP() << "no V4L2 video output device";
    V4l2Sink sink(found, makeSystemV4l2Device());
    std::string error;
    ASSERT_EQ(sink.open({720, 486, PixelFormat::Uyvy}, &error), 0) << error;
    EXPECT_GE(sink.stats().buffers, 2);
    const VideoFormat format = sink.format();
    int queued = 0;
    for (int i = 0; i < 8; ++i) {
        if (sink.writeField(TestField(format, i, base::fieldTime(0.0, i)).buffer) == 0) ++queued;
    }
    EXPECT_GE(queued, 2);
    EXPECT_EQ(sink.close(&error), 0) << error;
}

}  // namespace
}  // namespace io
