// Weaves alternating fields (NTSC: bottom first) into full frames.
#pragma once

#include <cstdint>
#include <vector>

#include "io/video_format.hpp"

namespace io {

// A Bottom field starts a frame and the next Top field completes it. Lines a frame never got
// (a Top with no Bottom before it, or a Bottom left at the end) keep the previous frame's lines,
// black at the start, so every field appears in exactly one frame.
class FieldWeaver {
  public:
    explicit FieldWeaver(const VideoFormat& format);

    // Copies `field` into the frame; calls `emit(frame, stride)` for each frame it completes
    // (a Bottom arriving while another Bottom waits first completes the waiting frame).
    template <class Emit>
    void add(const FieldBuffer& field, Emit&& emit) {
        if (field.parity == FieldParity::Bottom && pending_) {
            emit(frame_.data(), stride_);
            pending_ = false;
        }
        copyLines(field);
        if (field.parity == FieldParity::Top) {
            emit(frame_.data(), stride_);
            pending_ = false;
        } else {
            pending_ = true;
        }
    }
    // Completes a waiting Bottom-only frame, if any.
    template <class Emit>
    void flush(Emit&& emit) {
        if (pending_) emit(frame_.data(), stride_);
        pending_ = false;
    }
    bool pending() const { return pending_; }
    const VideoFormat& format() const { return format_; }
    std::size_t stride() const { return stride_; }

  private:
    void copyLines(const FieldBuffer& field);

    VideoFormat format_;
    std::size_t stride_;
    std::vector<std::uint8_t> frame_;
    bool pending_ = false;
};

}  // namespace io
