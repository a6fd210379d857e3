// The objects' exact ray cast: a two-level walk (terrain cells, then the object cells inside the
// ones whose stick range the ray meets) and a box test per voxel of the runs it meets.
#include "ig/object_trace.hpp"

#include "ig/shading.hpp"
#include "ig/surface_hit.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace ig {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
// Height added above and below an object's box when the ray is clipped to it: the box's range
// is float, its voxels' heights double.
constexpr double kBoxPad = 1e-3;

// The walks' step to the next cell, after one left at tb = min(tx, ty, t1) (tx, ty: where the
// ray crosses its far x and y lines): returns the axis crossed (0 x, 1 y), and sets the next
// cell's entry ta and side `axis`. It is entered across the line crossed, where this one is
// left. Unless this cell was left before it was entered (a first cell placed by position, beside
// the one a ray within rounding of a vertical edge enters): then the entry and its side carry on.
// At a tie (a ray through a corner) the cell beyond is entered across y: the later of its two
// lines, at one value, as every walk here takes it.
int stepToNextCell(double tx, double ty, double tb, double& ta, int& axis) {
    const int stepped = tx <= ty ? 0 : 1;
    if (tb > ta) {
        axis = stepped;
        ta = tb;
    } else if (tb == ta && axis >= 0) {
        axis = std::max(axis, stepped);
    }
    return stepped;
}

// Visits the cells [x0, x1] x [y0, y1] of a grid that the ray meets over [t0, t1], in order:
// visit(cx, cy, ta, tb, axis) where axis is the axis crossed to enter (0 x, 1 y; `axis` for the
// first cell). Cell cx lies between lines lineX(cx) and lineX(cx + 1) (likewise y); `baseX`,
// `sizeX` only place the first cell (by position) before the lines confirm it. Stops when visit
// returns false.
template <typename LineX, typename LineY, typename Visit>
void walkGrid(double ox, double oy, double dx, double dy, double baseX, double baseY, double sizeX,
              double sizeY, LineX lineX, LineY lineY, std::int64_t x0, std::int64_t y0,
              std::int64_t x1, std::int64_t y1, double t0, double t1, int axis, Visit visit) {
    const double px = ox + t0 * dx - baseX, py = oy + t0 * dy - baseY;
    std::int64_t cx = std::clamp(static_cast<std::int64_t>(std::floor(px / sizeX)) + x0, x0, x1);
    std::int64_t cy = std::clamp(static_cast<std::int64_t>(std::floor(py / sizeY)) + y0, y0, y1);
    const int stepX = dx > 0.0 ? 1 : -1, stepY = dy > 0.0 ? 1 : -1;
    const double invX = dx != 0.0 ? 1.0 / dx : kInf, invY = dy != 0.0 ? 1.0 / dy : kInf;
    // Where the ray crosses the line it enters cell c by, and the one it leaves it by.
    const auto nearX = [&](std::int64_t c) { return (lineX(dx > 0.0 ? c : c + 1) - ox) * invX; };
    const auto nearY = [&](std::int64_t c) { return (lineY(dy > 0.0 ? c : c + 1) - oy) * invY; };
    const auto farX = [&](std::int64_t c) { return (lineX(dx > 0.0 ? c + 1 : c) - ox) * invX; };
    const auto farY = [&](std::int64_t c) { return (lineY(dy > 0.0 ? c + 1 : c) - oy) * invY; };
    // The position at t0 rounds: a ray within rounding of a line may not have crossed it yet by
    // the lines' own reckoning, which every walk steps by. Then its first cell is the one before.
    if (dx != 0.0) {
        while (cx != (dx > 0.0 ? x0 : x1) && nearX(cx) > t0)
            cx -= stepX;
    }
    if (dy != 0.0) {
        while (cy != (dy > 0.0 ? y0 : y1) && nearY(cy) > t0)
            cy -= stepY;
    }
    double ta = t0;
    double tx = dx != 0.0 ? farX(cx) : kInf, ty = dy != 0.0 ? farY(cy) : kInf;
    for (;;) {
        const double tb = std::min({tx, ty, t1});
        if (tb >= ta && !visit(cx, cy, ta, tb, axis)) return;
        if (tb >= t1) return;
        if (stepToNextCell(tx, ty, tb, ta, axis) == 0) {
            cx += stepX;
            if (cx < x0 || cx > x1) return;
            tx = farX(cx);
        } else {
            cy += stepY;
            if (cy < y0 || cy > y1) return;
            ty = farY(cy);
        }
    }
}

}  // namespace

