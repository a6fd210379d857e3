#include "io/field_weaver.hpp"

#include <algorithm>
#include <cstring>

namespace io {

FieldWeaver::FieldWeaver(const VideoFormat& format)
    : format_(format),
      stride_(static_cast<std::size_t>(format.width) * bytesPerPixel(format.format)),
      frame_(stride_ * static_cast<std::size_t>(format.height)) {
    for (int y = 0; y < format_.height; ++y) {
        fillBlack(format_.format, frame_.data() + y * stride_, format_.width);
    }
}

void FieldWeaver::copyLines(const FieldBuffer& field) {
    if (!field.data) return;
    const int lines = std::min(field.lines, fieldLines(format_.height, field.parity));
    const std::size_t bytes = std::min(stride_, field.stride);
    const int first = fieldFirstLine(field.parity);
    for (int i = 0; i < lines; ++i) {
        std::memcpy(frame_.data() + static_cast<std::size_t>(first + 2 * i) * stride_,
                    field.data + static_cast<std::size_t>(i) * field.stride, bytes);
    }
}

}  // namespace io
