// Voxel objects drawn over a finished terrain image by their screen footprint: each object's
// box projected to a pixel rectangle, only the pixels inside traced, exactly as the reference.
#pragma once

#include "ig/caster.hpp"
#include "ig/sticks.hpp"

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
void drawObjects(std::span<const ObjectLayer* const> layers, const SkyModel& sky,
                 const Camera& camera, RenderedFrame& frame, int x0, int x1, bool parallel);

// The slow twin, for tests: every pixel of columns [x0, x1) traced by traceObjects up to its
// depth, one after the other.
void drawObjectsPerPixel(std::span<const ObjectLayer* const> layers, const SkyModel& sky,
                         const Camera& camera, RenderedFrame& frame, int x0, int x1);

// What a caster's render() calls after its terrain cast: allocates the frame's objectId
// (width * height zeros) and draws every column, in parallel; nothing when `layers` is empty.
void drawObjectsOverTerrain(std::span<const ObjectLayer* const> layers, const SkyModel& sky,
                            const Camera& camera, RenderedFrame& frame);

}  // namespace ig
