#include "io/v4l2_sink.hpp"

#include <linux/videodev2.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>

#include "io/file_sinks.hpp"

namespace io {
namespace {

constexpr unsigned kBufferCount = 4;
constexpr unsigned kMinBuffers = 2;

std::uint32_t fourccOf(PixelFormat format) {
    switch (format) {
        case PixelFormat::Uyvy:
            return V4L2_PIX_FMT_UYVY;
        case PixelFormat::Y8:
            return V4L2_PIX_FMT_GREY;
        case PixelFormat::Rgb8:
            return V4L2_PIX_FMT_RGB24;
    }
    return 0;
}

std::string fourccText(std::uint32_t code) {
    std::string s;
    for (int i = 0; i < 4; ++i) {
        const char c = static_cast<char>((code >> (8 * i)) & 0xff);
        s += (c >= 32 && c < 127) ? c : '?';
    }
    return s;
}

std::string fieldText(std::uint32_t field) {
    switch (field) {
        case V4L2_FIELD_ANY:
            return "any";
        case V4L2_FIELD_NONE:
            return "progressive";
        case V4L2_FIELD_TOP:
            return "top";
        case V4L2_FIELD_BOTTOM:
            return "bottom";
        case V4L2_FIELD_INTERLACED:
            return "interlaced";
        case V4L2_FIELD_ALTERNATE:
            return "alternate";
        default:
            return "field order " + std::to_string(field);
    }
}

std::string errnoText(int rc) {
    return std::strerror(rc < 0 ? -rc : rc);
}

}  // namespace

V4l2Sink::V4l2Sink(std::string devicePath, std::unique_ptr<V4l2Device> device)
    : path_(std::move(devicePath)), device_(std::move(device)) {}

V4l2Sink::~V4l2Sink() {
    if (open_ || device_) release();
}

int V4l2Sink::fail(std::string* error, const std::string& what, int rc) {
    release();
    if (error) *error = "v4l2:" + path_ + ": " + what;
    return rc;
}

void V4l2Sink::release() {
    if (!device_) return;
    if (streaming_) {
        int type = V4L2_BUF_TYPE_VIDEO_OUTPUT;
        device_->ioctl(VIDIOC_STREAMOFF, &type);
        streaming_ = false;
    }
    for (Buffer& b : buffers_) {
        if (b.data) device_->unmap(b.data, b.length);
    }
    if (!buffers_.empty()) {
        v4l2_requestbuffers req{};
        req.count = 0;
        req.type = V4L2_BUF_TYPE_VIDEO_OUTPUT;
        req.memory = V4L2_MEMORY_MMAP;
        device_->ioctl(VIDIOC_REQBUFS, &req);
    }
    buffers_.clear();
    device_->close();
    open_ = false;
}

int V4l2Sink::open(const VideoFormat& requested, std::string* error) {
    if (!device_) {
        if (error) *error = "v4l2:" + path_ + ": no device";
        return -ENODEV;
    }
    if (open_) {
        if (error) *error = "v4l2:" + path_ + ": already open";
        return -EBUSY;
    }
    if (const std::string bad = checkVideoFormat(requested); !bad.empty()) {
        if (error) *error = "v4l2:" + path_ + ": " + bad;
        return -EINVAL;
    }
    stats_ = {};
    started_ = false;
    int rc = device_->open(path_);
    if (rc != 0) return fail(error, "cannot open: " + errnoText(rc), rc);

    v4l2_capability cap{};
    rc = device_->ioctl(VIDIOC_QUERYCAP, &cap);
    if (rc != 0) return fail(error, "not a V4L2 device (QUERYCAP: " + errnoText(rc) + ")", rc);
    const std::uint32_t caps =
        (cap.capabilities & V4L2_CAP_DEVICE_CAPS) ? cap.device_caps : cap.capabilities;
    if (!(caps & V4L2_CAP_VIDEO_OUTPUT)) {
        if (caps & V4L2_CAP_VIDEO_OUTPUT_MPLANE) {
            return fail(error, "offers only multi-planar video output, which is not supported",
                        -ENODEV);
        }
        if (caps & (V4L2_CAP_VIDEO_CAPTURE | V4L2_CAP_VIDEO_CAPTURE_MPLANE)) {
            return fail(error, "is a video capture device, not a video output device", -ENODEV);
        }
        return fail(error, "is not a video output device", -ENODEV);
    }
    if (!(caps & V4L2_CAP_STREAMING)) {
        return fail(error, "does not support streaming (mmap) I/O", -ENODEV);
    }

    v4l2_std_id standard = V4L2_STD_NTSC;
    rc = device_->ioctl(VIDIOC_S_STD, &standard);
    if (rc == 0) {
        stats_.standardSet = true;
    } else if (rc != -ENOTTY && rc != -ENODATA) {
        return fail(error, "refused the NTSC standard (S_STD: " + errnoText(rc) + ")", rc);
    }

    const std::uint32_t fourcc = fourccOf(requested.format);
    const int wantLines = requested.height / 2;
    v4l2_format fmt{};
    fmt.type = V4L2_BUF_TYPE_VIDEO_OUTPUT;
    fmt.fmt.pix.width = static_cast<std::uint32_t>(requested.width);
    fmt.fmt.pix.height = static_cast<std::uint32_t>(wantLines);  // per field (ALTERNATE)
    fmt.fmt.pix.pixelformat = fourcc;
    fmt.fmt.pix.field = V4L2_FIELD_ALTERNATE;
    fmt.fmt.pix.colorspace = V4L2_COLORSPACE_SMPTE170M;
    const std::string asked = fourccText(fourcc) + " " + std::to_string(requested.width) + "x" +
                              std::to_string(wantLines) + " per field, alternate";
    rc = device_->ioctl(VIDIOC_S_FMT, &fmt);
    if (rc != 0)
        return fail(error, "refused the format " + asked + " (S_FMT: " + errnoText(rc) + ")", rc);
    fmt = {};
    fmt.type = V4L2_BUF_TYPE_VIDEO_OUTPUT;
    rc = device_->ioctl(VIDIOC_G_FMT, &fmt);
    if (rc != 0) return fail(error, "G_FMT failed: " + errnoText(rc), rc);
    const v4l2_pix_format& pix = fmt.fmt.pix;
    if (pix.pixelformat != fourcc || pix.field != V4L2_FIELD_ALTERNATE || pix.width == 0 ||
        pix.height == 0) {
        return fail(error,
                    "refused the format " + asked + ": it offers " + fourccText(pix.pixelformat) +
                        " " + std::to_string(pix.width) + "x" + std::to_string(pix.height) + ", " +
                        fieldText(pix.field),
                    -EINVAL);
    }
    format_ = requested;
    format_.width = static_cast<int>(pix.width);
    format_.height = static_cast<int>(pix.height) * 2;
    deviceFieldLines_ = static_cast<int>(pix.height);
    const std::uint32_t rowBytes =
        pix.width * static_cast<std::uint32_t>(bytesPerPixel(format_.format));
    bytesPerLine_ = std::max(pix.bytesperline, rowBytes);
    sizeImage_ = std::max(pix.sizeimage, bytesPerLine_ * pix.height);

    v4l2_requestbuffers req{};
    req.count = kBufferCount;
    req.type = V4L2_BUF_TYPE_VIDEO_OUTPUT;
    req.memory = V4L2_MEMORY_MMAP;
    rc = device_->ioctl(VIDIOC_REQBUFS, &req);
    if (rc != 0) return fail(error, "cannot get mmap buffers (REQBUFS: " + errnoText(rc) + ")", rc);
    buffers_.resize(req.count);
    if (req.count < kMinBuffers) {
        return fail(error,
                    "granted " + std::to_string(req.count) + " buffers, needs at least " +
                        std::to_string(kMinBuffers),
                    -ENOMEM);
    }
    for (unsigned i = 0; i < req.count; ++i) {
        v4l2_buffer b{};
        b.index = i;
        b.type = V4L2_BUF_TYPE_VIDEO_OUTPUT;
        b.memory = V4L2_MEMORY_MMAP;
        rc = device_->ioctl(VIDIOC_QUERYBUF, &b);
        if (rc != 0) return fail(error, "QUERYBUF failed: " + errnoText(rc), rc);
        if (b.length < sizeImage_) {
            return fail(error,
                        "buffer " + std::to_string(i) + " holds " + std::to_string(b.length) +
                            " bytes, a field needs " + std::to_string(sizeImage_),
                        -EINVAL);
        }
        int mapError = 0;
        void* p = device_->map(b.length, b.m.offset, &mapError);
        if (!p)
            return fail(error, "mmap failed: " + errnoText(mapError),
                        mapError ? mapError : -ENOMEM);
        buffers_[i] = {p, b.length, false};
        auto* bytes = static_cast<std::uint8_t*>(p);
        for (int y = 0; y < deviceFieldLines_; ++y) {
            fillBlack(format_.format, bytes + static_cast<std::size_t>(y) * bytesPerLine_,
                      format_.width);
        }
    }
    stats_.buffers = static_cast<int>(req.count);

    int type = V4L2_BUF_TYPE_VIDEO_OUTPUT;
    rc = device_->ioctl(VIDIOC_STREAMON, &type);
    if (rc != 0) return fail(error, "STREAMON failed: " + errnoText(rc), rc);
    streaming_ = true;
    open_ = true;
    return 0;
}

int V4l2Sink::reclaim() {
    for (;;) {
        v4l2_buffer b{};
        b.type = V4L2_BUF_TYPE_VIDEO_OUTPUT;
        b.memory = V4L2_MEMORY_MMAP;
        const int rc = device_->ioctl(VIDIOC_DQBUF, &b);
        if (rc == -EAGAIN) return 0;
        if (rc != 0) return rc;
        if (b.index < buffers_.size()) buffers_[b.index].queued = false;
    }
}

int V4l2Sink::writeField(const FieldBuffer& field) {
    if (!open_) return -EBADF;
    if (field.lines <= 0 || !field.data || field.stride == 0) return -EINVAL;
    if (!started_ && field.parity == FieldParity::Top) {
        ++stats_.leadingTopSkipped;
        return 0;
    }
    int rc = reclaim();
    if (rc != 0) return rc;
    auto freeBuffer = [this] {
        return std::find_if(buffers_.begin(), buffers_.end(),
                            [](const Buffer& b) { return !b.queued; });
    };
    auto it = freeBuffer();
    if (it == buffers_.end()) {
        rc = device_->waitWritable(bufferWaitMs_);
        if (rc < 0) return rc;
        if (rc > 0 && (rc = reclaim()) != 0) return rc;
        it = freeBuffer();
        if (it == buffers_.end()) {
            ++stats_.fieldsDropped;
            return -EAGAIN;
        }
    }
    auto* dst = static_cast<std::uint8_t*>(it->data);
    const std::size_t rowBytes =
        static_cast<std::size_t>(format_.width) * bytesPerPixel(format_.format);
    const std::size_t copyBytes = std::min(rowBytes, field.stride);
    const int copyPixels = static_cast<int>(copyBytes / bytesPerPixel(format_.format));
    for (int y = 0; y < deviceFieldLines_; ++y) {
        std::uint8_t* row = dst + static_cast<std::size_t>(y) * bytesPerLine_;
        if (y < field.lines) {
            std::memcpy(row, field.data + static_cast<std::size_t>(y) * field.stride,
                        static_cast<std::size_t>(copyPixels) * bytesPerPixel(format_.format));
            if (copyPixels < format_.width) {
                fillBlack(
                    format_.format,
                    row + static_cast<std::size_t>(copyPixels) * bytesPerPixel(format_.format),
                    format_.width - copyPixels);
            }
        } else {
            fillBlack(format_.format, row, format_.width);
        }
    }
    v4l2_buffer b{};
    b.index = static_cast<std::uint32_t>(it - buffers_.begin());
    b.type = V4L2_BUF_TYPE_VIDEO_OUTPUT;
    b.memory = V4L2_MEMORY_MMAP;
    b.bytesused = sizeImage_;
    b.field = field.parity == FieldParity::Top ? V4L2_FIELD_TOP : V4L2_FIELD_BOTTOM;
    const double seconds = std::max(0.0, field.time);
    const double whole = std::floor(seconds);
    b.timestamp.tv_sec = static_cast<decltype(b.timestamp.tv_sec)>(whole);
    b.timestamp.tv_usec = static_cast<decltype(b.timestamp.tv_usec)>(
        std::min(999999.0, std::round((seconds - whole) * 1e6)));
    rc = device_->ioctl(VIDIOC_QBUF, &b);
    if (rc != 0) return rc;
    it->queued = true;
    started_ = true;
    ++stats_.fieldsQueued;
    return 0;
}

int V4l2Sink::close(std::string* error) {
    if (!open_) {
        if (error) *error = "v4l2:" + path_ + ": not open";
        return -EBADF;
    }
    int type = V4L2_BUF_TYPE_VIDEO_OUTPUT;
    const int rc = device_->ioctl(VIDIOC_STREAMOFF, &type);
    streaming_ = false;
    release();
    if (rc != 0) {
        if (error) *error = "v4l2:" + path_ + ": STREAMOFF failed: " + errnoText(rc);
        return rc;
    }
    return 0;
}

}  // namespace io
