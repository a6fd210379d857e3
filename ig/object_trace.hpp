// Exact ray casting of sticks: a ray walked through the object grid, each voxel a box,
// semi-transparent voxels blended front to back over what lies behind (the secondary ray).
#pragma once

#include "ig/caster.hpp"
#include "ig/sticks.hpp"

#include <glm/vec3.hpp>

#include <span>
#include <vector>

namespace ig {

// Brightness of a voxel face by the axis it faces: a fixed light from above and the south-west.
inline constexpr float kFaceShadeTop = 1.0f;
inline constexpr float kFaceShadeBottom = 0.55f;
inline constexpr float kFaceShadeX = 0.75f;  // faces looking east or west
inline constexpr float kFaceShadeY = 0.88f;  // faces looking north or south

enum class VoxelFace : std::uint8_t { Top, Bottom, X, Y };
float faceShade(VoxelFace face);

// One voxel a ray passes through.
struct VoxelHit {
    double enter = 0.0;  // ray parameter where it enters the voxel's box
    Rgba8 color;
    VoxelFace face = VoxelFace::Top;
    std::uint16_t id = 0;
    std::uint32_t seq = 0;  // position when collected (sortHits' last key)
};

// What the objects in front of a background make of a pixel.
struct ObjectShading {
    float rgb[3] = {0.0f, 0.0f, 0.0f};  // accumulated colour, 0..255, already weighted
    float transmittance = 1.0f;         // fraction of the background that shows through
    std::uint16_t id = 0;               // first object with a voxel of non-zero opacity, or 0
    double depth = 0.0;                 // where the ray enters that voxel
};

// Scratch of one worker, reused from pixel to pixel (no allocation per pixel once grown).
struct ObjectTraceScratch {
    std::vector<VoxelHit> hits;
};

// Walks the ray origin + t * dir (dir of unit length) from t = 0 to `tEnd` (the terrain hit, or
// +inf) through every layer (all on one map and one object grid), every voxel box it crosses
// in order, and accumulates their colours front to back (colour * face shade, hazed by
// distance; a voxel of opacity a passes 1 - a of what is behind it; alpha 0 passes all). Stops
// when less than 1/1024 of the background would show. Voxels the ray enters before `tStart`
// are left out (a near clipping plane).
void traceObjects(std::span<const ObjectLayer* const> layers, const glm::dvec3& origin,
                  const glm::dvec3& dir, double tEnd, const SkyModel& sky,
                  ObjectTraceScratch& scratch, ObjectShading& out, double tStart = 0.0);

// ---- The walk's parts, shared with the footprint pass (ig/object_pass.*) ----------------------
// The span [t0, t1] traceObjects walks: the ray inside the map's footprint and the layers'
// height range, up to tEnd; false when empty (or no layer holds anything).
bool objectRaySpan(std::span<const ObjectLayer* const> layers, const glm::dvec3& origin,
                   const glm::dvec3& dir, double tEnd, double& t0, double& t1);
// The same span with the layers' height range [lo, hi] worked out once (objectHeightRange);
// false when lo > hi.
bool objectHeightRange(std::span<const ObjectLayer* const> layers, float& lo, float& hi);
bool objectRaySpan(const TerrainMap& map, float lo, float hi, const glm::dvec3& origin,
                   const glm::dvec3& dir, double tEnd, double& t0, double& t1);
// Appends the voxels of `cell` the ray meets over [ta, tb] inside the cell's column, entered
// across `axis` (0 x, 1 y, -1 none: the walk starts in the cell).
void collectVoxelHits(const StickTable& table, const ObjectCell& cell, const glm::dvec3& o,
                      const glm::dvec3& d, double ta, double tb, int axis,
                      std::vector<VoxelHit>& hits);
// One cell of an object's box, as collectBoxHits tests it before decoding any run, shared with
// the footprint pass's splatted cells. First the ray's height range over [ta, tb], widened by a
// millimetre (the lists' ranges are float, their runs double), against the cell's own range
// `range` (ObjectLayer::boxColumnRanges: the hull of its entries'): false when it misses, as it
// does for most cells a ray crosses in a box.
inline bool boxCellHeightMet(const float range[2], const glm::dvec3& o, const glm::dvec3& d,
                             double ta, double tb, double& zLo, double& zHi) {
    constexpr double kListPad = 1e-3;
    const double zA = o.z + ta * d.z, zB = o.z + tb * d.z;
    zLo = (zA < zB ? zA : zB) - kListPad;
    zHi = (zA < zB ? zB : zA) + kListPad;
    return !(zHi < range[0] || zLo > range[1]);
}
// Then the voxels of the cell's entries of object `id` (`entries`: ObjectLayer::boxCellsAt) that
// the ray meets over [ta, tb], entered across `axis`; an entry whose sticks lie wholly above or
// below [zLo, zHi] is passed without decoding its runs (they would give nothing).
inline void collectBoxCellHits(const StickTable& table, std::span<const ObjectCell> entries,
                               std::uint16_t id, double zLo, double zHi, const glm::dvec3& o,
                               const glm::dvec3& d, double ta, double tb, int axis,
                               std::vector<VoxelHit>& hits) {
    for (const ObjectCell& cell : entries) {
        if (cell.id != id) continue;
        if (zHi < cell.baseZ + table.bottom(cell.stick) ||
            zLo > cell.baseZ + table.top(cell.stick)) {
            continue;
        }
        collectVoxelHits(table, cell, o, d, ta, tb, axis, hits);
    }
}
// Appends the voxels of object `box` (its id's entries only) that the ray meets within
// [t0, t1] (objectRaySpan's span): the same hits, entries and faces as traceObjects' walk finds
// in those cells, found by walking the box's cells alone from the one the ray enters first.
// `cutoff`: no cell entered beyond it is walked (nothing there can show); lowered to the entry
// of every opaque voxel found. Start it at t1 and pass it on from box to box.
void collectBoxHits(const ObjectLayer& layer, const ObjectBox& box, const glm::dvec3& o,
                    const glm::dvec3& d, double t0, double t1, std::vector<VoxelHit>& hits,
                    double& cutoff);
// Sorts hits by entry along the ray; voxels entered at the same point (objects sharing a cell)
// by id, then in the order collected: the same order however the hits were gathered.
void sortHits(std::vector<VoxelHit>& hits);
// Blends one hit (in order along the ray) into `out`; true when less than 1/1024 of what lies
// behind still shows (out.transmittance is then 0 and the walk stops).
bool blendVoxelHit(const VoxelHit& hit, const SkyModel& sky, ObjectShading& out);

// `background` seen through `shading`: the background itself (bit for bit) where nothing
// covers it, else the blend, rounded.
Rgb8 composeOver(const ObjectShading& shading, Rgb8 background);

}  // namespace ig

namespace ig {

// Visible pixels of one object in a frame's object-id image, and their bounding box
// (inclusive pixel coordinates).
struct ObjectPixels {
    std::uint16_t id = 0;
    std::uint64_t pixels = 0;
    int x0 = 0, y0 = 0, x1 = 0, y1 = 0;
};
// Every id present in frame.objectId (0 excluded), by increasing id.
std::vector<ObjectPixels> objectPixelStats(const RenderedFrame& frame);

}  // namespace ig
