// The span caster's resample: vertical-plane columns (column-major) to the pitched image's rows.
#pragma once

#include "ig/caster.hpp"

#include <cstdint>

namespace ig {

// Rows [y0, y1) of columns [j0, j1) of a column-major plane (column j starts at
// colMajor + j * height) into a row-major block: plane (j, y) goes to rows[(y - y0) * stride +
// j - j0]. 4x4 register transposes where the processor has SSE2, the plain loop elsewhere.
void spanTranspose(const std::uint32_t* colMajor, int height, int j0, int j1, int y0, int y1,
                   std::uint32_t* rows, int stride);
void spanTranspose(const float* colMajor, int height, int j0, int j1, int y0, int y1, float* rows,
                   int stride);
// The plain loop (the twin the tests compare against).
void spanTransposeReference(const std::uint32_t* colMajor, int height, int j0, int j1, int y0,
                            int y1, std::uint32_t* rows, int stride);

// The position of output pixel x of a row in plane columns, 32.32 fixed point:
// first + x * step. Rounded to 1/256 of a column, it gives the column j and the weight w / 256
// toward column j + 1.
struct SpanRowMap {
    std::int64_t first = 0, step = 0;
};
SpanRowMap spanRowMap(double firstColumn, double stretch);

// One output row from one plane row (colour packed r | g << 8 | b << 16, depth): colour
// (c_j (256 - w) + c_j+1 w + 128) >> 8 per channel; depth linear on a smooth surface (both
// finite, within 5 %), else the nearer column's (w < 128: j). The caller guarantees that every
// column read, j + 1 included, is inside the plane row.
void spanResampleRow(const std::uint32_t* __restrict__ color, const float* __restrict__ depth,
                     SpanRowMap map, int width, Rgb8* __restrict__ outColor,
                     float* __restrict__ outDepth);
// The same, pixel by pixel and channel by channel (the twin the tests compare against).
void spanResampleRowReference(const std::uint32_t* color, const float* depth, SpanRowMap map,
                              int width, Rgb8* outColor, float* outDepth);

}  // namespace ig
