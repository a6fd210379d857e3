#include "io/v4l2_sim.hpp"

#include <linux/videodev2.h>

#include <algorithm>
#include <cerrno>
#include <cstring>

namespace io {
namespace {

constexpr std::uint32_t kOffsetUnit = 1u << 16;  // mmap cookie of buffer i: i * kOffsetUnit

std::string fourccText(std::uint32_t code) {
    std::string s;
    for (int i = 0; i < 4; ++i)
        s += static_cast<char>((code >> (8 * i)) & 0xff);
    return s;
}

std::uint32_t bytesPerPixelOf(std::uint32_t fourcc) {
    switch (fourcc) {
        case V4L2_PIX_FMT_GREY:
            return 1;
        case V4L2_PIX_FMT_RGB24:
            return 3;
        default:
            return 2;
    }
}

}  // namespace

SimulatedV4l2Device::SimulatedV4l2Device(SimulatedV4l2Config config) : config_(config) {}

SimulatedV4l2Device::~SimulatedV4l2Device() = default;

int SimulatedV4l2Device::open(const std::string&) {
    calls_.push_back("open");
    if (!config_.exists) return -ENOENT;
    open_ = true;
    return 0;
}

void SimulatedV4l2Device::close() {
    if (!open_) return;
    calls_.push_back("close");
    open_ = false;
    streaming_ = false;
}

int SimulatedV4l2Device::ioctl(unsigned long request, void* arg) {
    if (!open_) return -EBADF;
    switch (request) {
        case VIDIOC_QUERYCAP:
            calls_.push_back("QUERYCAP");
            return queryCap(arg);
        case VIDIOC_S_STD:
            calls_.push_back("S_STD");
            if (!config_.standards) return -ENOTTY;
            standard_ = *static_cast<v4l2_std_id*>(arg);
            return (standard_ & V4L2_STD_ALL) ? 0 : -EINVAL;
        case VIDIOC_S_FMT:
            calls_.push_back("S_FMT");
            return setFormat(arg);
        case VIDIOC_G_FMT:
            calls_.push_back("G_FMT");
            return getFormat(arg);
        case VIDIOC_REQBUFS:
            calls_.push_back("REQBUFS");
            return requestBuffers(arg);
        case VIDIOC_QUERYBUF:
            calls_.push_back("QUERYBUF");
            return queryBuffer(arg);
        case VIDIOC_QBUF:
            calls_.push_back("QBUF");
            return queueBuffer(arg);
        case VIDIOC_DQBUF:
            calls_.push_back("DQBUF");
            return dequeueBuffer(arg);
        case VIDIOC_STREAMON:
            calls_.push_back("STREAMON");
            if (*static_cast<int*>(arg) != V4L2_BUF_TYPE_VIDEO_OUTPUT || buffers_.empty())
                return -EINVAL;
            streaming_ = true;
            return 0;
        case VIDIOC_STREAMOFF:
            calls_.push_back("STREAMOFF");
            if (*static_cast<int*>(arg) != V4L2_BUF_TYPE_VIDEO_OUTPUT) return -EINVAL;
            streaming_ = false;
            for (Buffer& b : buffers_)
                b.queued = false;
            showing_.clear();
            done_.clear();
            return 0;
        default:
            calls_.push_back("unknown");
            return -ENOTTY;
    }
}

int SimulatedV4l2Device::queryCap(void* arg) {
    auto* cap = static_cast<v4l2_capability*>(arg);
    *cap = {};
    std::strncpy(reinterpret_cast<char*>(cap->driver), "vig-sim", sizeof cap->driver - 1);
    std::strncpy(reinterpret_cast<char*>(cap->card), "Simulated NTSC output", sizeof cap->card - 1);
    std::uint32_t caps = 0;
    if (config_.output) caps |= V4L2_CAP_VIDEO_OUTPUT;
    if (config_.capture) caps |= V4L2_CAP_VIDEO_CAPTURE;
    if (config_.streaming) caps |= V4L2_CAP_STREAMING;
    cap->device_caps = caps;
    cap->capabilities = caps | V4L2_CAP_DEVICE_CAPS;
    return 0;
}

int SimulatedV4l2Device::setFormat(void* arg) {
    auto* fmt = static_cast<v4l2_format*>(arg);
    if (fmt->type != V4L2_BUF_TYPE_VIDEO_OUTPUT || !config_.output) return -EINVAL;
    if (streaming_ || !buffers_.empty()) return -EBUSY;
    v4l2_pix_format& pix = fmt->fmt.pix;
    requestedFourcc_ = fourccText(pix.pixelformat);
    requestedWidth_ = static_cast<int>(pix.width);
    requestedFieldLines_ = static_cast<int>(pix.height);
    requestedAlternate_ = pix.field == V4L2_FIELD_ALTERNATE;
    if (config_.formatErrno != 0) return -config_.formatErrno;
    width_ = config_.width > 0 ? static_cast<std::uint32_t>(config_.width) : pix.width;
    fieldLines_ =
        config_.fieldLines > 0 ? static_cast<std::uint32_t>(config_.fieldLines) : pix.height;
    pixelFormat_ = config_.acceptPixelFormat ? pix.pixelformat : V4L2_PIX_FMT_YUYV;
    field_ = config_.acceptAlternate ? pix.field : static_cast<std::uint32_t>(V4L2_FIELD_NONE);
    bytesPerLine_ = width_ * bytesPerPixelOf(pixelFormat_) +
                    static_cast<std::uint32_t>(config_.bytesPerLinePadding);
    sizeImage_ = bytesPerLine_ * fieldLines_;
    return getFormat(arg);
}

int SimulatedV4l2Device::getFormat(void* arg) {
    auto* fmt = static_cast<v4l2_format*>(arg);
    if (fmt->type != V4L2_BUF_TYPE_VIDEO_OUTPUT || !config_.output) return -EINVAL;
    fmt->fmt.pix = {};
    fmt->fmt.pix.width = width_;
    fmt->fmt.pix.height = fieldLines_;
    fmt->fmt.pix.pixelformat = pixelFormat_;
    fmt->fmt.pix.field = field_;
    fmt->fmt.pix.bytesperline = bytesPerLine_;
    fmt->fmt.pix.sizeimage = sizeImage_;
    fmt->fmt.pix.colorspace = V4L2_COLORSPACE_SMPTE170M;
    return 0;
}

int SimulatedV4l2Device::requestBuffers(void* arg) {
    auto* req = static_cast<v4l2_requestbuffers*>(arg);
    if (req->type != V4L2_BUF_TYPE_VIDEO_OUTPUT || req->memory != V4L2_MEMORY_MMAP) return -EINVAL;
    if (streaming_) return -EBUSY;
    if (req->count == 0) {
        if (liveMappings_ > 0) return -EBUSY;
        buffers_.clear();
        return 0;
    }
    if (sizeImage_ == 0) return -EINVAL;
    req->count =
        std::min<std::uint32_t>(req->count, static_cast<std::uint32_t>(config_.maxBuffers));
    buffers_.assign(req->count, Buffer{});
    for (Buffer& b : buffers_)
        b.memory.assign(sizeImage_, 0);
    doneField_.assign(req->count, 0);
    return 0;
}

int SimulatedV4l2Device::queryBuffer(void* arg) {
    auto* b = static_cast<v4l2_buffer*>(arg);
    if (b->type != V4L2_BUF_TYPE_VIDEO_OUTPUT || b->index >= buffers_.size()) return -EINVAL;
    b->length = static_cast<std::uint32_t>(buffers_[b->index].memory.size());
    b->m.offset = b->index * kOffsetUnit;
    b->flags = V4L2_BUF_FLAG_TIMESTAMP_COPY;
    return 0;
}

void* SimulatedV4l2Device::map(std::size_t length, std::int64_t offset, int* errorOut) {
    const std::size_t index = static_cast<std::size_t>(offset) / kOffsetUnit;
    if (!open_ || offset % kOffsetUnit != 0 || index >= buffers_.size() ||
        length > buffers_[index].memory.size()) {
        if (errorOut) *errorOut = -EINVAL;
        return nullptr;
    }
    buffers_[index].mapped = true;
    ++liveMappings_;
    return buffers_[index].memory.data();
}

int SimulatedV4l2Device::unmap(void* address, std::size_t) {
    for (Buffer& b : buffers_) {
        if (b.mapped && b.memory.data() == address) {
            b.mapped = false;
            --liveMappings_;
            return 0;
        }
    }
    return -EINVAL;
}

int SimulatedV4l2Device::queueBuffer(void* arg) {
    auto* b = static_cast<v4l2_buffer*>(arg);
    if (b->type != V4L2_BUF_TYPE_VIDEO_OUTPUT || b->memory != V4L2_MEMORY_MMAP ||
        b->index >= buffers_.size()) {
        return -EINVAL;
    }
    Buffer& buffer = buffers_[b->index];
    if (buffer.queued || !buffer.mapped || b->bytesused > buffer.memory.size()) return -EINVAL;
    if (field_ == V4L2_FIELD_ALTERNATE && b->field != V4L2_FIELD_TOP &&
        b->field != V4L2_FIELD_BOTTOM) {
        return -EINVAL;  // alternate output needs every buffer to say which field it holds
    }
    SimulatedV4l2Buffer record;
    record.index = static_cast<int>(b->index);
    record.v4l2Field = b->field;
    record.field = b->field == V4L2_FIELD_TOP ? FieldParity::Top : FieldParity::Bottom;
    record.timestampUs =
        static_cast<std::int64_t>(b->timestamp.tv_sec) * 1000000 + b->timestamp.tv_usec;
    record.bytesUsed = b->bytesused;
    if (config_.keepData)
        record.data.assign(buffer.memory.begin(), buffer.memory.begin() + b->bytesused);
    queued_.push_back(std::move(record));
    buffer.queued = true;
    doneField_[b->index] = b->field;
    showing_.push_back(static_cast<int>(b->index));
    // The device shows the newest buffer and hands back the ones a newer buffer replaced.
    while (config_.consumes && streaming_ && showing_.size() > 1) {
        done_.push_back(showing_.front());
        showing_.pop_front();
    }
    return 0;
}

int SimulatedV4l2Device::dequeueBuffer(void* arg) {
    auto* b = static_cast<v4l2_buffer*>(arg);
    if (b->type != V4L2_BUF_TYPE_VIDEO_OUTPUT || b->memory != V4L2_MEMORY_MMAP) return -EINVAL;
    if (!streaming_) return -EINVAL;
    if (done_.empty()) return -EAGAIN;
    const int index = done_.front();
    done_.pop_front();
    buffers_[index].queued = false;
    b->index = static_cast<std::uint32_t>(index);
    b->field = doneField_[index];
    b->sequence = sequence_++;
    b->flags = V4L2_BUF_FLAG_DONE | V4L2_BUF_FLAG_TIMESTAMP_COPY;
    return 0;
}

int SimulatedV4l2Device::waitWritable(int) {
    return done_.empty() ? 0 : 1;
}

}  // namespace io
