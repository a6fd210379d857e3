// File and null sinks: interlaced Y4M video, PNG snapshots of woven frames, and a null sink.
#pragma once

#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#include "io/field_weaver.hpp"
#include "io/frame_sink.hpp"
#include "io/output_file.hpp"

namespace io {

// YUV4MPEG2, "Ib" (bottom field first), F30000:1001, A10:11, C422 (Uyvy, Rgb8) or Cmono (Y8).
// Each Bottom+Top pair of fields becomes one woven frame. Written under the output-file policy
// (io/output_file.hpp): a file goes to PATH.part, renamed to PATH by a successful close(); a
// failed or abandoned sink leaves no file behind; a device or FIFO is written in place; on a
// second stop signal the file is cut to its last whole frame and renamed into place.
class Y4mSink final : public FrameSink {
  public:
    explicit Y4mSink(std::string path);
    ~Y4mSink() override;
    int open(const VideoFormat& format, std::string* error) override;
    int writeField(const FieldBuffer& field) override;
    int close(std::string* error) override;
    const VideoFormat& format() const override { return format_; }
    std::uint64_t framesWritten() const { return frames_; }
    const std::string& path() const { return path_; }

  private:
    void writeFrame(const std::uint8_t* frame, std::size_t stride);
    void discard();

    std::string path_;
    VideoFormat format_;
    OutputFile out_;
    std::FILE* file_ = nullptr;
    std::unique_ptr<FieldWeaver> weaver_;
    std::vector<std::uint8_t> planar_;
    std::uint64_t frames_ = 0;
    int writeError_ = 0;
};

// Every `every`-th woven frame as DIR/frame_NNNNNN.png (RGB, or grey for Y8); NNNNNN counts
// woven frames from 0. open() creates DIR if its parent exists, and refuses a folder that is not
// empty unless `overwrite`.
class PngSink final : public FrameSink {
  public:
    PngSink(std::string directory, int every, bool overwrite = false);
    int open(const VideoFormat& format, std::string* error) override;
    int writeField(const FieldBuffer& field) override;
    int close(std::string* error) override;
    const VideoFormat& format() const override { return format_; }
    std::uint64_t filesWritten() const { return files_; }

  private:
    void writeFrame(const std::uint8_t* frame, std::size_t stride);

    std::string directory_;
    int every_;
    bool overwrite_;
    VideoFormat format_;
    std::unique_ptr<FieldWeaver> weaver_;
    std::vector<std::uint8_t> rgb_;
    std::uint64_t frames_ = 0, files_ = 0;
    int writeError_ = 0;
    std::string lastError_;
};

// Accepts and counts fields (for timing runs).
class NullSink final : public FrameSink {
  public:
    int open(const VideoFormat& format, std::string* error) override;
    int writeField(const FieldBuffer& field) override;
    int close(std::string* error) override;
    const VideoFormat& format() const override { return format_; }
    std::uint64_t fieldsWritten() const { return fields_; }

  private:
    VideoFormat format_;
    std::uint64_t fields_ = 0;
    bool open_ = false;
};

// Checks a field against `format` before a sink uses it; empty when fine.
std::string checkField(const VideoFormat& format, const FieldBuffer& field);

}  // namespace io
