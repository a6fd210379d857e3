// The fast caster (Cohen-Or sec. 2.1, with the multiresolution march): its class, shared by
// its parts. caster_fast.cpp holds the class, the kernel choice, the render loop and the
// one-ray paths; caster_packets.cpp the four-column packets; far_march.cpp the march past the
// level-0 distance; caster_rows_*.cpp the row batches, one object per instruction set.
// Internal to ig (makeFastCaster, caster_impl.hpp, makes one).
#pragma once

#include "base/check.hpp"
#include "ig/caster.hpp"
#include "ig/caster_lanes.hpp"
#include "ig/coherence.hpp"
#include "ig/far_march.hpp"
#include "ig/fast_column.hpp"
#include "ig/level0_march.hpp"
#include "ig/multires_march.hpp"
#include "ig/pyramid.hpp"
#include "ig/shading.hpp"
#include "ig/slope_bound.hpp"
#include "ig/surface_hit.hpp"

#include <glm/vec3.hpp>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <memory>
#include <optional>
#include <string_view>
#include <utility>

namespace ig::fast {

class FastCaster final : public Caster {
  public:
    FastCaster(const TerrainMap& map, const RenderOptions& options,
               std::shared_ptr<const TerrainPyramid> pyramid);

    CasterKind kind() const override { return CasterKind::Fast; }

    std::string_view kernelName() const override { return casterKernelName(kernel_); }

    // The coherence test (fast_column.hpp, climbsClear): inline in the caster's own paths
    // (columns, packets); the row batches call the out-of-line climbsClear, which is this.
    static bool climbsClear(const ColumnContext& cc, ColumnState& st, bool majorX, double rn,
                            double rz) {
        const double sMajor = majorX ? cc.spacingX : cc.spacingY;
        const double sMinor = majorX ? cc.spacingY : cc.spacingX;
        const double gap = std::abs(rn - st.prevRn), climb = rz - st.prevRz;
        if (climbsClearOf(climb, cc.maxSlope, sMinor, gap)) return true;
        // Both rays' tracks stay within this horizontal distance of the eye up to prevU.
        const double reach =
            st.prevU * (sMajor + std::max(std::abs(rn), std::abs(st.prevRn)) * sMinor);
        return climbsClearOf(climb, st.wedge.upTo(reach), sMinor, gap);
    }

    void render(const Camera& camera, RenderedFrame& frame) const override;
    void finishFrame(const Camera& camera, RenderedFrame& frame) const override;

    int workUnits(const Camera& camera) const override;

    std::pair<int, int> unitColumns(const Camera& camera, int unit) const override;

    void renderUnit(const Camera& camera, RenderedFrame& frame, int unit,
                    UnitCounters& counters) const override;

  private:
    static void checkRoll(const Camera& camera) {
        CHECK(camera.pose().roll == 0.0)
            << "fast caster renders roll = 0 (the PRP applies roll); use naive or reference";
    }

    // Renders work unit `unit` (a column, or a group of four adjacent columns).
    using UnitRenderer = void (FastCaster::*)(const MapView& mv, const Camera& camera, double d0,
                                              int unit, RenderedFrame& frame,
                                              UnitCounters& counters) const;

    // The kernel and the function that renders a work unit with it, chosen once. The
    // multiresolution caster (levels != 0): coherent rays find their level-0 hit between the
    // major grid lines where they pass from above to below the surface, by linear
    // interpolation (the paper's discrete traversal, no exact solve; see linearRay), on rows
    // batched over vector lanes where the kernel has them. The single level: columns, four at
    // a time with AVX2 where the kernel has them and one ray per pixel.
    void chooseKernel();

    // A fresh cast: its hit, if any, and where the ray stopped (the hit, or where it left the
    // map box; 0 when it misses the box).
    struct FreshCast {
        std::optional<LevelHit> hit;
        double tStop = 0.0;
    };

    // The fresh (t-parameterised) path: box clip, hierarchical skip where worthwhile, exact
    // level-0 march out to tNear, multiresolution march beyond.
    // The bottom ray always descends the max-height pyramid (hierarchical first hit); a restart
    // only when its way through the map box is long (near the nadir a march is cheaper).
    [[gnu::always_inline]] FreshCast castFresh(const TerrainRay& ray, double horiz, double d0,
                                               bool bottom, std::uint64_t& steps) const;

