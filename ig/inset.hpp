// High-resolution target areas nested in a global terrain (docs/design/insets.md): finer maps
// over rectangles of the global one, with their own pyramids, met by every ray before the
// global terrain wherever they lie nearer.
#pragma once

#include "ig/caster.hpp"
#include "ig/terrain.hpp"

#include <glm/vec2.hpp>

#include <memory>
#include <string>
#include <vector>

namespace ig {

// A finer map for the global cells [x0, x0 + cellsX) x [y0, y0 + cellsY): its samples lie on
// the global grid subdivided `factor` times (a power of two, 2..256), its south-west sample on
// global sample (x0, y0), so it holds cellsX * factor + 1 by cellsY * factor + 1 samples at
// the global spacing / factor. Its height quantisation may differ from the global map's.
struct InsetSource {
    std::string name;  // named in errors ("inset 1", a file name)
    TerrainMap fine;
    int x0 = 0;
    int y0 = 0;
    int factor = 2;
};

// A nested inset: its map in local coordinates and where it lies. The map holds the inset's
// samples inside a skirt of a few global cells of the global surface at the inset's spacing.
struct Inset {
    std::string name;
    TerrainMap map;
    glm::dvec2 origin{0.0};    // world position of the map's sample (0, 0)
    int mapX0 = 0, mapY0 = 0;  // the global sample at the map's sample (0, 0)
    int x0 = 0, y0 = 0;        // global samples of the inset's south-west and north-east corners
    int x1 = 0, y1 = 0;
    int factor = 1;
    glm::dvec2 coverMin{0.0}, coverMax{0.0};  // the inset's square, world metres

    // Whether world (x, y) lies over the inset (its edges included).
    bool covers(double x, double y) const;
};

// The global terrain and its insets, as one surface: the inset's wherever one lies, the global
// map's elsewhere. Nesting changes both maps where they meet:
// - the inset's outer `blendCells` fine cells blend (smoothstep) its heights and colours toward
//   the global surface, so that on its edge it is the global surface: no seam, as between
//   pyramid levels;
// - the global samples over an inset become the lower envelope of the inset's samples around
//   each (the least of them over the global cells the sample spans), so the global surface
//   there stays under the inset's and a ray meets the inset first; further away, where the
//   inset's coarse levels and the global ones meet, the global data is a slightly low copy of
//   the same terrain rather than a hole.
class NestedTerrain {
  public:
    // Throws InputError naming the inset for one that does not fit the global map (size,
    // spacing, placement, a factor not a power of two, overlapping another, heights outside the
    // global quantisation's range) or a negative blend width.
    NestedTerrain(TerrainMap global, std::vector<InsetSource> insets, int blendCells = 8);

    const TerrainMap& global() const { return global_; }
    const std::vector<Inset>& insets() const { return insets_; }

    // Surface height (the finest data) at world (x, y), as TerrainMap::surfaceHeight.
    double surfaceHeight(double x, double y) const;
    // Nearest exact hit of the ray on the global map and on every inset (world point).
    RayHit intersect(const glm::dvec3& origin, const glm::dvec3& dir) const;
    // Distance along `dir` (unit) of the first surface entry in [ta, tb] over every map, as
    // entryBeyond; negative where there is none.
    double entryBeyond(const glm::dvec3& origin, const glm::dvec3& dir, double ta, double tb) const;
    // The global map with its samples over each inset raised to the greatest of the inset's
    // samples around each: a surface on or above the nested one everywhere (a flight model's
    // floor that keeps the eye above every inset), the global one away from the insets.
    TerrainMap upperGround() const;
    // The nested surface as one map over the global extent at the finest inset's spacing:
    // that inset's samples where it lies, elsewhere the surface (global or a coarser inset's)
    // sampled and rounded, with its colours. What the nested caster is checked against (the
    // whole fine terrain in memory); factor^2 times the global map's memory.
    TerrainMap fineEquivalent() const;
    // Colours every map by the elevation ramp over the global map's range and water level
    // (elevationRampAlbedo): the same colour at the same height in every map.
    void applyRamp();

  private:
    TerrainMap global_;
    std::vector<Inset> insets_;
};

// A caster over a nested terrain: the global map's frame, then each inset's own caster over the
// columns where the inset can show, the nearer hit kept per pixel (depth, then colour). The
// reference, naive and fast casters (any levels, kernel, supersampling, sun lighting: each map
// lit by its own normals); the span caster and objects are refused with InputError. The image does
// not depend on the thread count. Renders as one work unit (FrameStream runs it on every thread, no
// overlap between frames).
std::unique_ptr<Caster> makeNestedCaster(CasterKind kind, const NestedTerrain& terrain,
                                         const RenderOptions& options = {});

// renderFrame over a nested terrain: the view is checked against, and the nine control points
// cast on, the nested surface.
RenderedFrame renderNestedFrame(const Caster& caster, const NestedTerrain& terrain,
                                const Pose& pose, const Intrinsics& intrinsics, double time = 0.0,
                                std::uint64_t sequence = 0, double nearM = 0.0);

// The synthetic generator's samples over global cells [x0, x0 + cellsX) x [y0, y0 + cellsY)
// of a synthetic map with `spacing`, `factor` times finer (its finest detail octaves follow
// the spacing, so the inset holds detail the global map lacks). Throws InputError where the
// finer synthetic map would exceed the generator's size.
InsetSource syntheticInset(std::uint64_t seed, double spacing, int x0, int y0, int cellsX,
                           int cellsY, int factor);

}  // namespace ig
