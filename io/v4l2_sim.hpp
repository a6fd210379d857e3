// A simulated V4L2 output device behind the V4l2Device seam, for tests without hardware.
#pragma once

#include <cstdint>
#include <deque>
#include <string>
#include <vector>

#include "io/v4l2_device.hpp"
#include "io/video_format.hpp"

namespace io {

struct SimulatedV4l2Config {
    bool exists = true;     // false: open() fails with ENOENT
    bool output = true;     // advertises V4L2_CAP_VIDEO_OUTPUT
    bool capture = false;   // advertises V4L2_CAP_VIDEO_CAPTURE
    bool streaming = true;  // advertises V4L2_CAP_STREAMING
    bool standards = true;  // false: S_STD answers ENOTTY (an output with no analogue standard)
    int width = 0;          // the width S_FMT settles on (0: as asked)
    int fieldLines = 0;     // the per-field height S_FMT settles on (0: as asked)
    bool acceptPixelFormat = true;  // false: S_FMT answers with YUYV instead
    bool acceptAlternate = true;    // false: S_FMT answers with V4L2_FIELD_NONE
    int formatErrno = 0;            // non-zero: S_FMT fails with this errno
    int maxBuffers = 4;             // REQBUFS grants at most this many
    int bytesPerLinePadding = 0;
    bool consumes = true;  // the device shows queued buffers and hands them back
    bool keepData = true;  // record each queued buffer's bytes
};

// One VIDIOC_QBUF as the device saw it.
struct SimulatedV4l2Buffer {
    int index = 0;
    FieldParity field = FieldParity::Bottom;
    std::uint32_t v4l2Field = 0;
    std::int64_t timestampUs = 0;
    std::uint32_t bytesUsed = 0;
    std::vector<std::uint8_t> data;  // bytesUsed bytes, when keepData
};

class SimulatedV4l2Device final : public V4l2Device {
  public:
    explicit SimulatedV4l2Device(SimulatedV4l2Config config = {});
    ~SimulatedV4l2Device() override;

    int open(const std::string& path) override;
    int ioctl(unsigned long request, void* arg) override;
    void* map(std::size_t length, std::int64_t offset, int* errorOut) override;
    int unmap(void* address, std::size_t length) override;
    int waitWritable(int timeoutMs) override;
    void close() override;

    // What the device was asked, in order: "open", "QUERYCAP", "S_STD", "S_FMT", ...
    const std::vector<std::string>& calls() const { return calls_; }
    const std::vector<SimulatedV4l2Buffer>& queued() const { return queued_; }
    std::uint64_t standard() const { return standard_; }  // the v4l2_std_id set by S_STD
    std::string requestedFourcc() const { return requestedFourcc_; }
    int requestedWidth() const { return requestedWidth_; }
    int requestedFieldLines() const { return requestedFieldLines_; }
    bool requestedAlternate() const { return requestedAlternate_; }
    int bufferCount() const { return static_cast<int>(buffers_.size()); }
    int liveMappings() const { return liveMappings_; }
    bool streaming() const { return streaming_; }
    bool isOpen() const { return open_; }

  private:
    struct Buffer {
        std::vector<std::uint8_t> memory;
        bool queued = false;
        bool mapped = false;
    };
    int queryCap(void* arg);
    int setFormat(void* arg);
    int getFormat(void* arg);
    int requestBuffers(void* arg);
    int queryBuffer(void* arg);
    int queueBuffer(void* arg);
    int dequeueBuffer(void* arg);

    SimulatedV4l2Config config_;
    std::vector<std::string> calls_;
    std::vector<SimulatedV4l2Buffer> queued_;
    std::vector<Buffer> buffers_;
    std::deque<int> showing_, done_;
    std::vector<std::uint32_t> doneField_;
    std::uint64_t standard_ = 0;
    std::string requestedFourcc_;
    int requestedWidth_ = 0, requestedFieldLines_ = 0;
    bool requestedAlternate_ = false;
    std::uint32_t width_ = 720, fieldLines_ = 243, pixelFormat_ = 0, field_ = 0;
    std::uint32_t bytesPerLine_ = 0, sizeImage_ = 0;
    std::uint32_t sequence_ = 0;
    int liveMappings_ = 0;
    bool open_ = false, streaming_ = false;
};

}  // namespace io