float faceShade(VoxelFace face) {
    switch (face) {
        case VoxelFace::Top:
            return kFaceShadeTop;
        case VoxelFace::Bottom:
            return kFaceShadeBottom;
        case VoxelFace::X:
            return kFaceShadeX;
        case VoxelFace::Y:
            return kFaceShadeY;
    }
    return 1.0f;
}

// The voxels of one cell entry that the ray meets over [ta, tb] (inside the cell's column).
void collectVoxelHits(const StickTable& table, const ObjectCell& cell, const glm::dvec3& o,
                      const glm::dvec3& d, double ta, double tb, int axis,
                      std::vector<VoxelHit>& hits) {
    const double zA = o.z + ta * d.z, zB = o.z + tb * d.z;
    const double zLo = std::min(zA, zB), zHi = std::max(zA, zB);
    const double h = table.voxelHeight(cell.stick);
    const int runs = table.runCount(cell.stick);
    const VoxelFace side = axis == 1 ? VoxelFace::Y : VoxelFace::X;
    StickRun run = table.firstRun(cell.stick);
    for (int r = 0; r < runs; ++r, run = r < runs ? StickTable::nextRun(run) : run) {
        const double runLo = cell.baseZ + run.first * h, runHi = runLo + run.count * h;
        if (zHi < runLo) break;  // this run and every one above it
        if (zLo > runHi) continue;
        const double last = run.count - 1;
        const int k0 = static_cast<int>(std::clamp(std::floor((zLo - runLo) / h), 0.0, last));
        const int k1 = static_cast<int>(std::clamp(std::floor((zHi - runLo) / h), 0.0, last));
        for (int k = k0; k <= k1; ++k) {
            const double zb = runLo + k * h, zt = zb + h;
            double enter = ta, exit = tb;
            if (!clipSlab(o.z, d.z, zb, zt, enter, exit) || !(enter < exit)) continue;
            const Rgba8 c = run.voxel(k);
            if (c.a == 0) continue;
            VoxelFace face = side;
            if (enter > ta)
                face = d.z < 0.0 ? VoxelFace::Top : VoxelFace::Bottom;
            else if (axis < 0)
                face = d.z < 0.0 ? VoxelFace::Top : VoxelFace::Bottom;
            hits.push_back(VoxelHit{enter, c, face, cell.id});
        }
    }
}

bool blendVoxelHit(const VoxelHit& hit, const SkyModel& sky, ObjectShading& out) {
    const float a = hit.color.a / 255.0f;
    const float shade = faceShade(hit.face);
    float c[3] = {hit.color.r * shade, hit.color.g * shade, hit.color.b * shade};
    applyHaze(sky, c, hit.enter);
    const float w = out.transmittance * a;
    for (int i = 0; i < 3; ++i)
        out.rgb[i] += w * c[i];
    out.transmittance *= 1.0f - a;
    if (out.id == 0) {
        out.id = hit.id;
        out.depth = hit.enter;
    }
    if (out.transmittance < 1.0f / 1024.0f) {
        out.transmittance = 0.0f;
        return true;
    }
    return false;
}

