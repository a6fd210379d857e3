// Voxel objects drawn over a finished terrain image by their screen footprint: each object's
// box projected to a pixel rectangle, only the pixels inside traced, exactly as the reference.
#pragma once

#include "ig/caster.hpp"
#include "ig/sticks.hpp"

#include <cstddef>
#include <span>

namespace ig {

// Draws `layers` (all on one map and object grid) over columns [x0, x1) of `frame`, whose colour
// and depth hold the terrain seen through each pixel centre (depth +inf for sky) and whose
// objectId holds width * height zeros (CHECKed). Every pixel whose centre ray may meet an
// object's box (its cells and height range, projected) walks the cells of
// those boxes up to the pixel's depth and composes the voxels it meets front to back over the
// terrain colour: the colour, id and depth traceObjects gives for the same ray and depth. Other
// pixels are left bit for bit. Rows of tiles go to the library's workers when `parallel` (call
// it inside the caster's thread arena); the image does not depend on how they are split.
//
// Boxes come in two kinds (docs/design/objects.md, "Splatted columns"): a far box, whose cells are
// each a pixel or less, is walked cell by cell by every pixel of its footprint; a near box is
// splatted: each of its cells holding an entry is projected on its own and the pixels of that
// projection find the cell's span along their ray as the walk would, nearest cells first, so a
// pixel stops at its first opaque voxel after a few cells. Both give the walk's voxels.
struct ObjectPassStats {
    std::size_t boxes = 0;     // boxes with a footprint in the columns drawn
    std::size_t splatted = 0;  // of which splatted
    std::size_t columns = 0;   // the splatted boxes' cells with a projection
};
struct ObjectPassOptions {
    // A box is splatted when its footprint holds at least this many pixels per cell holding an
    // entry; 0 splats every box, +inf walks every box.
    double splatPixelsPerColumn = 4.0;
    ObjectPassStats* stats = nullptr;  // when set, filled
};
void drawObjects(std::span<const ObjectLayer* const> layers, const SkyModel& sky,
                 const Camera& camera, RenderedFrame& frame, int x0, int x1, bool parallel,
                 const ObjectPassOptions& options = {});

// The slow twin, for tests: every pixel of columns [x0, x1) traced by traceObjects up to its
// depth, one after the other.
void drawObjectsPerPixel(std::span<const ObjectLayer* const> layers, const SkyModel& sky,
                         const Camera& camera, RenderedFrame& frame, int x0, int x1);

// What a caster's render() calls after its terrain cast: allocates the frame's objectId
// (width * height zeros) and draws every column, in parallel; nothing when `layers` is empty.
void drawObjectsOverTerrain(std::span<const ObjectLayer* const> layers, const SkyModel& sky,
                            const Camera& camera, RenderedFrame& frame);

}  // namespace ig
