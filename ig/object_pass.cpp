// The objects' footprint pass (docs/design/objects.md, "Objects in the fast casters"): boxes
// projected to pixel rectangles, binned into tiles, each tile's pixels traced through the boxes
// that cover them.
#include "ig/object_pass.hpp"

#include "base/check.hpp"

#include "ig/object_trace.hpp"
#include "ig/surface_hit.hpp"

#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>
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
};

// The pixel rectangle of `box` within columns [cx0, cx1) and rows [0, h): the pixels whose
// centres lie within a pixel of the projection of the box's part in front of the camera.
// False when none.
bool footprint(const ObjectLayer& layer, const ObjectBox& box, const Camera& camera, int cx0,
               int cx1, int h, Footprint& out) {
    const TerrainMap& map = layer.map();
    const std::int64_t k = layer.subdivision();
    const auto line = [k](std::int64_t g, double spacing, double cell) {
        const std::int64_t b = g / k;
        return static_cast<double>(b) * spacing + static_cast<double>(g - b * k) * cell;
    };
    const double xs[2] = {line(box.cx0, map.spacingX(), layer.cellSizeX()),
                          line(box.cx1 + 1, map.spacingX(), layer.cellSizeX())};
    const double ys[2] = {line(box.cy0, map.spacingY(), layer.cellSizeY()),
                          line(box.cy1 + 1, map.spacingY(), layer.cellSizeY())};
    const double zs[2] = {box.zLo - kBoxPad, box.zHi + kBoxPad};
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
    out.x0 = static_cast<int>(std::max<double>(fx0, cx0));
    out.x1 = static_cast<int>(std::min<double>(fx1, cx1 - 1));
    out.y0 = static_cast<int>(std::max(fy0, 0.0));
    out.y1 = static_cast<int>(std::min<double>(fy1, h - 1));
    return true;
}

// A worker's buffers, reused from tile to tile.
struct TileScratch {
    std::vector<std::uint32_t> start;  // per pixel of the tile + 1: its first footprint
    std::vector<std::uint32_t> list;   // footprints by pixel
    std::vector<VoxelHit> hits;
    std::vector<std::pair<double, std::uint32_t>> order;  // a pixel's boxes by entry
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
                 const Camera& camera, RenderedFrame& frame, int x0, int x1, bool parallel) {
    const int w = camera.intrinsics().width, h = camera.intrinsics().height;
    CHECK_EQ(frame.objectId.size(), static_cast<std::size_t>(w) * static_cast<std::size_t>(h));
    x0 = std::max(x0, 0);
    x1 = std::min(x1, w);
    if (layers.empty() || x0 >= x1) return;
    const TerrainMap& map = layers[0]->map();

    // Every box's footprint, then binned by tile (a count per tile, then the lists in place).
    std::vector<Footprint> feet;
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
            feet.push_back(f);
        }
    }
    if (feet.empty()) return;
    const int tilesX = (x1 - x0 + kTile - 1) / kTile, tilesY = (h + kTile - 1) / kTile;
    std::vector<std::uint32_t> tileStart(static_cast<std::size_t>(tilesX) * tilesY + 1, 0);
    const auto forTiles = [&](const Footprint& f, auto visit) {
        for (int ty = f.y0 / kTile; ty <= f.y1 / kTile; ++ty) {
            for (int tx = (f.x0 - x0) / kTile; tx <= (f.x1 - x0) / kTile; ++tx) {
                visit(static_cast<std::size_t>(ty) * tilesX + tx);
            }
        }
    };
    for (const Footprint& f : feet)
        forTiles(f, [&](std::size_t t) { ++tileStart[t + 1]; });
    for (std::size_t t = 1; t < tileStart.size(); ++t)
        tileStart[t] += tileStart[t - 1];
    std::vector<std::uint32_t> tileList(tileStart.back());
    {
        std::vector<std::uint32_t> fill(tileStart.begin(), tileStart.end() - 1);
        for (std::uint32_t i = 0; i < feet.size(); ++i)
            forTiles(feet[i], [&](std::size_t t) { tileList[fill[t]++] = i; });
    }

    const glm::dvec3 eye = camera.pose().position;
    float heightLo = 0.0f, heightHi = 0.0f;
    if (!objectHeightRange(layers, heightLo, heightHi)) return;
    tbb::enumerable_thread_specific<TileScratch> scratches;
    const auto drawTile = [&](int tile) {
        const std::uint32_t first = tileStart[static_cast<std::size_t>(tile)];
        const std::uint32_t last = tileStart[static_cast<std::size_t>(tile) + 1];
        if (first == last) return;
        const int tx0 = x0 + (tile % tilesX) * kTile, ty0 = (tile / tilesX) * kTile;
        const int tw = std::min(kTile, x1 - tx0), th = std::min(kTile, h - ty0);
        TileScratch& s = scratches.local();
        // The footprints covering each pixel of the tile, by pixel (a count, then in place).
        s.start.assign(static_cast<std::size_t>(tw) * th + 1, 0);
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
                if (s.start[p] == s.start[p + 1]) continue;
                const int x = tx0 + px, y = ty0 + py;
                const std::size_t idx = static_cast<std::size_t>(y) * w + x;
                const TerrainRay ray(map, eye, camera.rayDirection(x + 0.5, y + 0.5));
                double t0, t1;
                if (!objectRaySpan(map, heightLo, heightHi, ray.origin, ray.dir, frame.depth[idx],
                                   t0, t1)) {
                    continue;
                }
                // The boxes in the order the ray enters them, walked until one opaque voxel
                // hides the rest.
                s.order.clear();
                const double inv[3] = {1.0 / ray.dir.x, 1.0 / ray.dir.y, 1.0 / ray.dir.z};
                for (std::uint32_t i = s.start[p]; i < s.start[p + 1]; ++i) {
                    const Footprint& f = feet[s.list[i]];
                    const double enter = boxEntry(f, ray.origin, inv, t0, t1);
                    if (enter <= t1) s.order.push_back({enter, s.list[i]});
                }
                std::sort(s.order.begin(), s.order.end());
                s.hits.clear();
                double cutoff = t1;
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
    const int tiles = tilesX * tilesY;
    if (parallel) {
        tbb::parallel_for(0, tiles, drawTile);
    } else {
        for (int t = 0; t < tiles; ++t)
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