bool objectHeightRange(std::span<const ObjectLayer* const> layers, float& lo, float& hi) {
    lo = std::numeric_limits<float>::infinity();
    hi = -lo;
    for (const ObjectLayer* l : layers) {
        if (l->empty()) continue;
        lo = std::min(lo, l->minBottom());
        hi = std::max(hi, l->maxTop());
    }
    return lo <= hi;
}

bool objectRaySpan(const TerrainMap& map, float lo, float hi, const glm::dvec3& origin,
                   const glm::dvec3& dir, double tEnd, double& t0, double& t1) {
    if (!(lo <= hi)) return false;
    // The ray inside the objects' box: the map's footprint, their height range.
    t0 = 0.0;
    t1 = std::isfinite(tEnd) ? tEnd : kInf;
    return clipSlab(origin.x, dir.x, 0.0, map.extentX(), t0, t1) &&
           clipSlab(origin.y, dir.y, 0.0, map.extentY(), t0, t1) &&
           clipSlab(origin.z, dir.z, lo, hi, t0, t1) && t0 < t1;
}

bool objectRaySpan(std::span<const ObjectLayer* const> layers, const glm::dvec3& origin,
                   const glm::dvec3& dir, double tEnd, double& t0, double& t1) {
    if (layers.empty()) return false;
    float lo = 0.0f, hi = 0.0f;
    if (!objectHeightRange(layers, lo, hi)) return false;
    return objectRaySpan(layers[0]->map(), lo, hi, origin, dir, tEnd, t0, t1);
}

void traceObjects(std::span<const ObjectLayer* const> layers, const glm::dvec3& origin,
                  const glm::dvec3& dir, double tEnd, const SkyModel& sky,
                  ObjectTraceScratch& scratch, ObjectShading& out, double tStart) {
    out = ObjectShading{};
    double t0 = 0.0, t1 = 0.0;
    if (!objectRaySpan(layers, origin, dir, tEnd, t0, t1)) return;
    const ObjectLayer& first = *layers[0];
    const TerrainMap& map = first.map();
    const int k = first.subdivision();
    const double csx = first.cellSizeX(), csy = first.cellSizeY();
    const int bw = map.width() - 1, bh = map.height() - 1;
    std::vector<VoxelHit>& hits = scratch.hits;
    bool done = false;
    const double spx = map.spacingX(), spy = map.spacingY();
    // The grids' lines: the terrain's, and the objects' as objectGridLine places them (the boxes'
    // own lines, ObjectLayer::boxLinesX/Y, so every walk crosses the same lines at the same t).
    const auto terrainX = [&](std::int64_t i) { return static_cast<double>(i) * spx; };
    const auto terrainY = [&](std::int64_t i) { return static_cast<double>(i) * spy; };
    const auto objectX = [&](std::int64_t i) { return objectGridLine(i, k, spx, csx); };
    const auto objectY = [&](std::int64_t i) { return objectGridLine(i, k, spy, csy); };
    walkGrid(
        origin.x, origin.y, dir.x, dir.y, 0.0, 0.0, spx, spy, terrainX, terrainY, 0, 0, bw - 1,
        bh - 1, t0, t1, -1, [&](std::int64_t bx, std::int64_t by, double ba, double bb, int baxis) {
            const double zA = origin.z + ba * dir.z, zB = origin.z + bb * dir.z;
            const double zLo = std::min(zA, zB), zHi = std::max(zA, zB);
            bool meets = false;
            for (const ObjectLayer* l : layers) {
                const int ix = static_cast<int>(bx), iy = static_cast<int>(by);
                meets = meets || (zLo <= l->blockTop(ix, iy) && zHi >= l->blockBottom(ix, iy));
            }
            if (!meets) return true;
            // The object cells of this terrain cell, in order along the ray.
            walkGrid(origin.x, origin.y, dir.x, dir.y, terrainX(bx), terrainY(by), csx, csy,
                     objectX, objectY, bx * k, by * k, bx * k + k - 1, by * k + k - 1, ba, bb,
                     baxis, [&](std::int64_t cx, std::int64_t cy, double ta, double tb, int axis) {
                         hits.clear();
                         for (const ObjectLayer* l : layers) {
                             for (const ObjectCell& cell : l->cellsAt(cx, cy))
                                 collectVoxelHits(l->table(), cell, origin, dir, ta, tb, axis,
                                                  hits);
                         }
                         if (hits.empty()) return true;
                         sortHits(hits);
                         for (const VoxelHit& hit : hits) {
                             if (hit.enter < tStart) continue;
                             if (blendVoxelHit(hit, sky, out)) {
                                 done = true;
                                 return false;
                             }
                         }
                         return true;
                     });
            return !done;
        });
}