    // The hit from tStart on: exact on level 0 out to tNear, the multiresolution march beyond.
    std::optional<LevelHit> castFrom(const TerrainRay& ray, double horiz, double d0, double tStart,
                                     double t1, std::uint64_t& steps) const;

    Rgb8 shadeLevelHit(const LevelHit& hit, const glm::dvec3& p) const;

    // The shared haze and quantization (shading.hpp).
    Rgb8 haze(float rgb[3], double t) const {
        applyHaze(options_.sky, rgb, t);
        return quantizeColor(rgb);
    }

    // A ray of a column in major-axis form: direction d (length len); per major grid unit u it
    // travels lenPerU along d, rn minor cells and rz metres up; inv = 1 / |major component|
    // (grid units); the major axis is x (majorX) or y, travelled in direction sgn.
    struct MajorRay {
        glm::dvec3 d;
        double len, lenPerU, inv;
        bool majorX;
        int sgn;
        double rn, rz;
    };

    // Starts a column's state: its slope bounds look at the wedge its rays sweep.
    void startColumn(const Camera& camera, const ColumnContext& cc, ColumnState& st) const;

    // One ray of a column, any case: coherent, restarted, past the level-0 distance, straight
    // down. Sets the colour and the hit distance (negative: sky) and moves the state on.
    [[gnu::noinline]] void castRay(const ColumnContext& cc, const glm::dvec3& d, ColumnState& st,
                                   Rgb8& c, double& tHit) const;

    // The multiresolution caster's coherent ray (levels != 0): where the ray climbs clear of the
    // ray below (the same proof as castRay's), it marches from where that ray stopped, sampling
    // the surface where it crosses major grid lines (the bilinear surface there, linear along
    // the line) and taking its hit between the last line it passed above and the first it is
    // under, by linear interpolation of its height over the surface. False (state untouched)
    // for every other case, which castRay then casts.
    [[gnu::always_inline]] bool linearRay(const ColumnContext& cc, const glm::dvec3& d,
                                          ColumnState& st, Rgb8& c, double& tHit) const;

    // The pyramid whose nodes long marches pass, or none (RenderOptions::skipNodes).
    const TerrainPyramid* skipPyramid() const {
        return options_.skipNodes ? pyramid_.get() : nullptr;
    }

    // marchCoherent's march on the surface sampled at major grid lines, linear between them.
    // The march goes from node A (the grid line at or before uStart; uStart itself when that
    // line is behind the eye) to the following lines; the hit lies between the last node the
    // ray passed above and the first it is under. Long marches pass max-height nodes where they
    // can (skipNodes; not without pyr).
    template <bool kMajorX>
    [[gnu::always_inline]] static ColumnMarch marchLinear(const MapView& mv, const EyeGrid& eg,
                                                          const TerrainPyramid* pyr, int sgn,
                                                          double rn, double rz, double uStart,
                                                          double uNear, std::uint64_t& steps);

    // The surface (raw) where the ray crosses a level-0 major line at minor coordinate n >= 0:
    // linear along the line between the samples h0 (minor i) and h1 (minor i + 1).
    struct LineSample {
        double h = 0.0, h0 = 0.0, h1 = 0.0;
        int i = 0;
    };

    template <bool kMajorX>
    [[gnu::always_inline]] static LineSample lineSample(const std::uint16_t* heights, int w,
                                                        int minorCount, long line, double n);

    // Where the track crosses the minor grid line between major lines A and B (their samples
    // sA and sB in adjacent minor cells): the fraction s of the way from A to B, and the ray's
    // height over the surface there (linear along that minor line between A's and B's samples
    // on it). With these nodes the hit does not depend on which axis the ray marches along.
    // (invRn: 1 / rn, the major units per minor cell.)
    struct MinorNode {
        double s, diff;
    };

    [[gnu::always_inline]] static MinorNode minorNode(const LineSample& sA, const LineSample& sB,
                                                      double nA, double invRn, double zA,
                                                      double zB);

    static PyramidLevel levelZero(const MapView& mv);

    // A restarted ray (its climb over the ray below does not outrun the slope bound: steep
    // features around) starts as far out as the column's clearance chain proves it clear:
    // any ray whose track stays within one minor cell of a ray X's at equal u, and which climbs
    // at least as fast, is above the terrain wherever X passed above the cell maxima within one
    // minor cell of its own track. The ray then scans on from there against those widened maxima
    // to where it first comes near the terrain (its own link of the chain), and marches
    // coherently from there to its hit. Without a chain to start from it scans from the eye,
    // but only where the ray below stopped within kChainReach major cells (a long empty march is
    // left to the hierarchical fresh cast). False when the march cannot run (the eye is off the
    // map, or a start off it): the ray is cast fresh.
    static constexpr double kChainReach = 4096.0;

