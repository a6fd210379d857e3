// The footprint: the view frustum, cut off at the forward depth of the farthest point of the
// map's box, is a pyramid (apex and four far corners); its part between the terrain's lowest
// and highest heights is a convex polytope whose vertices are the pyramid's vertices inside that
// slab and the points where the pyramid's eight edges cross its two planes. Every ray segment
// that can meet the terrain lies in it, so every cell such a ray reads lies under the convex
// hull of those vertices projected on the ground. A tile is needed at level k when its square
// meets that hull and its horizontal distances from the eye meet level k's distance band.
#include "ig/tile_footprint.hpp"

#include <glm/geometric.hpp>

#include <algorithm>
#include <cmath>
#include <limits>

namespace ig {
namespace {

struct P2 {
    double x, y;
};

double cross(const P2& o, const P2& a, const P2& b) {
    return (a.x - o.x) * (b.y - o.y) - (a.y - o.y) * (b.x - o.x);
}

// Andrew's monotone chain; counter-clockwise, no repeated points.
std::vector<P2> convexHull(std::vector<P2> p) {
    std::sort(p.begin(), p.end(),
              [](const P2& a, const P2& b) { return a.x < b.x || (a.x == b.x && a.y < b.y); });
    p.erase(std::unique(p.begin(), p.end(),
                        [](const P2& a, const P2& b) { return a.x == b.x && a.y == b.y; }),
            p.end());
    if (p.size() < 3) return p;
    std::vector<P2> h(2 * p.size());
    std::size_t k = 0;
    for (std::size_t i = 0; i < p.size(); ++i) {
        while (k >= 2 && cross(h[k - 2], h[k - 1], p[i]) <= 0)
            --k;
        h[k++] = p[i];
    }
    for (std::size_t i = p.size() - 1, t = k + 1; i > 0; --i) {
        while (k >= t && cross(h[k - 2], h[k - 1], p[i - 1]) <= 0)
            --k;
        h[k++] = p[i - 1];
    }
    h.resize(k - 1);
    return h;
}

// Whether the axis-aligned rectangle meets the convex polygon (separating axes).
bool rectMeetsHull(double x0, double y0, double x1, double y1, const std::vector<P2>& hull) {
    if (hull.empty()) return false;
    double hx0 = hull[0].x, hx1 = hull[0].x, hy0 = hull[0].y, hy1 = hull[0].y;
    for (const P2& p : hull) {
        hx0 = std::min(hx0, p.x);
        hx1 = std::max(hx1, p.x);
        hy0 = std::min(hy0, p.y);
        hy1 = std::max(hy1, p.y);
    }
    if (hx1 < x0 || hx0 > x1 || hy1 < y0 || hy0 > y1) return false;
    const std::size_t n = hull.size();
    for (std::size_t i = 0; i < n && n >= 2; ++i) {
        const P2 a = hull[i], b = hull[(i + 1) % n];
        const double nx = -(b.y - a.y), ny = b.x - a.x;  // a normal of edge a-b
        const double c[4][2] = {{x0, y0}, {x1, y0}, {x1, y1}, {x0, y1}};
        double rmin = std::numeric_limits<double>::infinity(), rmax = -rmin;
        for (const auto& q : c) {
            const double d = nx * q[0] + ny * q[1];
            rmin = std::min(rmin, d);
            rmax = std::max(rmax, d);
        }
        double pmin = std::numeric_limits<double>::infinity(), pmax = -pmin;
        for (const P2& p : hull) {
            const double d = nx * p.x + ny * p.y;
            pmin = std::min(pmin, d);
            pmax = std::max(pmax, d);
        }
        if (rmax < pmin || rmin > pmax) return false;
    }
    return true;
}

// The ground hull of the frustum's part between heights lo and hi.
std::vector<P2> frustumHull(const Camera& camera, double lo, double hi, double farDepth) {
    const Intrinsics& in = camera.intrinsics();
    const glm::dvec3 eye = camera.pose().position;
    std::vector<glm::dvec3> v = {eye};
    const double cs[4][2] = {{0, 0},
                             {double(in.width), 0},
                             {double(in.width), double(in.height)},
                             {0, double(in.height)}};
    for (const auto& c : cs)  // the forward part of rayDirection is focal: depth farDepth
        v.push_back(eye + camera.rayDirection(c[0], c[1]) * (farDepth / in.focal));
    const int edges[8][2] = {{0, 1}, {0, 2}, {0, 3}, {0, 4}, {1, 2}, {2, 3}, {3, 4}, {4, 1}};
    std::vector<P2> pts;
    for (const glm::dvec3& p : v) {
        if (p.z >= lo && p.z <= hi) pts.push_back({p.x, p.y});
    }
    for (const auto& e : edges) {
        const glm::dvec3 a = v[e[0]], b = v[e[1]];
        for (const double z : {lo, hi}) {
            if ((a.z - z) * (b.z - z) < 0) {
                const double t = (z - a.z) / (b.z - a.z);
                pts.push_back({a.x + t * (b.x - a.x), a.y + t * (b.y - a.y)});
            }
        }
    }
    return convexHull(std::move(pts));
}

void addNodesAbove(const TerrainDbLayout& layout, const TileKey& key, std::set<TileKey>& out) {
    for (int j = std::max(key.level, 1); j < layout.nodeLevels(); ++j) {
        const int d = j - key.level;
        out.insert(TileKey{TileKind::Nodes, j, key.tx >> d, key.ty >> d});
    }
}

}  // namespace

LevelSelection LevelSelection::forCamera(const Intrinsics& intrinsics, const TerrainDbInfo& info,
                                         int coarseLevels) {
    LevelSelection s;
    s.coarseLevels = coarseLevels;
    s.d0 = intrinsics.lodFocal() * std::max(info.spacingX, info.spacingY);
    return s;
}

void LevelSelection::band(int level, int displayLevels, double& near, double& far) const {
    const double inf = std::numeric_limits<double>::infinity();
    const int top =
        coarseLevels < 0 ? displayLevels - 1 : std::min(coarseLevels, displayLevels - 1);
    near = inf;
    far = -inf;
    if (level > top) return;
    if (top == 0) {
        near = 0;
        far = inf;
        return;
    }
    if (level == 0) {
        near = 0;
        far = level0Reach * d0;
        return;
    }
    near = d0 * std::ldexp(1.0, level - 1);
    far = level == top ? inf : d0 * std::ldexp(1.0, level + 1);
}

std::size_t Footprint::count(TileKind kind, int level) const {
    return static_cast<std::size_t>(
        std::count_if(tiles.begin(), tiles.end(),
                      [&](const TileKey& k) { return k.kind == kind && k.level == level; }));
}

Footprint frameFootprint(const Camera& camera, const TerrainDbLayout& layout,
                         const TerrainDbInfo& info, const LevelSelection& selection,
                         double margin) {
    Footprint fp;
    const double lo = info.minRaw * info.heightScale + info.heightOffset - 1e-6;
    const double hi = info.maxRaw * info.heightScale + info.heightOffset + 1e-6;
    const double ex = (info.width - 1) * info.spacingX, ey = (info.height - 1) * info.spacingY;
    const glm::dvec3 eye = camera.pose().position;
    double farDepth = 1.0;
    for (const double x : {-margin, ex + margin})
        for (const double y : {-margin, ey + margin})
            for (const double z : {lo, hi})
                farDepth = std::max(farDepth, glm::length(glm::dvec3(x, y, z) - eye) * 1.001);
    const std::vector<P2> hull = frustumHull(camera, lo, hi, farDepth);
    if (hull.empty()) return fp;
    double hx0 = hull[0].x, hx1 = hx0, hy0 = hull[0].y, hy1 = hy0;
    for (const P2& p : hull) {
        hx0 = std::min(hx0, p.x);
        hx1 = std::max(hx1, p.x);
        hy0 = std::min(hy0, p.y);
        hy1 = std::max(hy1, p.y);
    }
    const int t = layout.tileSize();
    for (int k = 0; k < layout.displayLevels(); ++k) {
        double near, far;
        selection.band(k, layout.displayLevels(), near, far);
        if (!(near < far)) continue;
        // Tile (tx, ty) spans level-0 samples [tx T 2^k, (tx + 1) T 2^k], clipped to the map.
        const double tw = std::ldexp(static_cast<double>(t), k) * info.spacingX;
        const double th = std::ldexp(static_cast<double>(t), k) * info.spacingY;
        const int nx = layout.tilesX(TileKind::Display, k),
                  ny = layout.tilesY(TileKind::Display, k);
        // The hull's box, within the band's far distance of the eye: a tile farther along x or
        // y is farther than `far` (on a large map the hull reaches its edge, and level 0 alone
        // would otherwise visit every one of its tiles).
        double bx0 = hx0, bx1 = hx1, by0 = hy0, by1 = hy1;
        if (std::isfinite(far)) {
            bx0 = std::max(bx0, eye.x - far);
            bx1 = std::min(bx1, eye.x + far);
            by0 = std::max(by0, eye.y - far);
            by1 = std::min(by1, eye.y + far);
            if (!(bx0 <= bx1 && by0 <= by1)) continue;
        }
        const int tx0 = std::clamp(static_cast<int>(std::floor((bx0 - margin) / tw)), 0, nx - 1);
        const int tx1 = std::clamp(static_cast<int>(std::floor((bx1 + margin) / tw)), 0, nx - 1);
        const int ty0 = std::clamp(static_cast<int>(std::floor((by0 - margin) / th)), 0, ny - 1);
        const int ty1 = std::clamp(static_cast<int>(std::floor((by1 + margin) / th)), 0, ny - 1);
        for (int ty = ty0; ty <= ty1; ++ty) {
            for (int tx = tx0; tx <= tx1; ++tx) {
                const double x0 = tx * tw - margin, x1 = std::min((tx + 1) * tw, ex) + margin;
                const double y0 = ty * th - margin, y1 = std::min((ty + 1) * th, ey) + margin;
                const double dx = std::max({x0 - eye.x, 0.0, eye.x - x1});
                const double dy = std::max({y0 - eye.y, 0.0, eye.y - y1});
                const double dmin = std::sqrt(dx * dx + dy * dy);
                const double mx = std::max(std::abs(eye.x - x0), std::abs(eye.x - x1));
                const double my = std::max(std::abs(eye.y - y0), std::abs(eye.y - y1));
                const double dmax = std::sqrt(mx * mx + my * my);
                if (dmax < near || dmin >= far) continue;
                if (!rectMeetsHull(x0, y0, x1, y1, hull)) continue;
                const TileKey key{TileKind::Display, k, tx, ty};
                fp.tiles.insert(key);
                addNodesAbove(layout, key, fp.tiles);
            }
        }
    }
    return fp;
}

Footprint extendedFootprint(const Camera& camera, const TerrainDbLayout& layout,
                            const TerrainDbInfo& info, const LevelSelection& selection,
                            const glm::dvec3& velocity, double yawRate, double lookahead,
                            double step, double margin) {
    Footprint fp = frameFootprint(camera, layout, info, selection, margin);
    if (!(step > 0) || !(lookahead > 0)) return fp;
    for (double t = step; t <= lookahead + 1e-9; t += step) {
        Pose p = camera.pose();
        p.position += velocity * t;
        p.yaw += yawRate * t;
        const Footprint more =
            frameFootprint(Camera(p, camera.intrinsics()), layout, info, selection, margin);
        fp.tiles.insert(more.tiles.begin(), more.tiles.end());
    }
    return fp;
}

}  // namespace ig
