// A grid of thumbnails of frames spread evenly over a run, written as one PNG.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "io/field_weaver.hpp"
#include "io/video_format.hpp"

namespace io {

// Holds at most columns x rows thumbnails. When full it drops every other one and keeps only
// every second offered frame from then on, so at any time the sheet shows between half and all
// of its cells, evenly spaced over everything offered so far, first frame included.
class ContactSheet {
  public:
    ContactSheet(int columns, int rows, int thumbWidth);
    ~ContactSheet();

    // Offers one woven frame of `format` (`stride` bytes per line).
    void offer(const VideoFormat& format, const std::uint8_t* frame, std::size_t stride);
    // Offers one field; fields are woven (bottom first) and each completed frame is offered.
    void offerField(const VideoFormat& format, const FieldBuffer& field);
    // Writes the grid as an RGB PNG (atomically); 0 or -errno with `error` naming `path`.
    int write(const std::string& path, std::string* error);

    int count() const { return static_cast<int>(thumbs_.size()); }
    std::uint64_t offered() const { return offered_; }
    // The offer number (0-based) of each kept thumbnail, in order.
    std::vector<std::uint64_t> frameNumbers() const;
    int thumbWidth() const { return thumbWidth_; }
    int thumbHeight() const { return thumbHeight_; }
    // RGB pixels of thumbnail `i` (thumbWidth x thumbHeight).
    const std::vector<std::uint8_t>& thumbnail(int i) const { return thumbs_[i].rgb; }

  private:
    struct Thumb {
        std::uint64_t number;
        std::vector<std::uint8_t> rgb;
    };

    int columns_, rows_, thumbWidth_;
    int thumbHeight_ = 0;
    std::uint64_t offered_ = 0;
    std::uint64_t every_ = 1;
    std::vector<Thumb> thumbs_;
    std::vector<std::uint8_t> rowRgb_;
    std::vector<std::uint32_t> sums_;
    std::unique_ptr<FieldWeaver> weaver_;
};

}  // namespace io
