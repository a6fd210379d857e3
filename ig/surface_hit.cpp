#include "ig/surface_hit.hpp"

#include "ig/caster.hpp"

#include <glm/geometric.hpp>

#include <algorithm>
#include <cmath>
#include <limits>

namespace ig {

TerrainRay::TerrainRay(const TerrainMap& map, const glm::dvec3& o, const glm::dvec3& d)
    : origin(o), dir(d * (1.0 / std::sqrt(d.x * d.x + d.y * d.y + d.z * d.z))) {
    gox = o.x / map.spacingX();
    goy = o.y / map.spacingY();
    gdx = dir.x / map.spacingX();
    gdy = dir.y / map.spacingY();
}

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

}  // namespace

bool clipToMapBox(const TerrainMap& map, const TerrainRay& ray, double& t0, double& t1) {
    t0 = 0.0;
    t1 = kInf;
    if (map.width() < 2 || map.height() < 2) return false;
    // The height slab is widened a little so a flat map still has a box with an inside.
    const double eps = 1e-6 * std::max({1.0, std::abs(map.minHeight()), std::abs(map.maxHeight())});
    return clipSlab(ray.gox, ray.gdx, 0.0, map.width() - 1.0, t0, t1) &&
           clipSlab(ray.goy, ray.gdy, 0.0, map.height() - 1.0, t0, t1) &&
           clipSlab(ray.origin.z, ray.dir.z, map.minHeight() - eps, map.maxHeight() + eps, t0, t1);
}

double heightAboveSurface(const TerrainMap& map, const TerrainRay& ray, double t) {
    const double gx = ray.gox + t * ray.gdx, gy = ray.goy + t * ray.gdy;
    const double eps = 1e-9;
    if (gx < -eps || gy < -eps || gx > map.width() - 1 + eps || gy > map.height() - 1 + eps) {
        return kInf;
    }
    const glm::dvec3 p = ray.at(t);
    return p.z - map.surfaceHeight(p.x, p.y);
}

namespace {

// Visits the cells the segment [ta, tb] of the ray crosses inside the map's box, in order:
// visit(ix, iy, tIn, tOut) returns a parameter >= 0 to stop with, or a negative value to go on.
// Returns what stopped it, or -1. `cells` counts the cells visited.
template <typename Visit>
double walkCells(const TerrainMap& map, const TerrainRay& ray, double ta, double tb,
                 std::uint64_t& cells, Visit visit) {
    double c0, c1;
    if (!clipToMapBox(map, ray, c0, c1)) return -1.0;
    ta = std::max(ta, c0);
    tb = std::min(tb, c1);
    if (!(ta <= tb)) return -1.0;

    const int w = map.width(), h = map.height();
    // Cell containing the start, nudged along the ray so that a start on a grid line picks the
    // cell the ray goes into.
    const double tNudge = ta + 1e-9 * std::max(1.0, tb - ta);
    int ix = std::clamp(static_cast<int>(std::floor(ray.gox + tNudge * ray.gdx)), 0, w - 2);
    int iy = std::clamp(static_cast<int>(std::floor(ray.goy + tNudge * ray.gdy)), 0, h - 2);
    const int stepX = ray.gdx > 0 ? 1 : -1, stepY = ray.gdy > 0 ? 1 : -1;
    const double invX = ray.gdx != 0.0 ? 1.0 / ray.gdx : kInf;
    const double invY = ray.gdy != 0.0 ? 1.0 / ray.gdy : kInf;

    double t = ta;
    while (t <= tb) {
        ++cells;
        // Parameter where the ray leaves this cell.
        const double nextX = ray.gdx != 0.0 ? ((ray.gdx > 0 ? ix + 1 : ix) - ray.gox) * invX : kInf;
        const double nextY = ray.gdy != 0.0 ? ((ray.gdy > 0 ? iy + 1 : iy) - ray.goy) * invY : kInf;
        const double tExit = std::min({nextX, nextY, tb});
        const double stop = visit(ix, iy, t, tExit);
        if (stop >= 0.0) return stop;
        if (tExit >= tb) break;
        t = tExit;
        if (nextX <= nextY) {
            ix += stepX;
            if (ix < 0 || ix > w - 2) break;
        } else {
            iy += stepY;
            if (iy < 0 || iy > h - 2) break;
        }
    }
    return -1.0;
}

}  // namespace

double exactHitInRange(const TerrainMap& map, const TerrainRay& ray, double ta, double tb,
                       std::uint64_t* cellsVisited) {
    std::uint64_t cells = 0;
    const double hit =
        walkCells(map, ray, ta, tb, cells, [&](int ix, int iy, double t, double tExit) {
            const double za = ray.origin.z + t * ray.dir.z, zb = ray.origin.z + tExit * ray.dir.z;
            if (std::min(za, zb) <= map.cellMaxRaw(ix, iy) * map.heightScale() + map.heightOffset())
                return solveCell(map, ray, ix, iy, t, tExit);
            return -1.0;
        });
    if (cellsVisited) *cellsVisited += cells;
    return hit;
}

double exitSolidInRange(const TerrainMap& map, const TerrainRay& ray, double ta, double tb) {
    std::uint64_t cells = 0;
    const double scale = map.heightScale(), offset = map.heightOffset();
    return walkCells(map, ray, ta, tb, cells, [&](int ix, int iy, double t, double tExit) {
        // The same solve with every height negated: the first point where the ray is on or
        // above the surface (0 when it already is at t).
        const double s = solveBilinear(
            -(map.raw(ix, iy) * scale + offset), -(map.raw(ix + 1, iy) * scale + offset),
            -(map.raw(ix, iy + 1) * scale + offset), -(map.raw(ix + 1, iy + 1) * scale + offset),
            ray.gox + t * ray.gdx - ix, ray.goy + t * ray.gdy - iy, ray.gdx, ray.gdy,
            -(ray.origin.z + t * ray.dir.z), -ray.dir.z, tExit - t);
        return s < 0.0 ? -1.0 : t + s;
    });
}

double entryBeyond(const TerrainMap& map, const TerrainRay& ray, double ta, double tb) {
    if (!(heightAboveSurface(map, ray, ta) <= 0.0)) return exactHitInRange(map, ray, ta, tb);
    // Inside the solid at ta: what it is inside of is not drawn; the ray goes on from where it
    // comes out (never, when it leaves the map under the surface: nothing lies beyond).
    const double out = exitSolidInRange(map, ray, ta, tb);
    if (out < 0.0) return -1.0;
    // On the surface at `out`, rising out of it: a step of a micrometre per kilometre takes it
    // off the surface so the next solve looks for the next entry, not this point.
    const double from = out + 1e-9 * std::max(1.0, out);
    if (from > tb) return -1.0;
    return exactHitInRange(map, ray, from, tb);
}

RayHit intersectTerrain(const TerrainMap& map, const glm::dvec3& origin, const glm::dvec3& dir) {
    const TerrainRay ray(map, origin, dir);
    RayHit hit;
    const double t = exactHitInRange(map, ray, 0.0, kInf);
    if (t >= 0.0) {
        hit.hit = true;
        hit.distance = t;
        hit.point = ray.at(t);
    }
    return hit;
}

}  // namespace ig
