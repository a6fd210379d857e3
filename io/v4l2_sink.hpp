// V4L2 video output sink: NTSC, V4L2_FIELD_ALTERNATE, mmap streaming, one field per buffer.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "io/frame_sink.hpp"
#include "io/v4l2_device.hpp"

namespace io {

struct V4l2SinkStats {
    std::uint64_t fieldsQueued = 0;
    std::uint64_t fieldsDropped = 0;      // no buffer came back from the device in time
    std::uint64_t leadingTopSkipped = 0;  // the stream starts with a Bottom field (NTSC)
    int buffers = 0;
    bool standardSet = false;  // S_STD NTSC accepted (false: the output has no analogue standard)
};

// open(): QUERYCAP (video output + streaming), S_STD NTSC, S_FMT width x height/2 per field in
// the pixel format with V4L2_FIELD_ALTERNATE, G_FMT (its sizes are honoured: see format()),
// REQBUFS >= 2 mmap buffers, QUERYBUF + mmap, STREAMON. writeField(): reclaims finished
// buffers (DQBUF), copies the field, sets `field` TOP/BOTTOM and the timestamp, QBUF.
class V4l2Sink final : public FrameSink {
  public:
    V4l2Sink(std::string devicePath, std::unique_ptr<V4l2Device> device);
    ~V4l2Sink() override;
    int open(const VideoFormat& format, std::string* error) override;
    int writeField(const FieldBuffer& field) override;
    int close(std::string* error) override;
    const VideoFormat& format() const override { return format_; }
    const V4l2SinkStats& stats() const { return stats_; }
    // How long writeField waits for the device to return a buffer before dropping the field.
    void setBufferWaitMs(int ms) { bufferWaitMs_ = ms; }

  private:
    struct Buffer {
        void* data = nullptr;
        std::size_t length = 0;
        bool queued = false;
    };
    int fail(std::string* error, const std::string& what, int rc);
    int reclaim();
    void release();

    std::string path_;
    std::unique_ptr<V4l2Device> device_;
    VideoFormat format_;
    std::uint32_t bytesPerLine_ = 0, sizeImage_ = 0;
    int deviceFieldLines_ = 0;
    std::vector<Buffer> buffers_;
    V4l2SinkStats stats_;
    int bufferWaitMs_ = 100;
    bool open_ = false, streaming_ = false, started_ = false;
};

}  // namespace io
