// High-resolution target areas nested in a global terrain (docs/design/insets.md): finer maps
// over rectangles of the global one, with their own pyramids, met by every ray before the
// global terrain wherever they lie nearer.
#pragma once

#include "ig/caster.hpp"
#include "ig/terrain.hpp"

#include <glm/vec2.hpp>

#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <utility>
#include <vector>

namespace ig {

// Global cells of the global surface around each inset's own samples in its map.
inline constexpr int kInsetSkirtCells = 4;

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
// The maps of a nested terrain as the casters read them, held elsewhere: the global map and
// each inset's placement and map (a NestedTerrain's, or paged from a database).
struct NestedMaps {
    struct Part {
        const Inset* placement = nullptr;  // where it lies (its own map unused)
        const TerrainMap* map = nullptr;   // its map, in the inset's local coordinates
    };
    const TerrainMap* global = nullptr;
    std::vector<Part> insets;

    // As NestedTerrain's.
    double surfaceHeight(double x, double y) const;
    RayHit intersect(const glm::dvec3& origin, const glm::dvec3& dir) const;
    double entryBeyond(const glm::dvec3& origin, const glm::dvec3& dir, double ta, double tb) const;
};

// The ground of a nested terrain: the surface of the insets where they lie, the global map's
// elsewhere (a pose's +H over a paged database with insets).
class NestedGround final : public Ground {
  public:
    explicit NestedGround(NestedMaps maps) : maps_(std::move(maps)) {}
    double groundHeight(double x, double y) const override { return maps_.surfaceHeight(x, y); }
    double extentX() const override { return maps_.global->extentX(); }
    double extentY() const override { return maps_.global->extentY(); }

  private:
    NestedMaps maps_;  // a copy: the maps it points to must outlive this
};

// What nesting needs of the global map before reading its samples: its size, spacing and
// height quantisation.
struct GlobalGrid {
    int width = 0, height = 0;
    double spacingX = 1.0, spacingY = 1.0, heightScale = 1.0, heightOffset = 0.0;
    static GlobalGrid of(const TerrainMap& map);
};

// The global samples over an inset, lowered: samples [x0, x1] x [y0, y1], rows south first.
struct InsetLowering {
    int x0 = 0, y0 = 0, x1 = 0, y1 = 0;
    std::vector<std::uint16_t> raw;
};

// NestedTerrain's nesting in steps, for a global map never held whole (a database being
// built): the lowerings need only the insets; each inset's map needs only a window of the
// lowered global map around it (window()). NestedTerrain's constructor runs the same steps
// over the whole map, so the two give the same maps to the bit.
class InsetNesting {
  public:
    // Checks the insets as NestedTerrain does (InputError naming the inset).
    InsetNesting(const GlobalGrid& grid, std::vector<InsetSource> sources, int blendCells);

    std::size_t size() const { return placed_.size(); }
    // Inset k's placement (its map empty until nest()).
    const Inset& placement(std::size_t k) const { return placed_[k]; }
    const std::vector<InsetLowering>& lowerings() const { return lowerings_; }
    // Lowers the samples of global rows [y0, y0 + rows) (full width, `heights` row-major) that
    // lie over an inset.
    void lowerRows(int y0, int rows, std::uint16_t* heights) const;
    // The global samples [x0, x1] x [y0, y1] inset k's map is made from.
    void window(std::size_t k, int& x0, int& y0, int& x1, int& y1) const;
    // Inset k nested: `lowered` holds the lowered global samples (every lowering applied) and
    // colours over at least window(k), its sample (0, 0) on global sample (ox, oy); the
    // inset's box reaches down to global raw height `floorRaw`.
    Inset nest(std::size_t k, const TerrainMap& lowered, int ox, int oy,
               std::uint16_t floorRaw) const;

  private:
    GlobalGrid grid_;
    std::vector<InsetSource> sources_;
    std::vector<std::vector<std::uint16_t>> fineRaw_;
    std::vector<Inset> placed_;
    std::vector<InsetLowering> lowerings_;
    int blendCells_ = 0;
};

class NestedTerrain {
  public:
    // Throws InputError naming the inset for one that does not fit the global map (size,
    // spacing, placement, a factor not a power of two, overlapping another, heights outside the
    // global quantisation's range) or a negative blend width.
    NestedTerrain(TerrainMap global, std::vector<InsetSource> insets, int blendCells = 8);
    // Insets nested already (InsetNesting, or read back from a database): `global` holds the
    // lowered samples. Throws InputError naming the inset whose map does not fit its
    // placement or the global map's spacing and quantisation.
    static NestedTerrain fromNested(TerrainMap global, std::vector<Inset> insets);

