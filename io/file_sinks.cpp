#include "io/file_sinks.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

#include "io/image_file.hpp"

namespace io {
namespace {

int fail(std::string* error, const std::string& message, int rc) {
    if (error) *error = message;
    return rc;
}

std::string errnoText(int e) {
    return std::strerror(e);
}

constexpr std::size_t kFileBuffer = 1 << 20;

}  // namespace

std::string checkField(const VideoFormat& format, const FieldBuffer& field) {
    if (field.lines <= 0) return "field " + std::to_string(field.index) + " has no lines";
    if (!field.data) return "field " + std::to_string(field.index) + " has no pixel data";
    const std::size_t rowBytes =
        static_cast<std::size_t>(format.width) * bytesPerPixel(format.format);
    if (field.stride < rowBytes) {
        return "field " + std::to_string(field.index) + " stride " + std::to_string(field.stride) +
               " is shorter than a " + std::to_string(format.width) + "-pixel " +
               pixelFormatName(format.format) + " line";
    }
    return {};
}

// ---- Y4M -------------------------------------------------------------------------------------

Y4mSink::Y4mSink(std::string path) : path_(std::move(path)) {}

Y4mSink::~Y4mSink() {
    discard();
}

void Y4mSink::discard() {
    out_.discard();
    file_ = nullptr;
}

int Y4mSink::open(const VideoFormat& format, std::string* error) {
    const std::string name = "y4m:" + path_;
    if (file_) return fail(error, name + ": already open", -EBUSY);
    if (path_.empty()) return fail(error, "y4m: no output path given", -EINVAL);
    if (const std::string bad = checkVideoFormat(format); !bad.empty()) {
        return fail(error, name + ": " + bad, -EINVAL);
    }
    format_ = format;
    std::string why;
    if (const int rc = out_.open(path_, &why); rc != 0) return fail(error, "y4m:" + why, rc);
    file_ = out_.get();
    if (file_ != stdout) std::setvbuf(file_, nullptr, _IOFBF, kFileBuffer);
    const char* colour = format.format == PixelFormat::Y8 ? "mono" : "422";
    char header[128];
    const int headerBytes =
        std::snprintf(header, sizeof header, "YUV4MPEG2 W%d H%d F30000:1001 Ib A10:11 C%s\n",
                      format.width, format.height, colour);
    if (std::fputs(header, file_) < 0) {
        const int e = errno ? errno : EIO;
        discard();
        return fail(error, name + ": cannot write: " + errnoText(e), -e);
    }
    const std::size_t luma = static_cast<std::size_t>(format.width) * format.height;
    const std::size_t chroma = static_cast<std::size_t>(format.width / 2) * format.height;
    const std::size_t frameBytes = format.format == PixelFormat::Y8 ? luma : luma + 2 * chroma;
    out_.keepWholeRecordsOnAbort(static_cast<std::uint64_t>(headerBytes), 6 + frameBytes);
    weaver_ = std::make_unique<FieldWeaver>(format);
    planar_.resize(static_cast<std::size_t>(format.width) * format.height * 2);
    frames_ = 0;
    writeError_ = 0;
    return 0;
}

void Y4mSink::writeFrame(const std::uint8_t* frame, std::size_t stride) {
    if (writeError_ != 0) return;
    const int w = format_.width, h = format_.height;
    const std::size_t lumaSize = static_cast<std::size_t>(w) * h;
    const std::size_t chromaSize = static_cast<std::size_t>(w / 2) * h;
    std::uint8_t* yPlane = planar_.data();
    std::uint8_t* cbPlane = yPlane + lumaSize;
    std::uint8_t* crPlane = cbPlane + chromaSize;
    for (int y = 0; y < h; ++y) {
        rowToPlanar422(format_.format, frame + static_cast<std::size_t>(y) * stride, w,
                       yPlane + static_cast<std::size_t>(y) * w,
                       cbPlane + static_cast<std::size_t>(y) * (w / 2),
                       crPlane + static_cast<std::size_t>(y) * (w / 2));
    }
    const std::size_t bytes =
        format_.format == PixelFormat::Y8 ? lumaSize : lumaSize + 2 * chromaSize;
    if (std::fputs("FRAME\n", file_) < 0 || std::fwrite(planar_.data(), 1, bytes, file_) != bytes) {
        writeError_ = errno ? errno : EIO;
        return;
    }
    ++frames_;
}

int Y4mSink::writeField(const FieldBuffer& field) {
    if (!file_) return -EBADF;
    if (!checkField(format_, field).empty()) return -EINVAL;
    weaver_->add(field, [this](const std::uint8_t* frame, std::size_t stride) {
        writeFrame(frame, stride);
    });
    return -writeError_;
}

int Y4mSink::close(std::string* error) {
    const std::string name = "y4m:" + path_;
    if (!file_) return fail(error, name + ": not open", -EBADF);
    weaver_->flush(
        [this](const std::uint8_t* frame, std::size_t stride) { writeFrame(frame, stride); });
    file_ = nullptr;
    if (writeError_ != 0) {
        out_.discard();
        return fail(error, name + ": write failed: " + errnoText(writeError_), -writeError_);
    }
    std::string why;
    if (const int rc = out_.commit(&why); rc != 0) return fail(error, "y4m:" + why, rc);
    return 0;
}

// ---- PNG -------------------------------------------------------------------------------------

PngSink::PngSink(std::string directory, int every, bool overwrite)
    : directory_(std::move(directory)), every_(every < 1 ? 1 : every), overwrite_(overwrite) {}

int PngSink::open(const VideoFormat& format, std::string* error) {
    const std::string name = "png:" + directory_;
    if (directory_.empty()) return fail(error, "png: no output directory given", -EINVAL);
    if (const std::string bad = checkVideoFormat(format); !bad.empty()) {
        return fail(error, name + ": " + bad, -EINVAL);
    }
    std::string why;
    if (const int rc = checkOutputFolder(directory_, overwrite_, &why); rc != 0) {
        return fail(error, "png:" + why, rc);
    }
    struct stat st {};
    if (::stat(directory_.c_str(), &st) != 0) {
        if (errno != ENOENT || ::mkdir(directory_.c_str(), 0755) != 0) {
            const int e = errno;
            return fail(error, name + ": cannot create directory: " + errnoText(e), -e);
        }
    } else if (!S_ISDIR(st.st_mode)) {
        return fail(error, name + ": is not a directory", -ENOTDIR);
    }
    if (::access(directory_.c_str(), W_OK | X_OK) != 0) {
        const int e = errno;
        return fail(error, name + ": directory is not writable: " + errnoText(e), -e);
    }
    format_ = format;
    weaver_ = std::make_unique<FieldWeaver>(format);
    if (format.format != PixelFormat::Y8) {
        rgb_.resize(static_cast<std::size_t>(format.width) * format.height * 3);
    }
    frames_ = files_ = 0;
    writeError_ = 0;
    return 0;
}

void PngSink::writeFrame(const std::uint8_t* frame, std::size_t stride) {
    const std::uint64_t number = frames_++;
    if (writeError_ != 0 || number % static_cast<std::uint64_t>(every_) != 0) return;
    char file[32];
    std::snprintf(file, sizeof file, "/frame_%06llu.png", static_cast<unsigned long long>(number));
    const int w = format_.width, h = format_.height;
    int rc;
    if (format_.format == PixelFormat::Y8) {
        rc = writePng8(directory_ + file, w, h, 1, {frame, static_cast<std::size_t>(w) * h},
                       &lastError_);
    } else {
        for (int y = 0; y < h; ++y) {
            rowToRgb(format_.format, frame + static_cast<std::size_t>(y) * stride, w,
                     rgb_.data() + static_cast<std::size_t>(y) * w * 3);
        }
        rc = writePng8(directory_ + file, w, h, 3, rgb_, &lastError_);
    }
    if (rc != 0) {
        writeError_ = -rc;
    } else {
        ++files_;
    }
}

int PngSink::writeField(const FieldBuffer& field) {
    if (!weaver_) return -EBADF;
    if (!checkField(format_, field).empty()) return -EINVAL;
    weaver_->add(field, [this](const std::uint8_t* frame, std::size_t stride) {
        writeFrame(frame, stride);
    });
    return -writeError_;
}

int PngSink::close(std::string* error) {
    if (!weaver_) return fail(error, "png:" + directory_ + ": not open", -EBADF);
    weaver_->flush(
        [this](const std::uint8_t* frame, std::size_t stride) { writeFrame(frame, stride); });
    weaver_.reset();
    if (writeError_ != 0) return fail(error, "png:" + lastError_, -writeError_);
    return 0;
}

// ---- null ------------------------------------------------------------------------------------

int NullSink::open(const VideoFormat& format, std::string* error) {
    if (const std::string bad = checkVideoFormat(format); !bad.empty()) {
        return fail(error, "null: " + bad, -EINVAL);
    }
    format_ = format;
    fields_ = 0;
    open_ = true;
    return 0;
}

int NullSink::writeField(const FieldBuffer& field) {
    if (!open_) return -EBADF;
    if (!checkField(format_, field).empty()) return -EINVAL;
    ++fields_;
    return 0;
}

int NullSink::close(std::string* error) {
    if (!open_) return fail(error, "null: not open", -EBADF);
    open_ = false;
    return 0;
}

}  // namespace io
