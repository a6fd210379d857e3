#include "prp/id_warp.hpp"

#include "prp/warp_apply_kernel.hpp"

namespace prp {

using namespace detail;

namespace {

// One output row at a time, the row walkers of the colour kernels (so the points are the
// colour's to the bit: the SIMD colour kernels are bit-identical to the scalar one).
template <class Rows>
void warpRows(const IdSource& source, Rows rows, const IdFieldView& field) {
    for (int line = 0; line < field.lines; ++line) {
        std::uint16_t* __restrict out = field.ids + static_cast<std::size_t>(line) * field.stride;
        rows.start(field.firstLine + 2 * line + 0.5);
        for (int x = 0; x < field.width; ++x, rows.next())
            out[x] = nearestId(source, rows.px(), rows.py());
    }
}

}  // namespace

void warpIdsQuadratic(const IdSource& source, const Quadratic& sourceFromOutput,
                      const IdFieldView& field) {
    warpRows(source, QuadraticRows{sourceFromOutput}, field);
}

void warpIdsHomography(const IdSource& source, const Homography& sourceFromOutput,
                       const IdFieldView& field) {
    warpRows(source, ProjectiveRows{sourceFromOutput}, field);
}

void warpIdsPoints(const IdSource& source, const std::int32_t* xs, const std::int32_t* ys,
                   std::size_t stride, const IdFieldView& field) {
    for (int line = 0; line < field.lines; ++line) {
        const std::size_t at = static_cast<std::size_t>(line) * stride;
        std::uint16_t* __restrict out = field.ids + static_cast<std::size_t>(line) * field.stride;
        for (int x = 0; x < field.width; ++x)
            out[x] = nearestId(source, static_cast<std::int64_t>(xs[at + x]) * 65536,
                               static_cast<std::int64_t>(ys[at + x]) * 65536);
    }
}

}  // namespace prp
