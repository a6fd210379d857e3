// The ray casters (reference, naive, fast) behind one interface, plus frame rendering.
#pragma once

#include "ig/frame.hpp"
#include "ig/terrain.hpp"

#include <memory>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace ig {

class ObjectLayer;
class SlopeBlocks;
class TerrainPyramid;
struct SunLighting;

// Span: cost per terrain sample (docs/design/span_renderer.md); steep frames go to Fast.
enum class CasterKind { Reference, Naive, Fast, Span };

std::string_view casterName(CasterKind kind);
// Parses "reference" | "naive" | "fast" | "span"; throws InputError otherwise.
CasterKind parseCasterKind(std::string_view name);

// Appearance of what is not terrain.
struct SkyModel {
    Rgb8 zenith{70, 110, 190};
    Rgb8 horizon{185, 205, 230};
    // Distance haze: colour blends toward `horizon` by 1 - exp(-distance / hazeDistance);
    // 0 disables haze.
    double hazeDistance = 0.0;
    // Height fall-off (scale height, metres; 0 off): the haze's density is exp(-z / hazeFalloff)
    // / hazeDistance at height z, so hazeDistance holds at z = 0. When on, the casters draw
    // without haze and a pass over the finished frame applies it (ig/haze_pass.hpp).
    double hazeFalloff = 0.0;
};

inline constexpr int kLevelsAuto = -1;
inline constexpr int kSupersampleAuto = 0;

// The fast caster's kernels (docs/design/ray_casting.md), chosen once when the caster is built.
// On the single level every one gives the scalar kernel's image to the bit; the row batches
// give their portable twins' to the bit and the scalar kernel's within the multiresolution
// caster's accuracy (docs/design/multires.md). Auto: the widest the processor has.
// Scalar: one column at a time, one ray at a time (the twin the vector kernels are tested
// against). Avx2: four adjacent columns at a time on the single level (one ray per pixel),
// four rows of a column at a time on the multiresolution caster. Avx512: eight rows at a time
// on the multiresolution caster (four where eight do not go together); the single level has no
// wider kernel than Avx2 and runs that. Rows4Portable, Rows8Portable: the Avx2 and Avx512 row
// batches' twins, the same template on portable lanes compiled for no instruction set, equal
// to them to the bit on any processor; never chosen by Auto (slow: for tests). On the single
// level they run the scalar kernel (the four-column packets' twin).
enum class CasterKernel { Auto, Scalar, Avx2, Avx512, Rows4Portable, Rows8Portable };

std::string_view casterKernelName(CasterKernel kernel);
// Parses "auto" | "scalar" | "avx2" | "avx512" | "rows4-portable" | "rows8-portable"; throws
// InputError otherwise.
CasterKernel parseCasterKernel(std::string_view name);
// What the running processor lacks to run `kernel` ("AVX2", "AVX-512 F/DQ/VL/BW"); empty when
// it can (always for Auto and Scalar).
std::string casterKernelMissing(CasterKernel kernel);

struct RenderOptions {
    SkyModel sky;
    int threads = 0;  // 0: the library's default
    // Fast caster: coarser display levels used where a voxel's footprint falls below a pixel.
    // kLevelsAuto: as many as the map has; 0: single level (exact on the bilinear surface, the
    // default, matching the reference caster); n > 0: at most n coarser levels.
    int levels = 0;
    // Fast caster: rays per pixel stacked vertically (1..8), averaged; the same at every pitch
    // (it helps most at shallow pitch, where a pixel's footprint stretches along the view).
    // Depth is the nearest of them. kSupersampleAuto: chosen per frame from the pitch
    // (autoSupersample in ig/appearance.hpp), at most supersampleMax.
    int supersample = 1;
    int supersampleMax = 4;
    // Fast caster: its kernel (the image is bit for bit the same with each). A kernel the
    // processor lacks is refused with InputError when the caster is built.
    CasterKernel kernel = CasterKernel::Auto;
    // Fast caster, multiresolution: a long march passes max-height nodes the rays stay above
    // instead of sampling every grid line in them. Same image; off for tests and measurement.
    bool skipNodes = true;
    // Span caster: a frame is drawn on the vertical image plane when the pitched window's rows
    // stretch over at most this many vertical-plane columns per pixel, else by the fast caster.
    double spanMaxStretch = 2.0;
    // Voxel objects drawn over the terrain (not owned; all on the caster's map and one object
    // grid): the static layer, and the moving objects stamped at the frame's instant. Drawn by
    // every caster (the fast and span ones in a pass after their terrain, ig/object_pass.hpp),
    // which then fills the frame's object-id image; empty: no objects, and the images are the
    // terrain's alone, bit for bit.
    std::vector<const ObjectLayer*> objects;
    // Sun lighting applied to each finished frame (ig/lighting_pass.hpp): the casters then draw
    // the map's colours as albedo and light them by the sun at the frame's time. Null: the
    // colours as they are, bit for bit.
    std::shared_ptr<const SunLighting> lighting;
    // Fast caster: what it otherwise builds from the whole map at construction, supplied by a
    // map paged from a terrain database (ig/paged_terrain.hpp), whose arrays are filled only
    // where a frame reads them: the pyramid (with `levels` coarser levels) and the per-block
    // slope bounds. Null: built from the map. The span caster does not take them.
    std::shared_ptr<const TerrainPyramid> pyramid;
    std::shared_ptr<const SlopeBlocks> slopes;
};