double objectGridLine(std::int64_t i, std::int64_t k, double spacing, double cell) {
    const std::int64_t b = i / k;
    return static_cast<double>(b) * spacing + static_cast<double>(i - b * k) * cell;
}

void collectBoxHits(const ObjectLayer& layer, const ObjectBox& box, const glm::dvec3& o,
                    const glm::dvec3& d, double t0, double t1, std::vector<VoxelHit>& hits,
                    double& cutoff) {
    const double csx = layer.cellSizeX(), csy = layer.cellSizeY();
    const double invX = d.x != 0.0 ? 1.0 / d.x : kInf, invY = d.y != 0.0 ? 1.0 / d.y : kInf;
    const auto clip = [](double oc, double dc, double inv, double lo, double hi, double& a,
                         double& b) {
        if (dc == 0.0) return oc >= lo && oc <= hi;
        double ta = (lo - oc) * inv, tb = (hi - oc) * inv;
        if (ta > tb) std::swap(ta, tb);
        a = std::max(a, ta);
        b = std::min(b, tb);
        return a <= b;
    };
    // The ray inside the box, from where it enters it (or t0) to where it leaves its height
    // range (the box padded: the walk below finds the exact cells).
    const double padX = 1e-9 * layer.map().spacingX(), padY = 1e-9 * layer.map().spacingY();
    double ta = t0, tz = t1;
    if (!clip(o.x, d.x, invX, static_cast<double>(box.cx0) * csx - padX,
              static_cast<double>(box.cx1 + 1) * csx + padX, ta, tz) ||
        !clip(o.y, d.y, invY, static_cast<double>(box.cy0) * csy - padY,
              static_cast<double>(box.cy1 + 1) * csy + padY, ta, tz) ||
        !clipSlab(o.z, d.z, box.zLo - kBoxPad, box.zHi + kBoxPad, ta, tz)) {
        return;
    }
    const std::int64_t stepX = d.x > 0.0 ? 1 : -1, stepY = d.y > 0.0 ? 1 : -1;
    const std::int64_t upX = d.x > 0.0, upY = d.y > 0.0;
    // Cells relative to the box's south-west cell.
    const std::int64_t nx = box.cx1 - box.cx0, ny = box.cy1 - box.cy0;
    std::int64_t ix = std::clamp(static_cast<std::int64_t>(std::floor((o.x + ta * d.x) / csx)),
                                 box.cx0, box.cx1) -
                      box.cx0;
    std::int64_t iy = std::clamp(static_cast<std::int64_t>(std::floor((o.y + ta * d.y) / csy)),
                                 box.cy0, box.cy1) -
                      box.cy0;
    // The box's grid lines, as traceObjects' walk places them (objectGridLine).
    const double* lineX = layer.boxLinesX(box);
    const double* lineY = layer.boxLinesY(box);
    // The first cell's entry as the full walk finds it: the later of the grid lines crossed into
    // it, or t0 (with no side crossed) when the walk starts in it.
    const double ex = d.x != 0.0 ? (lineX[ix + 1 - upX] - o.x) * invX : -kInf;
    const double ey = d.y != 0.0 ? (lineY[iy + 1 - upY] - o.y) * invY : -kInf;
    int axis = ex > ey ? 0 : 1;
    ta = std::max(ex, ey);
    if (ta <= t0) {
        ta = t0;
        axis = -1;
    }
    double tx = d.x != 0.0 ? (lineX[ix + upX] - o.x) * invX : kInf;
    double ty = d.y != 0.0 ? (lineY[iy + upY] - o.y) * invY : kInf;
    const StickTable& table = layer.table();
    const float* ranges = layer.boxColumnRanges(box);
    for (;;) {
        if (ta > cutoff) return;  // behind an opaque voxel already found
        const double tb = std::min({tx, ty, t1});
        double zLo, zHi;
        if (tb >= ta &&
            boxCellHeightMet(ranges + 2 * (iy * (nx + 1) + ix), o, d, ta, tb, zLo, zHi)) {
            const std::size_t before = hits.size();
            collectBoxCellHits(table, layer.boxCellsAt(box, box.cx0 + ix, box.cy0 + iy), box.id,
                               zLo, zHi, o, d, ta, tb, axis, hits);
            for (std::size_t i = before; i < hits.size(); ++i)
                if (hits[i].color.a == 255) cutoff = std::min(cutoff, hits[i].enter);
        }
        if (tb >= t1 || tb >= tz) return;
        // The next cell's entry as the per-pixel walk finds it (its first cell here is placed
        // by the position at the box's padded entry).
        if (stepToNextCell(tx, ty, tb, ta, axis) == 0) {
            ix += stepX;
            if (ix < 0 || ix > nx) return;
            tx = (lineX[ix + upX] - o.x) * invX;
        } else {
            iy += stepY;
            if (iy < 0 || iy > ny) return;
            ty = (lineY[iy + upY] - o.y) * invY;
        }
    }
}

