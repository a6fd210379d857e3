// The objects' footprint pass (docs/design/objects.md, "Objects in the fast casters"): boxes
// projected to pixel rectangles, binned into tiles, each tile's pixels traced through the boxes
// that cover them.
#include "ig/object_pass.hpp"

#include "base/check.hpp"

#include "ig/object_trace.hpp"
#include "ig/surface_hit.hpp"

#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>
#include <glm/common.hpp>
#include <glm/geometric.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <vector>

namespace ig {
namespace {

constexpr int kTile = 32;  // pixels on a side of a tile
// Camera depth (metres along the view axis) the boxes are clipped at: a ray's points nearer
// the camera plane than this are not drawn (the reference draws them; 1 um from the eye).
constexpr double kNear = 1e-6;
// Height added above and below each box: its range is float, the voxels' heights double.
constexpr double kBoxPad = 1e-3;
// Pixels added around a box's projection (a fraction of one).
constexpr double kMargin = 1e-3;

// One box's pixel rectangle (inclusive), and which box it is.
struct Footprint {
    int x0, y0, x1, y1;
    std::uint32_t layer, box;
    double lo[3], hi[3];  // the box padded as boxEntry pads it
    // Splatted: its cells' columns are drawn one by one (SplatColumn, columns [first, first +
    // count)) instead of each pixel walking the box.
    bool splat = false;
    std::uint32_t firstColumn = 0, columns = 0;
};

// One cell of a splatted box: the pixels whose rays may meet its entries, and the cell.
struct SplatColumn {
    int x0, y0, x1, y1;   // inclusive
    std::int32_t ix, iy;  // the cell, from the box's south-west one
    double near;          // at most the distance from the eye to the column's box
    std::uint32_t foot;   // its box's footprint
};

// The pixel rectangle of `box` within columns [cx0, cx1) and rows [0, h): the pixels whose
// centres lie within a pixel of the projection of the box's part in front of the camera.
// False when none.
// The pixel rectangle (inclusive) of the box xs x ys x zs within columns [cx0, cx1) and rows
// [0, h): the pixels whose centres lie within kMargin of the projection of the box's part in
// front of the camera. False when none.
bool projectedRect(const double xs[2], const double ys[2], const double zs[2], const Camera& camera,
                   int cx0, int cx1, int h, int& x0, int& y0, int& x1, int& y1) {
    const CameraBasis& basis = camera.basis();
    const glm::dvec3 eye = camera.pose().position;
    // The corners in camera coordinates (right, up, forward).
    std::array<glm::dvec3, 8> c;
    for (int i = 0; i < 8; ++i) {
        const glm::dvec3 d = glm::dvec3{xs[i & 1], ys[(i >> 1) & 1], zs[i >> 2]} - eye;
        c[static_cast<std::size_t>(i)] = {glm::dot(d, basis.right), glm::dot(d, basis.up),
                                          glm::dot(d, basis.forward)};
    }
    const Intrinsics& in = camera.intrinsics();
    double u0 = INFINITY, u1 = -INFINITY, v0 = INFINITY, v1 = -INFINITY;
    const auto add = [&](const glm::dvec3& p) {
        const double u = in.cx() + in.focal * p.x / p.z, v = in.cy() - in.focal * p.y / p.z;
        u0 = std::min(u0, u);
        u1 = std::max(u1, u);
        v0 = std::min(v0, v);
        v1 = std::max(v1, v);
    };
    bool any = false;
    for (const glm::dvec3& p : c) {
        if (p.z >= kNear) {
            add(p);
            any = true;
        }
    }
    if (!any) return false;
    // The box clipped by the plane z = kNear: where its edges cross it.
    for (int i = 0; i < 8; ++i) {
        for (const int bit : {1, 2, 4}) {
            const int j = i | bit;
            if (j == i) continue;
            const glm::dvec3& a = c[static_cast<std::size_t>(i)];
            const glm::dvec3& b = c[static_cast<std::size_t>(j)];
            if ((a.z >= kNear) == (b.z >= kNear)) continue;
            const double s = (kNear - a.z) / (b.z - a.z);
            add(glm::dvec3{a.x + s * (b.x - a.x), a.y + s * (b.y - a.y), kNear});
        }
    }
    // Pixel x has its centre at x + 0.5; a margin of kMargin for the rounding of the
    // projection and of the rays (both exact to about 1e-12 pixel).
    const double fx0 = std::ceil(u0 - 0.5 - kMargin), fx1 = std::floor(u1 - 0.5 + kMargin);
    const double fy0 = std::ceil(v0 - 0.5 - kMargin), fy1 = std::floor(v1 - 0.5 + kMargin);
    if (!(fx1 >= cx0 && fx0 < cx1 && fy1 >= 0.0 && fy0 < h)) return false;
    x0 = static_cast<int>(std::max<double>(fx0, cx0));
    x1 = static_cast<int>(std::min<double>(fx1, cx1 - 1));
    y0 = static_cast<int>(std::max(fy0, 0.0));
    y1 = static_cast<int>(std::min<double>(fy1, h - 1));
    return true;
}

bool footprint(const ObjectLayer& layer, const ObjectBox& box, const Camera& camera, int cx0,
               int cx1, int h, Footprint& out) {
    const double* lineX = layer.boxLinesX(box);
    const double* lineY = layer.boxLinesY(box);
    const double xs[2] = {lineX[0], lineX[box.cx1 - box.cx0 + 1]};
    const double ys[2] = {lineY[0], lineY[box.cy1 - box.cy0 + 1]};
    const double zs[2] = {box.zLo - kBoxPad, box.zHi + kBoxPad};
    return projectedRect(xs, ys, zs, camera, cx0, cx1, h, out.x0, out.y0, out.x1, out.y1);
}

// The columns of a splatted box: every cell holding an entry of its id whose projection (the
// cell's square, its entries' height range padded) reaches a pixel, nearest the eye first (so a
// pixel's cutoff falls early).
void splatColumns(const ObjectLayer& layer, const ObjectBox& box, const Camera& camera, int cx0,
                  int cx1, int h, std::vector<SplatColumn>& out) {
    const double* lineX = layer.boxLinesX(box);
    const double* lineY = layer.boxLinesY(box);
    const float* ranges = layer.boxColumnRanges(box);
    const glm::dvec3 eye = camera.pose().position;
    const std::int64_t nx = box.cx1 - box.cx0 + 1, ny = box.cy1 - box.cy0 + 1;
    const std::size_t first = out.size();
    for (std::int64_t iy = 0; iy < ny; ++iy) {
        for (std::int64_t ix = 0; ix < nx; ++ix) {
            const float* r = ranges + 2 * (iy * nx + ix);
            if (!(r[0] <= r[1])) continue;
            const double xs[2] = {lineX[ix], lineX[ix + 1]};
            const double ys[2] = {lineY[iy], lineY[iy + 1]};
            const double zs[2] = {r[0] - 2 * kBoxPad, r[1] + 2 * kBoxPad};
            SplatColumn c;
            if (!projectedRect(xs, ys, zs, camera, cx0, cx1, h, c.x0, c.y0, c.x1, c.y1)) continue;
            c.ix = static_cast<std::int32_t>(ix);
            c.iy = static_cast<std::int32_t>(iy);
            const glm::dvec3 lo{xs[0], ys[0], zs[0]}, hi{xs[1], ys[1], zs[1]};
            const double dist = glm::length(glm::clamp(eye, lo, hi) - eye);
            // A ray parameter is a distance (unit directions); less a micrometre per metre for
            // the rounding of both.
            c.near = dist - 1e-6 * (1.0 + dist);
            out.push_back(c);
        }
    }
    const auto distance = [&](const SplatColumn& c) {
        const double dx = 0.5 * (lineX[c.ix] + lineX[c.ix + 1]) - eye.x;
        const double dy = 0.5 * (lineY[c.iy] + lineY[c.iy + 1]) - eye.y;
        return dx * dx + dy * dy;
    };
    std::stable_sort(
        out.begin() + static_cast<std::ptrdiff_t>(first), out.end(),
        [&](const SplatColumn& a, const SplatColumn& b) { return distance(a) < distance(b); });
}

// A pixel's centre ray, worked out once per tile when first needed.
struct PixelRay {
    glm::dvec3 origin, dir;
    double invX = 0.0, invY = 0.0;  // 1 / dir.x, 1 / dir.y
    int upX = 0, upY = 0;           // dir.x > 0, dir.y > 0
    double t0 = 0.0, t1 = 0.0;      // objectRaySpan's span
    double cutoff = 0.0;            // the nearest opaque voxel the splatted columns found (else t1)
    std::uint32_t head = 0, tail = 0;  // the splatted hits' list in TileScratch::splatHits
    std::int8_t state = 0;             // 0 not yet worked out, 1 a span, -1 none
};

constexpr std::uint32_t kNoHit = 0xffffffffu;

// A worker's buffers, reused from tile to tile.
struct TileScratch {
    std::vector<std::uint32_t> start;  // per pixel of the tile + 1: its first walked footprint
    std::vector<std::uint32_t> list;   // walked footprints by pixel
    std::vector<VoxelHit> hits;
    std::vector<std::pair<double, std::uint32_t>> order;  // a pixel's boxes by entry
    std::vector<PixelRay> rays;                           // per pixel of the tile
    std::vector<VoxelHit> splatHits;                      // hits of splatted columns, all pixels
    std::vector<std::uint32_t> splatNext;                 // each one's next of its pixel
    std::vector<VoxelHit> cellHits;                       // one cell's, before they are linked
    std::vector<std::uint32_t> tileColumns;               // the tile's columns, nearest first
};

// Where the ray (origin o, inverse direction inv: +-inf on an axis it does not move along)
// enters footprint f's padded box within [t0, t1]; +inf when it misses. Only orders the boxes
// and skips those beyond an opaque voxel already found: the pad (a micrometre of the map's
// extent across, twice the walk's in height) keeps it at or before every voxel of the box.
double boxEntry(const Footprint& f, const glm::dvec3& o, const double inv[3], double t0,
                double t1) {
    const double oc[3] = {o.x, o.y, o.z};
    for (int a = 0; a < 3; ++a) {
        if (std::isinf(inv[a])) {
            if (oc[a] < f.lo[a] || oc[a] > f.hi[a]) return INFINITY;
            continue;
        }
        double ta = (f.lo[a] - oc[a]) * inv[a], tb = (f.hi[a] - oc[a]) * inv[a];
        if (ta > tb) std::swap(ta, tb);
        t0 = std::max(t0, ta);
        t1 = std::min(t1, tb);
    }
    return t0 <= t1 ? t0 : INFINITY;
}

}  // namespace

void drawObjects(std::span<const ObjectLayer* const> layers, const SkyModel& sky,
                 const Camera& camera, RenderedFrame& frame, int x0, int x1, bool parallel,
                 const ObjectPassOptions& options) {
    const int w = camera.intrinsics().width, h = camera.intrinsics().height;
    if (options.stats != nullptr) *options.stats = ObjectPassStats{};
    CHECK_EQ(frame.objectId.size(), static_cast<std::size_t>(w) * static_cast<std::size_t>(h));
    x0 = std::max(x0, 0);
    x1 = std::min(x1, w);
    if (layers.empty() || x0 >= x1) return;
    const TerrainMap& map = layers[0]->map();

    // Every box's footprint, then binned by tile (a count per tile, then the lists in place).
    // Boxes with several pixels per cell are splatted: their cells' columns projected one by one.
    std::vector<Footprint> feet;
    std::vector<SplatColumn> columns;
    for (std::size_t l = 0; l < layers.size(); ++l) {
        const std::vector<ObjectBox>& boxes = layers[l]->boxes();
        for (std::size_t b = 0; b < boxes.size(); ++b) {
            Footprint f;
            if (!footprint(*layers[l], boxes[b], camera, x0, x1, h, f)) continue;
            f.layer = static_cast<std::uint32_t>(l);
            f.box = static_cast<std::uint32_t>(b);
            const ObjectBox& box = boxes[b];
            const ObjectLayer& layer = *layers[l];
            const double pad = 1e-6 * std::max(map.extentX(), map.extentY());
            f.lo[0] = static_cast<double>(box.cx0) * layer.cellSizeX() - pad;
            f.hi[0] = static_cast<double>(box.cx1 + 1) * layer.cellSizeX() + pad;
            f.lo[1] = static_cast<double>(box.cy0) * layer.cellSizeY() - pad;
            f.hi[1] = static_cast<double>(box.cy1 + 1) * layer.cellSizeY() + pad;
            f.lo[2] = box.zLo - 2 * kBoxPad;
            f.hi[2] = box.zHi + 2 * kBoxPad;
            const double area = static_cast<double>(f.x1 - f.x0 + 1) * (f.y1 - f.y0 + 1);
            if (area >= options.splatPixelsPerColumn * static_cast<double>(box.filled)) {
                f.splat = true;
                f.firstColumn = static_cast<std::uint32_t>(columns.size());
                splatColumns(layer, box, camera, x0, x1, h, columns);
                f.columns = static_cast<std::uint32_t>(columns.size()) - f.firstColumn;
                if (f.columns == 0) continue;
                for (std::uint32_t c = f.firstColumn; c < f.firstColumn + f.columns; ++c)
                    columns[c].foot = static_cast<std::uint32_t>(feet.size());
            }
            feet.push_back(f);
        }
    }
    if (options.stats != nullptr) {
        options.stats->boxes = feet.size();
        options.stats->splatted = static_cast<std::size_t>(
            std::count_if(feet.begin(), feet.end(), [](const Footprint& f) { return f.splat; }));
        options.stats->columns = columns.size();
    }
    if (feet.empty()) return;
    const int tilesX = (x1 - x0 + kTile - 1) / kTile, tilesY = (h + kTile - 1) / kTile;
    const std::size_t tiles = static_cast<std::size_t>(tilesX) * static_cast<std::size_t>(tilesY);
    // Walked footprints and splatted columns by tile, each list in the order given.
    const auto binByTile = [&](std::size_t n, auto rectOf, std::vector<std::uint32_t>& start,
                               std::vector<std::uint32_t>& list) {
        const auto forTiles = [&](std::size_t i, auto visit) {
            int rx0, ry0, rx1, ry1;
            if (!rectOf(i, rx0, ry0, rx1, ry1)) return;
            for (int ty = ry0 / kTile; ty <= ry1 / kTile; ++ty)
                for (int tx = (rx0 - x0) / kTile; tx <= (rx1 - x0) / kTile; ++tx)
                    visit(static_cast<std::size_t>(ty) * tilesX + tx);
        };
        start.assign(tiles + 1, 0);
        for (std::size_t i = 0; i < n; ++i)
            forTiles(i, [&](std::size_t t) { ++start[t + 1]; });
        for (std::size_t t = 1; t < start.size(); ++t)
            start[t] += start[t - 1];
        list.resize(start.back());
        std::vector<std::uint32_t> fill(start.begin(), start.end() - 1);
        for (std::size_t i = 0; i < n; ++i)
            forTiles(i, [&](std::size_t t) { list[fill[t]++] = static_cast<std::uint32_t>(i); });
    };
    std::vector<std::uint32_t> tileStart, tileList, columnStart, columnList;
    binByTile(
        feet.size(),
        [&](std::size_t i, int& a, int& b, int& c, int& d) {
            const Footprint& f = feet[i];
            a = f.x0, b = f.y0, c = f.x1, d = f.y1;
            return !f.splat;
        },
        tileStart, tileList);
    binByTile(
        columns.size(),
        [&](std::size_t i, int& a, int& b, int& c, int& d) {
            const SplatColumn& col = columns[i];
            a = col.x0, b = col.y0, c = col.x1, d = col.y1;
            return true;
        },
        columnStart, columnList);

    const glm::dvec3 eye = camera.pose().position;
    float heightLo = 0.0f, heightHi = 0.0f;
    if (!objectHeightRange(layers, heightLo, heightHi)) return;
    tbb::enumerable_thread_specific<TileScratch> scratches;
    const auto drawTile = [&](int tile) {
        const std::uint32_t first = tileStart[static_cast<std::size_t>(tile)];
        const std::uint32_t last = tileStart[static_cast<std::size_t>(tile) + 1];
        const std::uint32_t firstColumn = columnStart[static_cast<std::size_t>(tile)];
        const std::uint32_t lastColumn = columnStart[static_cast<std::size_t>(tile) + 1];
        if (first == last && firstColumn == lastColumn) return;
        const int tx0 = x0 + (tile % tilesX) * kTile, ty0 = (tile / tilesX) * kTile;
        const int tw = std::min(kTile, x1 - tx0), th = std::min(kTile, h - ty0);
        TileScratch& s = scratches.local();
        const std::size_t pixels = static_cast<std::size_t>(tw) * th;
        s.rays.assign(pixels, PixelRay{});
        // The pixel's ray and span, the first time it is asked for.
        const auto rayAt = [&](std::size_t p) -> PixelRay& {
            PixelRay& r = s.rays[p];
            if (r.state != 0) return r;
            const int x = tx0 + static_cast<int>(p % static_cast<std::size_t>(tw));
            const int y = ty0 + static_cast<int>(p / static_cast<std::size_t>(tw));
            const std::size_t idx = static_cast<std::size_t>(y) * w + x;
            const TerrainRay ray(map, eye, camera.rayDirection(x + 0.5, y + 0.5));
            r.origin = ray.origin;
            r.dir = ray.dir;
            r.invX = 1.0 / ray.dir.x;
            r.invY = 1.0 / ray.dir.y;
            r.upX = ray.dir.x > 0.0;
            r.upY = ray.dir.y > 0.0;
            r.state = objectRaySpan(map, heightLo, heightHi, ray.origin, ray.dir, frame.depth[idx],
                                    r.t0, r.t1)
                          ? 1
                          : -1;
            r.cutoff = r.t1;
            r.head = r.tail = kNoHit;
            return r;
        };

        // The splatted boxes first: each column's pixels find the cell's span along their ray as
        // the walk would enter and leave it (the same grid lines, the same expressions) and
        // collect its voxels; the nearest opaque one found is each pixel's cutoff.
        s.splatHits.clear();
        s.splatNext.clear();
        s.tileColumns.assign(columnList.begin() + firstColumn, columnList.begin() + lastColumn);
        std::stable_sort(
            s.tileColumns.begin(), s.tileColumns.end(),
            [&](std::uint32_t a, std::uint32_t b) { return columns[a].near < columns[b].near; });
        for (const std::uint32_t ci : s.tileColumns) {
            const SplatColumn& col = columns[ci];
            const Footprint& f = feet[col.foot];
            const ObjectLayer& layer = *layers[f.layer];
            const ObjectBox& box = layer.boxes()[f.box];
            const double* lineX = layer.boxLinesX(box);
            const double* lineY = layer.boxLinesY(box);
            const int ya = std::max(col.y0, ty0), yb = std::min(col.y1, ty0 + th - 1);
            const int xa = std::max(col.x0, tx0), xb = std::min(col.x1, tx0 + tw - 1);
            const std::span<const ObjectCell> entries =
                layer.boxCellsAt(box, box.cx0 + col.ix, box.cy0 + col.iy);
            const float* range =
                layer.boxColumnRanges(box) + 2 * (col.iy * (box.cx1 - box.cx0 + 1) + col.ix);
            for (int y = ya; y <= yb; ++y) {
                for (int x = xa; x <= xb; ++x) {
                    const std::size_t p = static_cast<std::size_t>(y - ty0) * tw + (x - tx0);
                    PixelRay& r = rayAt(p);
                    if (r.state < 0 || r.cutoff < col.near) continue;
                    const glm::dvec3& o = r.origin;
                    const glm::dvec3& d = r.dir;
                    const double invX = r.invX, invY = r.invY;
                    const int upX = r.upX, upY = r.upY;
                    const double ex =
                        d.x != 0.0 ? (lineX[col.ix + 1 - upX] - o.x) * invX : -INFINITY;
                    const double ey =
                        d.y != 0.0 ? (lineY[col.iy + 1 - upY] - o.y) * invY : -INFINITY;
                    int axis = ex > ey ? 0 : 1;
                    double ta = std::max(ex, ey);
                    if (ta <= r.t0) {
                        ta = r.t0;
                        axis = -1;
                    }
                    if (ta > r.cutoff) continue;
                    const double tx = d.x != 0.0 ? (lineX[col.ix + upX] - o.x) * invX : INFINITY;
                    const double ty = d.y != 0.0 ? (lineY[col.iy + upY] - o.y) * invY : INFINITY;
                    const double tb = std::min({tx, ty, r.t1});
                    double zLo, zHi;
                    if (!(tb >= ta) || !boxCellHeightMet(range, o, d, ta, tb, zLo, zHi)) continue;
                    s.cellHits.clear();
                    collectBoxCellHits(layer.table(), entries, box.id, zLo, zHi, o, d, ta, tb, axis,
                                       s.cellHits);
                    for (const VoxelHit& hit : s.cellHits) {
                        if (hit.color.a == 255) r.cutoff = std::min(r.cutoff, hit.enter);
                        const auto at = static_cast<std::uint32_t>(s.splatHits.size());
                        s.splatHits.push_back(hit);
                        s.splatNext.push_back(kNoHit);
                        if (r.head == kNoHit)
                            r.head = at;
                        else
                            s.splatNext[r.tail] = at;
                        r.tail = at;
                    }
                }
            }
        }

        // The footprints the other boxes cover each pixel with, by pixel (a count, then in
        // place).
        s.start.assign(pixels + 1, 0);
        const auto forPixels = [&](const Footprint& f, auto visit) {
            const int ya = std::max(f.y0, ty0), yb = std::min(f.y1, ty0 + th - 1);
            const int xa = std::max(f.x0, tx0), xb = std::min(f.x1, tx0 + tw - 1);
            for (int y = ya; y <= yb; ++y)
                for (int x = xa; x <= xb; ++x)
                    visit(static_cast<std::size_t>(y - ty0) * tw + (x - tx0));
        };
        for (std::uint32_t i = first; i < last; ++i)
            forPixels(feet[tileList[i]], [&](std::size_t p) { ++s.start[p + 1]; });
        for (std::size_t p = 1; p < s.start.size(); ++p)
            s.start[p] += s.start[p - 1];
        s.list.resize(s.start.back());
        for (std::uint32_t i = first; i < last; ++i) {
            const std::uint32_t f = tileList[i];
            // start[p] is the next free slot of pixel p while filling; restored below.
            forPixels(feet[f], [&](std::size_t p) { s.list[s.start[p]++] = f; });
        }
        for (std::size_t p = s.start.size() - 1; p > 0; --p)
            s.start[p] = s.start[p - 1];
        s.start[0] = 0;

        for (int py = 0; py < th; ++py) {
            for (int px = 0; px < tw; ++px) {
                const std::size_t p = static_cast<std::size_t>(py) * tw + px;
                const bool walked = s.start[p] != s.start[p + 1];
                if (!walked && (s.rays[p].state <= 0 || s.rays[p].head == kNoHit)) continue;
                const PixelRay& ray = rayAt(p);
                if (ray.state < 0) continue;
                const int x = tx0 + px, y = ty0 + py;
                const std::size_t idx = static_cast<std::size_t>(y) * w + x;
                const double t0 = ray.t0, t1 = ray.t1;
                s.hits.clear();
                for (std::uint32_t k = ray.head; k != kNoHit; k = s.splatNext[k])
                    s.hits.push_back(s.splatHits[k]);
                // The walked boxes in the order the ray enters them, walked until one opaque
                // voxel hides the rest.
                s.order.clear();
                const double inv[3] = {1.0 / ray.dir.x, 1.0 / ray.dir.y, 1.0 / ray.dir.z};
                for (std::uint32_t i = s.start[p]; i < s.start[p + 1]; ++i) {
                    const Footprint& f = feet[s.list[i]];
                    const double enter = boxEntry(f, ray.origin, inv, t0, t1);
                    if (enter <= t1) s.order.push_back({enter, s.list[i]});
                }
                std::sort(s.order.begin(), s.order.end());
                double cutoff = ray.cutoff;
                for (const auto& [enter, fi] : s.order) {
                    if (enter > cutoff) break;
                    const Footprint& f = feet[fi];
                    const ObjectLayer& layer = *layers[f.layer];
                    collectBoxHits(layer, layer.boxes()[f.box], ray.origin, ray.dir, t0, t1, s.hits,
                                   cutoff);
                }
                if (s.hits.empty()) continue;
                sortHits(s.hits);
                ObjectShading shading;
                for (const VoxelHit& hit : s.hits)
                    if (blendVoxelHit(hit, sky, shading)) break;
                if (shading.id == 0) continue;
                frame.color[idx] = composeOver(shading, frame.color[idx]);
                frame.objectId[idx] = shading.id;
                frame.depth[idx] = static_cast<float>(shading.depth);
            }
        }
    };
    if (parallel) {
        tbb::parallel_for(0, static_cast<int>(tiles), drawTile);
    } else {
        for (int t = 0; t < static_cast<int>(tiles); ++t)
            drawTile(t);
    }
}

void drawObjectsPerPixel(std::span<const ObjectLayer* const> layers, const SkyModel& sky,
                         const Camera& camera, RenderedFrame& frame, int x0, int x1) {
    const int w = camera.intrinsics().width, h = camera.intrinsics().height;
    CHECK_EQ(frame.objectId.size(), static_cast<std::size_t>(w) * static_cast<std::size_t>(h));
    if (layers.empty()) return;
    const TerrainMap& map = layers[0]->map();
    ObjectTraceScratch scratch;
    ObjectShading shading;
    for (int y = 0; y < h; ++y) {
        for (int x = std::max(x0, 0); x < std::min(x1, w); ++x) {
            const std::size_t idx = static_cast<std::size_t>(y) * w + x;
            const TerrainRay ray(map, camera.pose().position,
                                 camera.rayDirection(x + 0.5, y + 0.5));
            traceObjects(layers, ray.origin, ray.dir, frame.depth[idx], sky, scratch, shading);
            frame.color[idx] = composeOver(shading, frame.color[idx]);
            frame.objectId[idx] = shading.id;
            if (shading.id != 0) frame.depth[idx] = static_cast<float>(shading.depth);
        }
    }
}

void drawObjectsOverTerrain(std::span<const ObjectLayer* const> layers, const SkyModel& sky,
                            const Camera& camera, RenderedFrame& frame) {
    if (layers.empty()) return;
    const int w = camera.intrinsics().width, h = camera.intrinsics().height;
    frame.objectId.assign(static_cast<std::size_t>(w) * static_cast<std::size_t>(h), 0);
    drawObjects(layers, sky, camera, frame, 0, w, true);
}

}  // namespace ig
