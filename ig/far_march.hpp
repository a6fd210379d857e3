// The multiresolution caster's far march (docs/design/multires.md): a ray past the level-0
// distance goes on over the coarser display levels, adjacent levels blended by distance.
// Internal to the fast caster; compiled with its floating-point flags (ig/CMakeLists.txt).
#pragma once

#include "ig/fast_column.hpp"
#include "ig/pyramid.hpp"
#include "ig/shading.hpp"

#include <algorithm>
#include <cstdint>

namespace ig::fast {

// A level's bilinear surface (raw) at its grid coordinates (major m, minor n), clamped.
template <bool kMajorX>
inline double levelSurface(const PyramidLevel& l, double m, double n) {
    const double gx = std::clamp(kMajorX ? m : n, 0.0, l.width - 1.0);
    const double gy = std::clamp(kMajorX ? n : m, 0.0, l.height - 1.0);
    const int ix = std::min(static_cast<int>(gx), l.width - 2);
    const int iy = std::min(static_cast<int>(gy), l.height - 2);
    const double fx = gx - ix, fy = gy - iy;
    const std::uint16_t* p = l.heights + l.index(ix, iy);
    const double a = p[0] + fx * (static_cast<double>(p[1]) - p[0]);
    const double b = p[l.width] + fx * (static_cast<double>(p[l.width + 1]) - p[l.width]);
    return a + fy * (b - a);
}

class FarMarch {
  public:
    FarMarch(const TerrainMap& map, const TerrainPyramid& pyramid, const SkyModel& sky)
        : map_(map), pyramid_(pyramid), sky_(sky), topLevel_(pyramid.levelCount() - 1) {}

    // Where a ray of the multiresolution caster has passed the level-0 distance above the
    // terrain: on over the coarser levels, each band of distance [d0 2^k, d0 2^(k+1)) sampled
    // where the ray crosses level k's major grid lines, its surface blended toward level k + 1's
    // by distance (weight D / (d0 2^k) - 1), the hit between the last line passed above and the
    // first under, its colour the same blend of the two levels' colours.
    // Sets the colour, the hit distance (negative: sky), where the ray stopped (uStop) and
    // whether it climbed over the map's highest point (above).
    // The ray's direction is (dx, dy, dz).
    void linearFar(const ColumnContext& cc, double dx, double dy, double dz, double len, double inv,
                   bool majorX, int sgn, double rn, double rz, double uStart, double& uStop,
                   bool& above, std::uint64_t& steps, Rgb8& c, double& tHit) const;

  private:
    struct FarHit {
        ColumnMarch::Kind kind = ColumnMarch::kStop;
        double u = 0.0;             // level-0 major units from the eye
        int level = 0;              // the band's level
        double weight = 0.0;        // of level + 1
        double gx = 0.0, gy = 0.0;  // level-0 grid coordinates of the hit
    };

    template <bool kMajorX>
    FarHit marchLinearFar(const ColumnContext& cc, int sgn, double rn, double rz, double hs,
                          double uStart, long budget, std::uint64_t& steps) const;

    // The shared haze and quantization (shading.hpp).
    Rgb8 haze(float rgb[3], double t) const {
        applyHaze(sky_, rgb, t);
        return quantizeColor(rgb);
    }

    const TerrainMap& map_;
    const TerrainPyramid& pyramid_;
    const SkyModel& sky_;
    int topLevel_;
};

}  // namespace ig::fast