// Columns of the vertical image plane per output pixel at the pitched window's most stretched
// row (1 at pitch 0; +inf where a row looks behind the vertical plane).
double spanStretch(const Camera& camera);

// Whether a caster renders roll = 0 only (the fast and span casters: the PRP applies roll).
inline bool casterNeedsLevelRoll(CasterKind kind) {
    return kind == CasterKind::Fast || kind == CasterKind::Span;
}

// Parses --levels: "auto" or a count >= 0; throws InputError otherwise.
int parseLevels(std::string_view text);

// Steps and restarts of the work units one thread rendered.
struct UnitCounters {
    std::uint64_t steps = 0;
    std::uint64_t restarts = 0;
};

// A ray caster over one terrain map. Implementations keep no per-frame state, so one caster
// may render several frames concurrently.
class Caster {
  public:
    virtual ~Caster() = default;
    virtual CasterKind kind() const = 0;
    // The kernel that renders the pixels, as recorded in RenderStats::kernel.
    virtual std::string_view kernelName() const { return "scalar"; }
    // Renders colour and depth of `camera` into `frame`, whose color and depth must already hold
    // width * height pixels of the camera's intrinsics (renderFrame does that), and fills
    // frame.stats. The reference and naive casters honour any roll; the fast caster
    // requires roll == 0 (CHECKed: callers refuse a rolled pose as bad input first).
    virtual void render(const Camera& camera, RenderedFrame& frame) const = 0;
    // The work on the whole frame after its pixels (the deferred sun lighting when
    // RenderOptions::lighting is set): render() does it; whoever renders the units does it once
    // they are all done (FrameStream).
    virtual void finishFrame(const Camera& camera, RenderedFrame& frame) const {
        (void)camera;
        (void)frame;
    }

    // The same frame as independent work units (image rows for the per-pixel casters, groups
    // of adjacent columns for the fast caster) that write disjoint pixels: rendering every unit
    // once, in any order and on any threads, gives render()'s image; the units' counters add
    // up to its stats (rays excepted). FrameStream runs them to overlap consecutive frames.
    virtual int workUnits(const Camera& camera) const = 0;
    virtual void renderUnit(const Camera& camera, RenderedFrame& frame, int unit,
                            UnitCounters& counters) const = 0;
    // For a caster whose units are groups of adjacent columns: the columns [first, second)
    // unit `unit` writes, every row of them. {0, 0} for the others (units of rows).
    virtual std::pair<int, int> unitColumns(const Camera& camera, int unit) const {
        (void)camera;
        (void)unit;
        return {0, 0};
    }
};

std::unique_ptr<Caster> makeCaster(CasterKind kind, const TerrainMap& map,
                                   const RenderOptions& options = {});

// Renders a whole frame: colour, depth, the nine control points (cast exactly by the reference
// caster through their pixel centres) and stats; with `nearM` > 0, nothing nearer than that
// plane ahead of the eye (RenderedFrame::nearM). Throws InputError for a non-finite pose, a
// camera below the terrain surface or a negative or non-finite near plane.
RenderedFrame renderFrame(const Caster& caster, const TerrainMap& map, const Pose& pose,
                          const Intrinsics& intrinsics, double time = 0.0,
                          std::uint64_t sequence = 0, double nearM = 0.0);

// Throws InputError for a non-finite pose, a degenerate image or a camera inside the terrain
// (what renderFrame checks first).
void validateView(const TerrainMap& map, const Pose& pose, const Intrinsics& intrinsics);

// Nine pixels evenly spread over an image: a 3x3 grid at 1/6, 1/2, 5/6 of width and height.
std::array<glm::dvec2, kControlPointCount> controlPointPixels(const Intrinsics& intrinsics);

// Exact hit of one ray against the map's bilinear surface (the reference surface model).
struct RayHit {
    bool hit = false;
    double distance = 0.0;  // along the normalised direction, metres
    glm::dvec3 point{0.0};
};
RayHit intersectTerrain(const TerrainMap& map, const glm::dvec3& origin, const glm::dvec3& dir);

}  // namespace ig