void sortHits(std::vector<VoxelHit>& hits) {
    const auto before = [](const VoxelHit& a, const VoxelHit& b) {
        if (a.enter != b.enter) return a.enter < b.enter;
        return a.id < b.id;
    };
    // Mostly collected in order already (the footprint pass takes the cells nearest first).
    std::size_t i = 1;
    while (i < hits.size() && !before(hits[i], hits[i - 1]))
        ++i;
    if (i >= hits.size()) return;
    for (std::size_t j = 0; j < hits.size(); ++j)
        hits[j].seq = static_cast<std::uint32_t>(j);
    std::sort(hits.begin(), hits.end(), [&](const VoxelHit& a, const VoxelHit& b) {
        if (before(a, b)) return true;
        if (before(b, a)) return false;
        return a.seq < b.seq;
    });
}

Rgb8 composeOver(const ObjectShading& shading, Rgb8 background) {
    if (shading.id == 0) return background;
    const float t = shading.transmittance;
    const float rgb[3] = {shading.rgb[0] + t * background.r, shading.rgb[1] + t * background.g,
                          shading.rgb[2] + t * background.b};
    return quantizeColor(rgb);
}

}  // namespace ig

namespace ig {

std::vector<ObjectPixels> objectPixelStats(const RenderedFrame& frame) {
    std::vector<ObjectPixels> byId(65536);
    const int w = frame.width();
    for (std::size_t i = 0; i < frame.objectId.size(); ++i) {
        const std::uint16_t id = frame.objectId[i];
        if (id == 0) continue;
        const int x = static_cast<int>(i % static_cast<std::size_t>(w));
        const int y = static_cast<int>(i / static_cast<std::size_t>(w));
        ObjectPixels& o = byId[id];
        if (o.pixels == 0) o = ObjectPixels{id, 0, x, y, x, y};
        ++o.pixels;
        o.x0 = std::min(o.x0, x);
        o.x1 = std::max(o.x1, x);
        o.y0 = std::min(o.y0, y);
        o.y1 = std::max(o.y1, y);
    }
    std::vector<ObjectPixels> out;
    for (const ObjectPixels& o : byId)
        if (o.pixels > 0) out.push_back(o);
    return out;
}

}  // namespace ig
