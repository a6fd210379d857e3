// Exact ray intersection with the bilinear terrain surface (the reference surface model).
#pragma once

#include "ig/terrain.hpp"

#include <glm/vec3.hpp>

#include <cmath>
#include <cstdint>

namespace ig {

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

// First t in [ta, tb] (a piece of the ray inside cell (cx, cy)) where the ray meets the cell's
// bilinear surface, or a negative value. A ray under the surface at ta hits at ta.
inline double solveCell(const TerrainMap& map, const TerrainRay& ray, int cx, int cy, double ta,
                        double tb) {
    const double scale = map.heightScale(), offset = map.heightOffset();
    const double h00 = map.raw(cx, cy) * scale + offset, h10 = map.raw(cx + 1, cy) * scale + offset;
    const double h01 = map.raw(cx, cy + 1) * scale + offset;
    const double h11 = map.raw(cx + 1, cy + 1) * scale + offset;
    // In local parameter s = t - ta: f(s) = z(s) - h(u(s), v(s)) = C + B s + A s^2.
    const double ua = ray.gox + ta * ray.gdx - cx, va = ray.goy + ta * ray.gdy - cy;
    const double a = h10 - h00, b = h01 - h00, c = h00 - h10 - h01 + h11;
    const double du = ray.gdx, dv = ray.gdy;
    const double C = ray.origin.z + ta * ray.dir.z - (h00 + a * ua + b * va + c * ua * va);
    if (C <= 0.0) return ta;
    const double B = ray.dir.z - (a * du + b * dv + c * (ua * dv + va * du));
    const double A = -c * du * dv;
    const double len = tb - ta;
    double root = len + 1.0;
    if (std::abs(A) * len <= 1e-12 * (std::abs(B) + 1e-300)) {
        if (B < 0.0) root = -C / B;
    } else {
        const double disc = B * B - 4.0 * A * C;
        if (disc >= 0.0) {
            const double sq = std::sqrt(disc);
            const double q = -0.5 * (B + (B >= 0 ? sq : -sq));
            const double r1 = q / A;
            const double r2 = q != 0.0 ? C / q : root;
            if (r1 >= 0.0 && r1 < root) root = r1;
            if (r2 >= 0.0 && r2 < root) root = r2;
        }
    }
    if (root <= len) return ta + root;
    // A root lost to rounding at the far end.
    return C + B * len + A * len * len <= 0.0 ? tb : -1.0;
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

}  // namespace ig
