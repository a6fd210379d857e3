// Exact ray intersection with the bilinear terrain surface (the reference surface model).
#pragma once

#include "ig/terrain.hpp"

#include <glm/vec3.hpp>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <utility>

namespace ig {

// Intersects [t0, t1] with the parameters where lo <= o + t * d <= hi (one slab of a ray/box
// test); false when nothing is left.
inline bool clipSlab(double o, double d, double lo, double hi, double& t0, double& t1) {
    if (d == 0.0) return o >= lo && o <= hi;
    double ta = (lo - o) / d, tb = (hi - o) / d;
    if (ta > tb) std::swap(ta, tb);
    t0 = std::max(t0, ta);
    t1 = std::min(t1, tb);
    return t0 <= t1;
}

// A ray prepared for terrain traversal: world origin and unit direction, plus the same ray in
// grid units (x / spacingX, y / spacingY, z in metres), which share the parameter t.
struct TerrainRay {
    glm::dvec3 origin;
    glm::dvec3 dir;   // unit length
    double gox, goy;  // origin in grid units
    double gdx, gdy;  // direction in grid units per metre of t

    TerrainRay(const TerrainMap& map, const glm::dvec3& o, const glm::dvec3& d);
    glm::dvec3 at(double t) const { return origin + t * dir; }
};

// First s in [0, len] where the ray z = za + dz * s meets the bilinear patch with corner heights
// h00, h10, h01, h11 (metres) at local cell coordinates (ua + du * s, va + dv * s); negative
// when there is none. A ray under the patch at s = 0 hits at 0.
[[gnu::always_inline]] inline double solveBilinear(double h00, double h10, double h01, double h11,
                                                   double ua, double va, double du, double dv,
                                                   double za, double dz, double len) {
    const double a = h10 - h00, b = h01 - h00, c = h00 - h10 - h01 + h11;
    const double C = za - (h00 + a * ua + b * va + c * ua * va);
    if (C <= 0.0) return 0.0;
    // Height of the ray above the surface: A s^2 + B s + C, C > 0. Its first positive root,
    // each branch written so that it does not cancel: with B < 0 it is C / q, q = (sqrt(disc)
    // - B) / 2 > 0 (the smaller root when A > 0, the only one when A <= 0); with B >= 0 the
    // only positive root is q' / A, q' = -(B + sqrt(disc)) / 2 < 0, and only when A < 0.
    const double B = dz - (a * du + b * dv + c * (ua * dv + va * du));
    const double A = -c * du * dv;
    const double disc = B * B - 4.0 * A * C;
    double root = -1.0;
    if (disc >= 0.0) {
        const double sq = std::sqrt(disc);
        if (B < 0.0) {
            root = C / (0.5 * (sq - B));
        } else if (A < 0.0) {
            root = -0.5 * (B + sq) / A;
        }
    }
    if (root >= 0.0 && root <= len) return root;
    return C + B * len + A * len * len <= 0.0 ? len : -1.0;
}

// First t in [ta, tb] (a piece of the ray inside cell (cx, cy)) where the ray meets the cell's
// bilinear surface, or a negative value. A ray under the surface at ta hits at ta.
inline double solveCell(const TerrainMap& map, const TerrainRay& ray, int cx, int cy, double ta,
                        double tb) {
    const double scale = map.heightScale(), offset = map.heightOffset();
    const double s = solveBilinear(
        map.raw(cx, cy) * scale + offset, map.raw(cx + 1, cy) * scale + offset,
        map.raw(cx, cy + 1) * scale + offset, map.raw(cx + 1, cy + 1) * scale + offset,
        ray.gox + ta * ray.gdx - cx, ray.goy + ta * ray.gdy - cy, ray.gdx, ray.gdy,
        ray.origin.z + ta * ray.dir.z, ray.dir.z, tb - ta);
    return s < 0.0 ? -1.0 : ta + s;
}

// The parameter interval in which the ray is inside the map's bounding box (footprint x
// [minHeight, maxHeight]). Returns false when it never is (or only behind the origin).
bool clipToMapBox(const TerrainMap& map, const TerrainRay& ray, double& t0, double& t1);

// Signed height of the ray above the bilinear surface at t (negative: inside the terrain).
// Outside the footprint returns +inf.
double heightAboveSurface(const TerrainMap& map, const TerrainRay& ray, double t);

// First t in [ta, tb] at which the ray meets the terrain solid (the region under the bilinear
// surface, inside the footprint), visiting every cell the segment crosses and solving the
// quadratic in each. Returns a negative value when there is none. A ray already inside the
// solid at ta hits at ta.
double exactHitInRange(const TerrainMap& map, const TerrainRay& ray, double ta, double tb,
                       std::uint64_t* cellsVisited = nullptr);

// First t in [ta, tb] at which a ray inside the terrain solid comes out of it (on or above the
// surface, inside the footprint); ta when it is not inside at ta; negative when it stays inside
// until it leaves the map.
double exitSolidInRange(const TerrainMap& map, const TerrainRay& ray, double ta, double tb);

// First t in [ta, tb] at which the ray enters the terrain solid from outside, the part of it
// that is inside at ta left out (what a near clipping plane at ta leaves of the terrain: a
// surface is drawn only where the ray crosses into it beyond the plane). Negative when none.
double entryBeyond(const TerrainMap& map, const TerrainRay& ray, double ta, double tb);

}  // namespace ig
