// Moving objects re-stamped at the field's instant. The warp moves what the rendered frame shows
// by the camera's motion; a vehicle moves on its own as well, so a field warped from a frame
// some fields old shows it where it was at the frame's instant. After the warp, each moving
// object the field shows is moved by its own image motion between the two instants (a point
// of it projected with the field's pose at both), its colour and id sampled from the rendered
// frame at the moved place, and the pixels it leaves take the background beside them.
#pragma once

#include "ig/camera.hpp"
#include "ig/frame.hpp"
#include "prp/id_warp.hpp"
#include "prp/warp_apply.hpp"
#include "prp/warp_fit.hpp"

#include <glm/vec3.hpp>

#include <cstdint>
#include <span>
#include <vector>

namespace prp {

// One moving object's own motion: a world point of it (the middle of its box) at the rendered
// frame's instant and at the field's.
struct ObjectMotion {
    std::uint16_t id = 0;
    glm::dvec3 atFrame{0.0};
    glm::dvec3 atField{0.0};
};

// Largest image motion of an object re-stamped (output pixels); one moving farther between
// the two instants (a jump of its trajectory, a host teleporting it) is left where it is.
inline constexpr double kMaxRestampShiftPx = 128.0;
// Smallest image motion worth re-stamping (output pixels).
inline constexpr double kMinRestampShiftPx = 1.0 / 64.0;

// Where a field samples the rendered frame: the output pixel's source point, as the field's
// warp model gives it. Quadratic and Homography: the map of output pixel centres (output-frame
// coordinates) to rendered-frame coordinates; Points: the points the depth model sampled
// (16.16 fixed point minus half a pixel, a field line every `stride` elements).
struct FieldSourceMap {
    enum class Kind { Quadratic, Homography, Points };
    Kind kind = Kind::Quadratic;
    Quadratic quadratic;
    Homography homography;
    const std::int32_t* xs = nullptr;
    const std::int32_t* ys = nullptr;
    std::size_t stride = 0;
    double windowPerOutputX = 1.0, windowPerOutputY = 1.0;  // rendered pixels per output pixel

    // Rendered-frame point seen at output-frame point (x, y) (a pixel centre is (X + 0.5,
    // Y + 0.5)) of a field whose first frame line is `firstLine` and which has `lines` lines.
    glm::dvec2 at(double x, double y, int firstLine, int lines, int width) const;
    // The sample point of field pixel (line, column) as applyPoints takes it.
    void point(int line, int column, int firstLine, std::int32_t& px, std::int32_t& py) const;
};

struct RestampStats {
    int objects = 0;              // moving objects moved in this field
    std::uint64_t pixels = 0;     // field pixels rewritten (the objects' and the uncovered ones)
    std::uint64_t uncovered = 0;  // of those, pixels an object left (background beside them)
};

// Scratch of restampMovingObjects (sized on first use, then reused).
struct RestampScratch {
    std::vector<std::int32_t> slot;  // by object id: index into the motions, -1
    struct Box {
        int x0, x1, l0, l1;  // field pixels showing the object: columns, lines (inclusive)
        bool seen;
    };
    std::vector<Box> boxes;
    std::vector<std::int32_t> xs, ys;  // one line's sample points
    std::vector<std::uint8_t> state;   // one line: 0 as warped, 1 the object, 2 uncovered
    std::vector<std::uint16_t> newIds;
};

// Moves each of `motions`' objects that `ids` shows by its image motion at `fieldPose` (roll
// included; `geometry` scales the rendered window to the output), sampling `color` (the frame's
// colour, or the processor's filtered copy of it) at `map`'s source points moved by it. An
// output pixel takes the object where the rendered pixel at the moved point is the object's and
// nothing of the warped field there is nearer (the frame's depths, the object's own change of
// range added); a pixel the object leaves takes, of the first pixels either side on its line
// that are neither the object nor covered by it, the farther (the background, not another
// object before it; the nearer one when as far). Parts of the object that the frame does not
// show (hidden then, or beyond its edge) stay missing. Rewrites only those pixels (and the
// other pixel of a UYVY pair).
// The AGC's sum is not updated (it measured the field as warped).
RestampStats restampMovingObjects(const ig::RenderedFrame& frame, const ig::Rgb8* color,
                                  const ig::Pose& fieldPose, const OutputGeometry& geometry,
                                  const FieldSourceMap& map, std::span<const ObjectMotion> motions,
                                  const FieldView& field, const IdFieldView& ids, int gainQ8,
                                  RestampScratch& scratch);

}  // namespace prp