    const TerrainMap& global() const { return global_; }
    const std::vector<Inset>& insets() const { return insets_; }
    // The maps, for the casters (valid while this lives and is not moved).
    NestedMaps maps() const;

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
    NestedTerrain() = default;
    TerrainMap global_;
    std::vector<Inset> insets_;
};

// Checks insets nested already (read back from a database) against the global grid: each
// placement within the map and by the nesting's rules, each map (`maps[k]`, inset k's) of the
// size, spacing and height quantisation its placement needs, none overlapping or touching
// another. Throws InputError naming the inset.
void checkNestedInsets(const GlobalGrid& global, std::span<const Inset> insets,
                       std::span<const TerrainMap* const> maps);

// A caster over a nested terrain: the global map's frame, then each inset's own caster over the
// columns where the inset can show, the nearer hit kept per pixel (depth, then colour). The
// reference, naive and fast casters (any levels, kernel, supersampling, sun lighting: each map
// lit by its own normals); the span caster is refused with InputError. Objects
// (RenderOptions::objects, a layer over the global grid standing on the nested surface) are drawn
// by the global pass and hidden where an inset's surface lies nearer. The image does not depend
// on the thread count. Renders as one work unit (FrameStream runs it on every thread, no
// overlap between frames).
std::unique_ptr<Caster> makeNestedCaster(CasterKind kind, const NestedTerrain& terrain,
                                         const RenderOptions& options = {});
// The same over maps held elsewhere (a paged database's), each with its own options (its
// pyramid and slope bounds); `insetOptions` one per inset of `maps`. `maps` is copied; the maps
// it points to must outlive the caster.
std::unique_ptr<Caster> makeNestedCaster(CasterKind kind, const NestedMaps& maps,
                                         const RenderOptions& globalOptions,
                                         const std::vector<RenderOptions>& insetOptions);

// The caster of a nested caster's global pass (over the global map alone, without the objects'
// composite), or nullptr when `caster` is not a nested caster.
const Caster* nestedGlobalCaster(const Caster& caster);

// renderFrame over a nested terrain: the view is checked against, and the nine control points
// cast on, the nested surface.
RenderedFrame renderNestedFrame(const Caster& caster, const NestedTerrain& terrain,
                                const Pose& pose, const Intrinsics& intrinsics, double time = 0.0,
                                std::uint64_t sequence = 0, double nearM = 0.0);
RenderedFrame renderNestedFrame(const Caster& caster, const NestedMaps& maps, const Pose& pose,
                                const Intrinsics& intrinsics, double time = 0.0,
                                std::uint64_t sequence = 0, double nearM = 0.0);

// The checks and control points of renderNestedFrame on their own (a frame made otherwise, such
// as a stereo pair's reprojected right eye): InputError for a view renderFrame refuses or a
// camera on or below an inset's surface; the nine control points cast on the nested surface
// (beyond frame.nearM).
void validateNestedView(const NestedMaps& maps, const Pose& pose, const Intrinsics& intrinsics);
void castNestedControlPoints(const NestedMaps& maps, const Camera& camera, RenderedFrame& frame);

// The options of each inset's own pass, as the nested caster draws it: `insetOptions` (one per
// inset of `maps`) without objects, and a sun lighting lit by the inset map's own normals.
std::vector<RenderOptions> insetPassOptions(const NestedMaps& maps,
                                            const std::vector<RenderOptions>& insetOptions);

// The synthetic generator's samples over global cells [x0, x0 + cellsX) x [y0, y0 + cellsY)
// of a synthetic map with `spacing`, `factor` times finer (its finest detail octaves follow
// the spacing, so the inset holds detail the global map lacks). Throws InputError where the
// finer synthetic map would exceed the generator's size.
InsetSource syntheticInset(std::uint64_t seed, double spacing, int x0, int y0, int cellsX,
                           int cellsY, int factor);

}  // namespace ig
