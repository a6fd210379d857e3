// Still-image files: PNG (8-bit grey/RGB, 16-bit grey) and PFM (float depth) writers.
#pragma once

#include <cstdint>
#include <span>
#include <string>

namespace io {

// Writes an 8-bit PNG of `channels` (1 grey, 3 RGB) interleaved samples, rows top first.
// `path` "-" writes to stdout. Writes to a temporary file and renames it, so a failure never
// leaves a half-written file; returns 0 or -errno, and sets `error` to a message naming the path.
int writePng8(const std::string& path, int width, int height, int channels,
              std::span<const std::uint8_t> pixels, std::string* error = nullptr);
// 16-bit grey PNG, rows top first.
int writePng16(const std::string& path, int width, int height,
               std::span<const std::uint16_t> pixels, std::string* error = nullptr);
// Portable float map, one channel ("Pf"), little-endian, rows top first in the argument (the
// file stores them bottom first, as the format says). +inf stays +inf.
int writePfm(const std::string& path, int width, int height, std::span<const float> values,
             std::string* error = nullptr);

}  // namespace io
