// What the fast caster's parts share about one image column: its rays' common set-up, the
// state carried from ray to ray up the column, the coherence test, and the row-batch kernels'
// entry points. Internal to the fast caster (caster_fast.cpp, caster_packets.cpp,
// far_march.cpp and the row batches, caster_rows_*.cpp).
//
// The row-batch files are compiled for one instruction set each: nothing here is an inline
// function they could instantiate (see docs/design/multires.md, "One object per instruction
// set"), only types and out-of-line functions.
#pragma once

#include "ig/caster.hpp"
#include "ig/level0_march.hpp"
#include "ig/slope_bound.hpp"

#include <glm/vec3.hpp>

#include <cstddef>
#include <cstdint>

// The vector kernels (four-column packets, row batches) exist on x86-64 with GCC or Clang.
#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#define VIG_CASTER_PACKETS 1
#define VIG_CASTER_WIDE 1
#else
#define VIG_CASTER_PACKETS 0
#define VIG_CASTER_WIDE 0
#endif
// The row batches' portable twins (GCC and Clang vector types, lowered lane by lane by the
// compiler for any processor) exist wherever the compiler has them.
#if defined(__GNUC__) || defined(__clang__)
#define VIG_CASTER_ROWS 1
#else
#define VIG_CASTER_ROWS 0
#endif

namespace ig {

class TerrainPyramid;

namespace fast {

class FarMarch;

// What every ray of one image column shares.
struct ColumnContext {
    const MapView* mv;
    glm::dvec3 base, down, eye;  // ray of row y: base + y * down
    EyeGrid eg;
    double d0;
    double invSx, invSy;
    double maxSlope;
    double spacingX, spacingY;
    bool multires;
};

// The ray below, in major-axis form: it and the next ray share the major coordinate at
// equal u (major grid units travelled from the eye), so coherence compares them there.
struct ColumnState {
    bool havePrev = false, prevMajorX = false, prevAbove = false;
    int prevSgn = 0;
    double prevRn = 0.0, prevRz = 0.0, prevU = 0.0;
    std::uint64_t steps = 0, restarts = 0;
    WedgeSlope wedge;  // the terrain's slope bound over the column's wedge, by distance
    // Clearance chain of the restarted rays (see restartInChain): segment j says a ray with
    // minor slope in [rnLo, rnHi] and height slope at most rzHi passed above the cell maxima
    // within one minor cell of its track from the previous segment's end (0 for the first)
    // to `end`.
    struct Segment {
        double rnLo, rnHi, rzHi, end;
    };
    static constexpr int kChain = 16;
    Segment chain[kChain];
    int chainLength = 0;
    bool chainMajorX = false;
    int chainSgn = 0;
};

// Whether this ray (rn minor cells and rz metres per major unit) climbs over the ray below
// fast enough to stay clear of the terrain up to where that ray stopped: per major unit it
// must rise more than the steepest terrain within that distance of the eye, in the column's
// wedge, rises across the gap between them. Tested with the map's global bound first (no
// local bound exceeds it, so a pass there is a pass); the same arithmetic in every path
// (the images are compared bit for bit). Out of line (FastCaster::climbsClear, which the
// caster's own paths inline): the row batches call it.
bool climbsClear(const ColumnContext& cc, ColumnState& st, bool majorX, double rn, double rz);

// N consecutive rays of one column (bottom to top) cast together by the multiresolution
// caster (RowBatches, caster_rows.hpp; four lanes with AVX2, eight with AVX-512): when each
// climbs clear of the ray below them (the column state; the same proof as linearRay's,
// against that one ray), all march from where it stopped, over the same major grid lines
// in step, each lane sampling the surface on its own track; linearRay's march and hit, lane
// by lane. A lane that reaches the level-0 distance goes on alone into the far march
// (FarMarch::linearFar). kDone when cast (colours and hit distances set, the state moved on);
// otherwise the state is untouched and the rays are cast one by one (kFar: they start past
// the level-0 distance).
enum class RowsOutcome { kDone, kFar, kOther };

// What the row batches read of the caster besides the column.
struct RowsCaster {
    const SkyModel* sky;
    const TerrainPyramid* pyramid;
    bool skipNodes;  // RenderOptions::skipNodes
    const FarMarch* far;
};

// One lane width's row batches, each compiled for its instruction set (caster_rows_avx2.cpp,
// caster_rows_avx512.cpp) or for none (caster_rows_portable.cpp, their twins) and picked
// once, when the caster is made.
struct RowKernel {
    // Batches of N rows down from image row y (one ray per pixel) while they go and at most
    // `batches` of them, each batch's pixels written to the column (colour and depth, row
    // stride w). The row the next batch would start at; `last` says why the run ended
    // (kDone: the batch limit or fewer than N rows left).
    using Run = int (*)(const RowsCaster& rc, const ColumnContext& cc, ColumnState& st, int y,
                        int batches, Rgb8* colorOut, float* depthOut, std::size_t w,
                        RowsOutcome& last);
    // Rays through image rows rowY[0 .. N) (bottom to top), their colours and hit distances
    // (negative: sky) into c and tHit.
    using Cast = RowsOutcome (*)(const RowsCaster& rc, const ColumnContext& cc, ColumnState& st,
                                 const double* rowY, Rgb8* c, double* tHit);
    int lanes = 0;  // 0: not in this build
    Run run = nullptr;
    Cast cast = nullptr;
};

}  // namespace fast

// The row batches of each instruction set. Call only where the processor has it
// (base::cpuFeatures); a build without the vector code returns an empty kernel.
namespace rows_avx2 {
fast::RowKernel kernel();
}
namespace rows_avx512 {
fast::RowKernel kernel();
}
// The same template on portable lanes of four and eight doubles, compiled without any
// instruction-set flag: each vector kernel's scalar twin, equal to it to the bit. Never chosen
// by default; runs on any processor (empty where the compiler lacks vector types).
namespace rows_portable {
fast::RowKernel kernel4();
fast::RowKernel kernel8();
}  // namespace rows_portable

}  // namespace ig
