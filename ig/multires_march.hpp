// Kernels over the terrain pyramid: hierarchical empty-space skipping down the max-height
// pyramid (first hits of rays with no coherent start), and the multiresolution march that steps
// over coarser display levels where a voxel's footprint falls below a pixel, blending adjacent
// levels by distance. See docs/design/multires.md.
#pragma once

#include "ig/grid_march.hpp"
#include "ig/pyramid.hpp"
#include "ig/surface_hit.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>

namespace ig {

// Skips the part of [tStart, tEnd] where the ray passes over max-pyramid nodes it cannot reach,
// descending from the coarsest node level to level 1 (2x2 cells). Returns the parameter from
// which a cell-level march must go on (no display level's surface is met before it), or a
// negative value when the ray meets nothing up to tEnd. Adds the nodes visited to `steps`.
inline double skipEmptySpace(const TerrainPyramid& pyr, const TerrainRay& ray, double tStart,
                             double tEnd, std::uint64_t& steps) {
    const int top = pyr.nodeLevelCount() - 1;
    if (top < 1 || !(tStart <= tEnd)) return tStart;
    constexpr double kInf = std::numeric_limits<double>::infinity();
    const TerrainMap& map = pyr.map();
    const double scale = map.heightScale(), offset = map.heightOffset();
    const double invX = ray.gdx != 0.0 ? 1.0 / ray.gdx : kInf;
    const double invY = ray.gdy != 0.0 ? 1.0 / ray.gdy : kInf;
    // Start at the node level whose node size matches the segment's extent in cells.
    const double span = std::max(std::abs(ray.gdx), std::abs(ray.gdy)) * (tEnd - tStart);
    int j = top;
    if (span < 2.0) {
        j = 1;
    } else if (span < 1e15) {
        j = std::min(top, std::ilogb(span) + 1);
    }
    double t = tStart;
    std::uint64_t count = 0;
    for (;;) {
        ++count;
        const double size = static_cast<double>(1 << j), invSize = 1.0 / size;
        const double gx = (ray.gox + t * ray.gdx) * invSize, gy = (ray.goy + t * ray.gdy) * invSize;
        // The node the ray goes into from t.
        const int nx =
            std::clamp(static_cast<int>(ray.gdx >= 0.0 ? std::floor(gx) : std::ceil(gx) - 1.0), 0,
                       pyr.nodesX(j) - 1);
        const int ny =
            std::clamp(static_cast<int>(ray.gdy >= 0.0 ? std::floor(gy) : std::ceil(gy) - 1.0), 0,
                       pyr.nodesY(j) - 1);
        const double tx =
            ray.gdx != 0.0 ? ((ray.gdx > 0 ? nx + 1 : nx) * size - ray.gox) * invX : kInf;
        const double ty =
            ray.gdy != 0.0 ? ((ray.gdy > 0 ? ny + 1 : ny) * size - ray.goy) * invY : kInf;
        const double tExit = std::min({tx, ty, tEnd});
        const double zLow = ray.origin.z + (ray.dir.z >= 0.0 ? t : tExit) * ray.dir.z;
        if (tExit > t && zLow > pyr.nodeMaxRaw(j, nx, ny) * scale + offset) {
            if (tExit >= tEnd) {
                steps += count;
                return -1.0;
            }
            t = tExit;
            if (j < top) ++j;
        } else if (j == 1) {
            steps += count;
            return t;
        } else {
            --j;
        }
    }
}

// The exact first hit on level 0 found by first descending the max-height pyramid: the
// hierarchical first hit of rays with no previous hit to start from. Same result as
// marchRay(map, ray, tStart, tEnd, steps).
inline double hierarchicalFirstHit(const TerrainPyramid& pyr, const TerrainRay& ray, double tStart,
                                   double tEnd, std::uint64_t& steps) {
    const double t = skipEmptySpace(pyr, ray, tStart, tEnd, steps);
    return t < 0.0 ? -1.0 : marchRay(pyr.map(), ray, t, tEnd, steps);
}

// A hit of the multiresolution march: the ray parameter, the display level whose cells it was
// found in, and the weight of the next coarser level blended in there.
struct LevelHit {
    double t = -1.0;
    int level = 0;
    double weight = 0.0;
};

namespace detail {

// Height (raw units) of level P's bilinear surface at the finer level's sample (i, j).
inline double parentRawAt(const PyramidLevel& p, int i, int j) {
    const int pi = std::min(i >> 1, p.width - 1), pj = std::min(j >> 1, p.height - 1);
    const int pi1 = std::min(pi + 1, p.width - 1), pj1 = std::min(pj + 1, p.height - 1);
    const double a = p.raw(pi, pj);
    if (!(i & 1) && !(j & 1)) return a;
    if (!(j & 1)) return 0.5 * (a + p.raw(pi1, pj));
    if (!(i & 1)) return 0.5 * (a + p.raw(pi, pj1));
    return 0.25 * (a + p.raw(pi1, pj) + p.raw(pi, pj1) + p.raw(pi1, pj1));
}

}  // namespace detail

// Bilinear colour of one display level at its grid coordinates (gx, gy), clamped to the grid.
inline void levelColor(const PyramidLevel& l, double gx, double gy, float rgb[3]) {
    gx = std::clamp(gx, 0.0, l.width - 1.0);
    gy = std::clamp(gy, 0.0, l.height - 1.0);
    const int ix = std::min(static_cast<int>(gx), l.width - 2);
    const int iy = std::min(static_cast<int>(gy), l.height - 2);
    const float fx = static_cast<float>(gx - ix), fy = static_cast<float>(gy - iy);
    const Rgb8* row0 = l.colors + l.index(ix, iy);
    const Rgb8* row1 = row0 + l.width;
    const float w00 = (1 - fx) * (1 - fy), w10 = fx * (1 - fy), w01 = (1 - fx) * fy, w11 = fx * fy;
    rgb[0] = w00 * row0[0].r + w10 * row0[1].r + w01 * row1[0].r + w11 * row1[1].r;
    rgb[1] = w00 * row0[0].g + w10 * row0[1].g + w01 * row1[0].g + w11 * row1[1].g;
    rgb[2] = w00 * row0[0].b + w10 * row0[1].b + w01 * row1[0].b + w11 * row1[1].b;
}

// Colour of a multiresolution hit at world (x, y): its level's colour blended with the next.
inline void levelHitColor(const TerrainPyramid& pyr, const LevelHit& hit, double x, double y,
                          float rgb[3]) {
    const TerrainMap& map = pyr.map();
    const double inv = 1.0 / (1 << hit.level);
    const double gx = x / map.spacingX() * inv, gy = y / map.spacingY() * inv;
    levelColor(pyr.level(hit.level), gx, gy, rgb);
    if (hit.weight > 0.0) {
        float c[3];
        levelColor(pyr.level(hit.level + 1), 0.5 * gx, 0.5 * gy, c);
        const float w = static_cast<float>(hit.weight);
        for (int i = 0; i < 3; ++i)
            rgb[i] += (c[i] - rgb[i]) * w;
    }
}

// The multiresolution march from tStart (at horizontal distance >= d0) to tEnd. Band k covers
// horizontal distances [d0 * 2^k, d0 * 2^(k+1)): the ray steps cell by cell over level k, whose
// surface there is blended toward level k + 1 with weight D / (d0 * 2^k) - 1 (constant over a
// cell, taken where the ray enters it), so the surface changes continuously with distance and
// no level boundary sweeps over the terrain as the camera moves. Band `topLevel` extends to
// infinity unblended. A level's cells start on grid lines of every finer level, so a band
// starts on the grid line where the previous ended. `horiz` is the ray's horizontal speed
// |dir.xy| (> 0).
inline LevelHit marchLevels(const TerrainPyramid& pyr, const TerrainRay& ray, double horiz,
                            double d0, int topLevel, double tStart, double tEnd,
                            std::uint64_t& steps) {
    constexpr double kInf = std::numeric_limits<double>::infinity();
    LevelHit none;
    if (!(tStart < tEnd) || !(horiz > 0.0)) return none;
    const TerrainMap& map = pyr.map();
    const double scale = map.heightScale(), offset = map.heightOffset();
    const double oz = ray.origin.z, dz = ray.dir.z;
    double t = tStart;
    int k = 0;
    double dk = d0;  // where band k starts
    while (k < topLevel && t * horiz >= 2.0 * dk) {
        ++k;
        dk *= 2.0;
    }
    std::uint64_t count = 0;
    for (;;) {
        const bool blend = k < topLevel;
        const double tBand = blend ? std::min(tEnd, 2.0 * dk / horiz) : tEnd;
        const PyramidLevel& l = pyr.level(k);
        const PyramidLevel* p = blend ? &pyr.level(k + 1) : nullptr;
        const double inv = 1.0 / (1 << k);
        const double gox = ray.gox * inv, goy = ray.goy * inv;
        const double gdx = ray.gdx * inv, gdy = ray.gdy * inv;
        const double invX = gdx != 0.0 ? 1.0 / gdx : kInf, invY = gdy != 0.0 ? 1.0 / gdy : kInf;
        const int lastX = l.width - 2, lastY = l.height - 2;
        const int sx = gdx > 0 ? 1 : -1, sy = gdy > 0 ? 1 : -1;
        const double gx = gox + t * gdx, gy = goy + t * gdy;
        int ix =
            std::clamp(static_cast<int>(gdx >= 0 ? std::floor(gx) : std::ceil(gx) - 1.0), 0, lastX);
        int iy =
            std::clamp(static_cast<int>(gdy >= 0 ? std::floor(gy) : std::ceil(gy) - 1.0), 0, lastY);
        while (t < tBand) {
            ++count;
            const double nextX = gdx != 0.0 ? ((gdx > 0 ? ix + 1 : ix) - gox) * invX : kInf;
            const double nextY = gdy != 0.0 ? ((gdy > 0 ? iy + 1 : iy) - goy) * invY : kInf;
            const double tExit = std::min({nextX, nextY, tBand});
            const double zLow = oz + (dz >= 0.0 ? t : tExit) * dz;
            int bound = l.cellMaxRaw(ix, iy);
            if (p) {
                bound = std::max<int>(bound, p->cellMaxRaw(std::min(ix >> 1, p->width - 2),
                                                           std::min(iy >> 1, p->height - 2)));
            }
            if (zLow <= bound * scale + offset) {
                const double w = p ? std::clamp(t * horiz / dk - 1.0, 0.0, 1.0) : 0.0;
                double h[4];
                for (int c = 0; c < 4; ++c) {
                    const int i = ix + (c & 1), j = iy + (c >> 1);
                    const double hk = l.raw(i, j);
                    h[c] =
                        (p ? hk + w * (detail::parentRawAt(*p, i, j) - hk) : hk) * scale + offset;
                }
                const double s =
                    solveBilinear(h[0], h[1], h[2], h[3], gox + t * gdx - ix, goy + t * gdy - iy,
                                  gdx, gdy, oz + t * dz, dz, std::max(tExit - t, 0.0));
                if (s >= 0.0) {
                    steps += count;
                    return LevelHit{t + s, k, w};
                }
            }
            if (tExit >= tBand) break;
            t = tExit;
            if (nextX <= nextY) {
                ix += sx;
                if (ix < 0 || ix > lastX) {
                    steps += count;
                    return none;
                }
            } else {
                iy += sy;
                if (iy < 0 || iy > lastY) {
                    steps += count;
                    return none;
                }
            }
        }
        t = std::max(t, tBand);
        if (!blend || t >= tEnd) break;
        ++k;
        dk *= 2.0;
    }
    steps += count;
    return none;
}

}  // namespace ig
