#include "prp/object_restamp.hpp"

#include "prp/warp_apply_kernel.hpp"

#include <glm/geometric.hpp>

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>

namespace prp {

namespace {

// Sample points are kept within this many rendered pixels of the frame (the sampler repeats the
// edge beyond it anyway), so that 16.16 fixed point holds them.
constexpr double kPointRange = 16384.0;

std::int32_t toPoint(double v) {
    const double c = std::clamp(v - 0.5, -kPointRange, kPointRange);
    return static_cast<std::int32_t>(std::floor(c * 0x1p16));
}

// The rendered pixel containing point s (clamped to the frame).
std::size_t pixelAt(const ig::RenderedFrame& frame, glm::dvec2 s) {
    const int w = frame.width(), h = frame.height();
    const double x = std::clamp(s.x, 0.0, w - 1.0), y = std::clamp(s.y, 0.0, h - 1.0);
    if (!(x == x) || !(y == y)) return 0;  // NaN: the corner, a pixel like any other
    return static_cast<std::size_t>(y) * static_cast<std::size_t>(w) + static_cast<std::size_t>(x);
}

// Depth of a rendered pixel for the occlusion test: NaN and non-positive depths count as far.
double depthOf(const ig::RenderedFrame& frame, std::size_t at) {
    const float d = frame.depth[at];
    return d > 0.0f ? static_cast<double>(d) : std::numeric_limits<double>::infinity();
}

}  // namespace

glm::dvec2 FieldSourceMap::at(double x, double y, int firstLine, int lines, int width) const {
    switch (kind) {
        case Kind::Quadratic:
            return quadratic({x, y});
        case Kind::Homography:
            return homography({x, y});
        case Kind::Points: {
            // The nearest pixel's point, moved by the output scaling over the rest.
            const int column = std::clamp(static_cast<int>(std::floor(x)), 0, width - 1);
            const int line = std::clamp(static_cast<int>(std::lround((y - 0.5 - firstLine) * 0.5)),
                                        0, lines - 1);
            const std::size_t i = static_cast<std::size_t>(line) * stride + column;
            const double px = (xs[i] + detail::kPointHalf) * 0x1p-16;
            const double py = (ys[i] + detail::kPointHalf) * 0x1p-16;
            return {px + (x - (column + 0.5)) * windowPerOutputX,
                    py + (y - (firstLine + 2.0 * line + 0.5)) * windowPerOutputY};
        }
    }
    return {0.0, 0.0};
}

void FieldSourceMap::point(int line, int column, int firstLine, std::int32_t& px,
                           std::int32_t& py) const {
    if (kind == Kind::Points) {
        const std::size_t i = static_cast<std::size_t>(line) * stride + column;
        px = xs[i];
        py = ys[i];
        return;
    }
    const glm::dvec2 s = kind == Kind::Quadratic
                             ? quadratic({column + 0.5, firstLine + 2.0 * line + 0.5})
                             : homography({column + 0.5, firstLine + 2.0 * line + 0.5});
    px = toPoint(s.x);
    py = toPoint(s.y);
}

RestampStats restampMovingObjects(const ig::RenderedFrame& frame, const ig::Rgb8* color,
                                  const ig::Pose& fieldPose, const OutputGeometry& geometry,
                                  const FieldSourceMap& map, std::span<const ObjectMotion> motions,
                                  const FieldView& field, const IdFieldView& ids, int gainQ8,
                                  RestampScratch& scratch) {
    RestampStats stats;
    if (motions.empty() || ids.ids == nullptr || frame.objectId.empty() || field.lines < 1 ||
        field.width < 1 || frame.depth.size() != frame.objectId.size()) {
        return stats;
    }
    // The field's pixels of each moving object, in one pass over its ids.
    if (scratch.slot.size() < 65536) scratch.slot.assign(65536, -1);
    scratch.boxes.assign(motions.size(), {0, 0, 0, 0, false});
    for (std::size_t k = 0; k < motions.size(); ++k) {
        if (motions[k].id != 0) scratch.slot[motions[k].id] = static_cast<std::int32_t>(k);
    }
    for (int line = 0; line < ids.lines; ++line) {
        const std::uint16_t* row = ids.ids + static_cast<std::size_t>(line) * ids.stride;
        for (int x = 0; x < ids.width; ++x) {
            if (row[x] == 0) continue;
            const std::int32_t k = scratch.slot[row[x]];
            if (k < 0) continue;
            RestampScratch::Box& b = scratch.boxes[static_cast<std::size_t>(k)];
            if (!b.seen) {
                b = {x, x, line, line, true};
            } else {
                b.x0 = std::min(b.x0, x);
                b.x1 = std::max(b.x1, x);
                b.l1 = line;  // lines come in order
            }
        }
    }
    for (const ObjectMotion& m : motions)
        scratch.slot[m.id] = -1;

    // The field's own camera (its field of view may differ from the frame's), window pixels
    // scaled to output pixels.
    const ig::Camera camera(fieldPose, geometry.fieldWindow());
    const glm::dvec2 outputPerWindow{static_cast<double>(geometry.width) / geometry.windowWidth,
                                     static_cast<double>(geometry.height) / geometry.windowHeight};
    const glm::dvec3 frameEye = frame.pose.position;
    const SourceView source{color, frame.width(), frame.height()};
    const int bpp = static_cast<int>(bytesPerPixel(field.format));
    const bool pairs = field.format == PixelFormat::Uyvy;
    for (std::size_t k = 0; k < motions.size(); ++k) {
        const RestampScratch::Box& box = scratch.boxes[k];
        const ObjectMotion& m = motions[k];
        if (!box.seen || m.id == 0) continue;
        const std::optional<glm::dvec2> from = camera.project(m.atFrame);
        const std::optional<glm::dvec2> to = camera.project(m.atField);
        if (!from || !to) continue;  // behind the eye
        const glm::dvec2 d = (*to - *from) * outputPerWindow;
        const double shift = std::max(std::abs(d.x), std::abs(d.y));
        if (!(shift >= kMinRestampShiftPx && shift <= kMaxRestampShiftPx)) continue;
        // The object's change of range from the frame's eye, for its depth where it now is.
        const double dRange = glm::length(m.atField - frameEye) - glm::length(m.atFrame - frameEye);

        // Columns and lines the object covers now or covered as warped, a pixel more each way.
        int xa = std::max(0, static_cast<int>(std::floor(box.x0 + std::min(0.0, d.x))) - 1);
        int xb =
            std::min(field.width - 1, static_cast<int>(std::ceil(box.x1 + std::max(0.0, d.x))) + 1);
        const double lineShift = 0.5 * d.y;  // field lines per output row
        const int la =
            std::max(0, static_cast<int>(std::floor(box.l0 + std::min(0.0, lineShift))) - 1);
        const int lb = std::min(field.lines - 1,
                                static_cast<int>(std::ceil(box.l1 + std::max(0.0, lineShift))) + 1);
        if (pairs) {
            xa &= ~1;
            xb |= 1;  // UYVY widths are even
        }
        if (xa > xb || la > lb) continue;
        const int span = xb - xa + 1;
        scratch.xs.resize(static_cast<std::size_t>(span));
        scratch.ys.resize(scratch.xs.size());
        scratch.state.resize(scratch.xs.size());
        scratch.newIds.resize(scratch.xs.size());
        bool moved = false;
        for (int line = la; line <= lb; ++line) {
            const double y = field.firstLine + 2.0 * line + 0.5;
            std::uint16_t* idRow = ids.ids + static_cast<std::size_t>(line) * ids.stride;
            std::uint8_t* state = scratch.state.data();
            bool any = false;
            for (int x = xa; x <= xb; ++x) {
                const int i = x - xa;
                state[i] = 0;
                const glm::dvec2 s =
                    map.at(x + 0.5 - d.x, y - d.y, field.firstLine, field.lines, field.width);
                const std::size_t at = pixelAt(frame, s);
                if (frame.objectId[at] == m.id) {
                    bool shown = idRow[x] == m.id;
                    if (!shown) {
                        // Hidden where something of the warped field is nearer.
                        const std::size_t here = pixelAt(
                            frame, map.at(x + 0.5, y, field.firstLine, field.lines, field.width));
                        shown = !(depthOf(frame, here) < depthOf(frame, at) + dRange);
                    }
                    if (shown) {
                        state[i] = 1;
                        scratch.xs[static_cast<std::size_t>(i)] = toPoint(s.x);
                        scratch.ys[static_cast<std::size_t>(i)] = toPoint(s.y);
                        scratch.newIds[static_cast<std::size_t>(i)] = m.id;
                        any = true;
                        continue;
                    }
                }
                if (idRow[x] == m.id) {
                    state[i] = 2;
                    any = true;
                }
            }
            if (!any) continue;
            // Uncovered pixels: the background beside the object on the line (the rendered frame
            // has nothing behind it).
            for (int x = xa; x <= xb; ++x) {
                const int i = x - xa;
                if (state[i] != 2) continue;
                // The first such pixel on either side; of two, the farther (the background
                // rather than another object in front of it), else the nearer.
                int side[2] = {-1, -1};
                for (int dir = 0; dir < 2; ++dir) {
                    const int step = dir == 0 ? -1 : 1;
                    for (int c = x + step; c >= 0 && c < field.width; c += step) {
                        if (idRow[c] == m.id) continue;
                        if (c >= xa && c <= xb && state[c - xa] == 1) continue;
                        side[dir] = c;
                        break;
                    }
                }
                int nearest = side[0] >= 0 ? side[0] : side[1];
                if (side[0] >= 0 && side[1] >= 0) {
                    std::int32_t lx, ly, rx, ry;
                    map.point(line, side[0], field.firstLine, lx, ly);
                    map.point(line, side[1], field.firstLine, rx, ry);
                    const double left =
                        depthOf(frame, pixelAt(frame, {(lx + detail::kPointHalf) * 0x1p-16,
                                                       (ly + detail::kPointHalf) * 0x1p-16}));
                    const double right =
                        depthOf(frame, pixelAt(frame, {(rx + detail::kPointHalf) * 0x1p-16,
                                                       (ry + detail::kPointHalf) * 0x1p-16}));
                    if (left != right) {
                        nearest = left > right ? side[0] : side[1];
                    } else {
                        nearest = x - side[0] <= side[1] - x ? side[0] : side[1];
                    }
                }
                if (nearest < 0) {
                    state[i] = 0;  // the whole line is the object: left as warped
                    continue;
                }
                map.point(line, nearest, field.firstLine, scratch.xs[static_cast<std::size_t>(i)],
                          scratch.ys[static_cast<std::size_t>(i)]);
                scratch.newIds[static_cast<std::size_t>(i)] = idRow[nearest];
                ++stats.uncovered;
            }
            // Rewrite the runs of changed pixels (whole pairs in UYVY: the pair's chroma; the
            // region is pair-aligned, so a run's pairs lie inside it).
            for (int x = xa; x <= xb;) {
                if (state[x - xa] == 0) {
                    ++x;
                    continue;
                }
                int r0 = x, r1 = x;
                while (r1 + 1 <= xb && state[r1 + 1 - xa] != 0)
                    ++r1;
                if (pairs) {
                    r0 &= ~1;
                    r1 |= 1;
                }
                x = r1 + 1;
                for (int c = r0; c <= r1; ++c) {
                    const std::size_t i = static_cast<std::size_t>(c - xa);
                    if (state[i] != 0) continue;
                    // The other pixel of a pair: the warped field's own point and id.
                    map.point(line, c, field.firstLine, scratch.xs[i], scratch.ys[i]);
                    scratch.newIds[i] = idRow[c];
                }
                const int n = r1 - r0 + 1;
                const FieldView out{field.pixels + static_cast<std::size_t>(line) * field.stride +
                                        static_cast<std::size_t>(r0) * bpp,
                                    field.stride,
                                    n,
                                    field.firstLine + 2 * line,
                                    1,
                                    field.format};
                applyPoints(source, scratch.xs.data() + (r0 - xa), scratch.ys.data() + (r0 - xa),
                            static_cast<std::size_t>(n), out, gainQ8, false);
                for (int c = r0; c <= r1; ++c) {
                    const std::size_t i = static_cast<std::size_t>(c - xa);
                    if (state[i] == 0) continue;
                    idRow[c] = scratch.newIds[i];
                    ++stats.pixels;
                }
                moved = true;
            }
        }
        if (moved) ++stats.objects;
    }
    return stats;
}

}  // namespace prp
