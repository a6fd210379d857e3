// Local bounds on the terrain's slope for the fast caster's coherence test. A ray may start
// where the ray below it stopped when its climb over that ray outruns the most the terrain can
// rise across the gap between their ground tracks. With the map's one global slope bound, a
// single cliff or tower anywhere on the map would make every column restart everywhere; these
// bounds only look at the terrain the column's rays pass over.
#pragma once

#include "ig/terrain.hpp"

#include <glm/vec2.hpp>

#include <algorithm>
#include <vector>

namespace ig {

// The map cut into blocks of kBlock x kBlock cells, each with a bound on the gradient magnitude
// (m/m) of the bilinear surface over its cells (stored as float, rounded up).
class SlopeBlocks {
  public:
    static constexpr int kBlock = 8;
    // Computed from the whole map.
    explicit SlopeBlocks(const TerrainMap& map);
    // Read from elsewhere (a terrain database's slope section): blocksX(map) x blocksY(map)
    // bounds, rows south first, which must outlive this.
    SlopeBlocks(const TerrainMap& map, const float* bounds);
    SlopeBlocks(const SlopeBlocks&) = delete;
    SlopeBlocks& operator=(const SlopeBlocks&) = delete;

    // Blocks along each axis of a width x height sample map.
    static int blocksAlong(int samples) { return (std::max(samples - 1, 1) + kBlock - 1) / kBlock; }
    // A block's bound from the largest raw sample differences of its cells along x and y (over
    // a cell the bilinear surface's x-slope lies between its two edge slopes, likewise y), with
    // sx = |height scale| / spacing x, sy likewise: rounded up to a float.
    static float boundOf(int dx, int dy, double sx, double sy);

    int blocksX() const { return blocksX_; }
    const float* data() const { return bound_; }  // blocksX() x blocksY(), rows south first
    int blocksY() const { return blocksY_; }
    double blockMetresX() const { return blockMetresX_; }
    double blockMetresY() const { return blockMetresY_; }
    // The bound over the block holding world (x, y), metres; points off the map take the
    // nearest block's.
    double at(double x, double y) const;
    // The largest bound over the blocks that the box [x0, x1] x [y0, y1] (metres) touches,
    // clamped to the map.
    double maxOver(double x0, double y0, double x1, double y1) const;

  private:
    int blocksX_ = 1, blocksY_ = 1;
    double blockMetresX_ = 1.0, blockMetresY_ = 1.0;
    double invBlockX_ = 1.0, invBlockY_ = 1.0;
    std::vector<float> owned_;      // the bounds when computed here
    const float* bound_ = nullptr;  // owned_'s, or the supplied ones
};

// One image column's slope bound as a function of horizontal distance from the eye: the largest
// block bound over the wedge between the column's two extreme ray azimuths, out to that
// distance. Filled as the column's rays need it (no allocation): the wedge is cut square to its
// bisector into slices (a point within distance D of the eye lies at most D along the bisector)
// and across into pieces at most a block long and wide, and every block that a piece's bounding
// box touches counts, so no block the wedge crosses is missed. When the wedge is not narrower
// than a right angle (near the nadir, tracks fanning all round), the map's global bound.
class WedgeSlope {
  public:
    static constexpr int kRings = 256;

    // eye: horizontal position; a, b: horizontal directions of the column's first and last ray;
    // reach: a distance beyond which no part of the map lies.
    void reset(const SlopeBlocks* blocks, glm::dvec2 eye, glm::dvec2 a, glm::dvec2 b, double reach,
               double globalBound);

    // A bound on |gradient| over the wedge within `distance` of the eye.
    double upTo(double distance) {
        if (!blocks_) return global_;
        const double r = distance * invStep_;
        // Out of range or NaN: the whole wedge.
        const int i = r < 0.0 ? 0 : (r < kRings - 1 ? static_cast<int>(r) : kRings - 1);
        if (i >= filled_) fill(i);
        return profile_[i];
    }

  private:
    void fill(int last);

    const SlopeBlocks* blocks_ = nullptr;
    glm::dvec2 eye_{0.0};
    glm::dvec2 axis_{0.0},
        side_{0.0};  // the wedge's bisector, and its half-width per unit along it
    double step_ = 1.0, invStep_ = 1.0, piece_ = 1.0;
    double global_ = 0.0;
    int filled_ = 0;
    double profile_[kRings];
};

}  // namespace ig