    bool restartInChain(const ColumnContext& cc, const MajorRay& ray, ColumnState& st, Rgb8& c,
                        double& tHit) const;

    // From u = uStart, the first step (its start u, not before uStart) where the ray comes down
    // to the largest cell maximum within one minor cell of the cells it crosses; where it
    // leaves the map or climbs over its highest point first, there. The step loop of
    // marchCoherent with the widened bound.
    template <bool kMajorX>
    static double clearanceScan(const MapView& mv, const EyeGrid& eg, int sgn, double rn, double rz,
                                double uStart, std::uint64_t& steps);

    // The outcome of a coherent march: colour, hit distance and the next start. False when the
    // march started outside the map (the ray must be cast fresh).
    [[gnu::always_inline]] bool finishCoherent(const ColumnContext& cc, const glm::dvec3& d,
                                               double len, double lenPerU, const ColumnMarch& r,
                                               ColumnState& st, Rgb8& c, double& tHit) const;

    // A coherent ray that reached the level-0 distance: the multiresolution march from there.
    [[gnu::noinline]] void continueFar(const ColumnContext& cc, const glm::dvec3& d, double lenPerU,
                                       const ColumnMarch& r, ColumnState& st, Rgb8& c,
                                       double& tHit) const;

    ColumnContext columnContext(const MapView& mv, const Camera& camera, double d0, int x) const;

    // One column of the multiresolution caster, bottom to top: kLanes rays at a time (eight with
    // AVX-512, with four where eight do not go; four with AVX2; 0: none) where they are
    // coherent with the ray below them, else one by one. With kSuper, the supersample rays of
    // each pixel are stacked in the column (as renderColumn casts them) and averaged, the depth
    // the nearest.
    template <bool kSuper, int kLanes>
    void renderLinearColumn(const MapView& mv, const Camera& camera, double d0, int x,
                            RenderedFrame& frame, UnitCounters& counters) const;

    void renderColumnUnit(const MapView& mv, const Camera& camera, double d0, int x,
                          RenderedFrame& frame, UnitCounters& counters) const;

    // One column of the single-level caster, bottom to top, the supersample rays of a pixel
    // stacked inside it and averaged (depth: the nearest).
    void renderColumn(const MapView& mv, const Camera& camera, double d0, int x,
                      RenderedFrame& frame, UnitCounters& counters) const;

#if VIG_CASTER_PACKETS
    // The four-column packets (caster_packets.cpp): four adjacent columns cast together, row
    // by row, with AVX2, bit for bit the image one column at a time gives.
    // Four adjacent columns with AVX2 (the image's last columns one at a time).
    void renderPacketUnit(const MapView& mv, const Camera& camera, double d0, int unit,
                          RenderedFrame& frame, UnitCounters& counters) const;
    VIG_CASTER_AVX2 void renderPacket(const MapView& mv, const Camera& camera, double d0, int x0,
                                      RenderedFrame& frame, UnitCounters& counters) const;
    // Casts row y of the four columns where it can; `done[l]` tells which lanes it cast. The
    // state of the other lanes is untouched.
    template <bool kMajorX>
    [[gnu::always_inline]] VIG_CASTER_AVX2 void packetRow(const ColumnContext* cc, ColumnState* st,
                                                          V4 dx, V4 dy, V4 dz, V4 len, int sgnI,
                                                          Rgb8* c, double* tHit, bool* done) const;
#endif

    const TerrainMap& map_;
    RenderOptions options_;
    CasterKernel kernel_ = CasterKernel::Scalar;  // the kernel that runs (chooseKernel)
    UnitRenderer renderUnit_ = nullptr;
    int columnsPerUnit_ = 1;
    std::shared_ptr<const TerrainPyramid> pyramid_;
    std::shared_ptr<const SlopeBlocks> slopes_;
    int topLevel_ = 0;
    std::optional<FarMarch> far_;      // the multiresolution march past the level-0 distance
    RowsCaster rows_{};                // what the row batches read of this caster
    RowKernel rowsNarrow_, rowsWide_;  // four and eight lanes (chooseKernel)
};

}  // namespace ig::fast
