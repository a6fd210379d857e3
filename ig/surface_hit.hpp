// Exact ray intersection with the bilinear terrain surface (the reference surface model).
#pragma once

#include "ig/terrain.hpp"

#include <glm/vec3.hpp>

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
