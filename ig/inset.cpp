#include "ig/inset.hpp"

#include "base/check.hpp"
#include "ig/appearance.hpp"
#include "ig/caster_impl.hpp"
#include "ig/error.hpp"
#include "ig/lighting_pass.hpp"
#include "ig/near_clip.hpp"
#include "ig/surface_hit.hpp"
#include "ig/synthetic.hpp"

#include <tbb/combinable.h>
#include <tbb/parallel_for.h>
#include <glm/geometric.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <string>
#include <utility>

namespace ig {

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr int kSkirtCells = kInsetSkirtCells;

bool isPowerOfTwo(int n) {
    return n > 0 && (n & (n - 1)) == 0;
}

// Bilinear value at fractional sample (gx, gy) of a row-major grid `at(ix, iy)` of w x h.
template <typename At>
double bilinearAt(int w, int h, double gx, double gy, At at) {
    const int ix = std::clamp(static_cast<int>(std::floor(gx)), 0, w - 2);
    const int iy = std::clamp(static_cast<int>(std::floor(gy)), 0, h - 2);
    const double fx = gx - ix, fy = gy - iy;
    return (at(ix, iy) * (1.0 - fx) + at(ix + 1, iy) * fx) * (1.0 - fy) +
           (at(ix, iy + 1) * (1.0 - fx) + at(ix + 1, iy + 1) * fx) * fy;
}

std::uint16_t toRaw(double v) {
    return static_cast<std::uint16_t>(std::clamp(std::lround(v), 0L, 65535L));
}

std::uint8_t toByte(double v) {
    return static_cast<std::uint8_t>(std::clamp(std::lround(v), 0L, 255L));
}

// Checks `src` against the global grid and returns its placement (x1, y1); throws InputError.
std::pair<int, int> checkPlacement(const GlobalGrid& global, const InsetSource& src) {
    const std::string& n = src.name;
    if (!isPowerOfTwo(src.factor) || src.factor < 2 || src.factor > 256) {
        throw InputError(n + ": refinement factor " + std::to_string(src.factor) +
                         " must be a power of two from 2 to 256");
    }
    const TerrainMap& f = src.fine;
    if (f.width() < 2 || f.height() < 2) throw InputError(n + ": the map is empty");
    if ((f.width() - 1) % src.factor != 0 || (f.height() - 1) % src.factor != 0) {
        throw InputError(n + ": " + std::to_string(f.width()) + " x " + std::to_string(f.height()) +
                         " samples do not span whole global cells " + "at factor " +
                         std::to_string(src.factor) + " (need cells * factor + 1)");
    }
    const double sx = global.spacingX / src.factor, sy = global.spacingY / src.factor;
    if (std::abs(f.spacingX() - sx) > 1e-9 * sx || std::abs(f.spacingY() - sy) > 1e-9 * sy) {
        throw InputError(n + ": spacing " + std::to_string(f.spacingX()) + " x " +
                         std::to_string(f.spacingY()) + " m is not the global spacing / " +
                         std::to_string(src.factor) + " (" + std::to_string(sx) + " m)");
    }
    const int x1 = src.x0 + (f.width() - 1) / src.factor;
    const int y1 = src.y0 + (f.height() - 1) / src.factor;
    if (src.x0 < 0 || src.y0 < 0 || x1 > global.width - 1 || y1 > global.height - 1) {
        throw InputError(n + ": global cells [" + std::to_string(src.x0) + ", " +
                         std::to_string(x1) + ") x [" + std::to_string(src.y0) + ", " +
                         std::to_string(y1) + ") lie outside the global map's " +
                         std::to_string(global.width - 1) + " x " +
                         std::to_string(global.height - 1) + " cells");
    }
    return {x1, y1};
}

// The map's extent in global samples: the inset's own plus the skirt, clamped to the map.
void mapExtent(const GlobalGrid& g, const Inset& in, int& mapX1, int& mapY1) {
    mapX1 = std::min(in.x1 + kSkirtCells, g.width - 1);
    mapY1 = std::min(in.y1 + kSkirtCells, g.height - 1);
}

}  // namespace

bool Inset::covers(double x, double y) const {
    return x >= coverMin.x && y >= coverMin.y && x <= coverMax.x && y <= coverMax.y;
}

GlobalGrid GlobalGrid::of(const TerrainMap& map) {
    return {map.width(),    map.height(),      map.spacingX(),
            map.spacingY(), map.heightScale(), map.heightOffset()};
}

InsetNesting::InsetNesting(const GlobalGrid& grid, std::vector<InsetSource> sources, int blendCells)
    : grid_(grid), sources_(std::move(sources)), blendCells_(blendCells) {
    if (grid_.width < 2 || grid_.height < 2) {
        throw InputError("insets: the global map is empty");
    }
    if (blendCells < 0) {
        throw InputError("insets: blend width " + std::to_string(blendCells) +
                         " cells must be 0 or more");
    }
    const double scale = grid_.heightScale, offset = grid_.heightOffset;
    for (InsetSource& src : sources_) {
        if (src.name.empty()) src.name = "inset " + std::to_string(placed_.size() + 1);
        const auto [x1, y1] = checkPlacement(grid_, src);
        for (const Inset& other : placed_) {
            // A global cell at least between them: each lowers samples of its own only.
            if (src.x0 <= other.x1 && x1 >= other.x0 && src.y0 <= other.y1 && y1 >= other.y0) {
                throw InputError(src.name + ": overlaps or touches " + other.name +
                                 " (insets must be at least one global cell apart)");
            }
        }
        // The fine heights in the global quantisation.
        const TerrainMap& f = src.fine;
        std::vector<std::uint16_t> raw(static_cast<std::size_t>(f.width()) * f.height());
        for (int v = 0; v < f.height(); ++v) {
            for (int u = 0; u < f.width(); ++u) {
                const double q = (f.heightAt(u, v) - offset) / scale;
                if (!(q >= -0.5 && q < 65535.5)) {
                    throw InputError(
                        src.name + ": height " + std::to_string(f.heightAt(u, v)) +
                        " m at sample (" + std::to_string(u) + ", " + std::to_string(v) +
                        ") is outside the global map's height range (" + std::to_string(offset) +
                        " to " + std::to_string(offset + 65535.0 * scale) + " m)");
                }
                raw[static_cast<std::size_t>(v) * f.width() + u] = toRaw(q);
            }
        }
        Inset in;
        in.name = src.name;
        in.x0 = src.x0;
        in.y0 = src.y0;
        in.x1 = x1;
        in.y1 = y1;
        in.factor = src.factor;
        in.coverMin = {in.x0 * grid_.spacingX, in.y0 * grid_.spacingY};
        in.coverMax = {x1 * grid_.spacingX, y1 * grid_.spacingY};
        in.mapX0 = std::max(in.x0 - kSkirtCells, 0);
        in.mapY0 = std::max(in.y0 - kSkirtCells, 0);
        in.origin = {in.mapX0 * grid_.spacingX, in.mapY0 * grid_.spacingY};
        placed_.push_back(std::move(in));
        fineRaw_.push_back(std::move(raw));
    }
    for (std::size_t k = 0; k < placed_.size(); ++k) {
        const Inset& in = placed_[k];
        const std::vector<std::uint16_t>& raw = fineRaw_[k];
        const int fw = sources_[k].fine.width(), fac = in.factor;
        // The global samples over the inset: the least fine sample of the global cells each
        // spans inside the inset, so the global bilinear surface stays under the inset's.
        InsetLowering low;
        low.x0 = in.x0;
        low.y0 = in.y0;
        low.x1 = in.x1;
        low.y1 = in.y1;
        low.raw.reserve(static_cast<std::size_t>(in.x1 - in.x0 + 1) * (in.y1 - in.y0 + 1));
        for (int j = in.y0; j <= in.y1; ++j) {
            const int v0 = (std::max(j - 1, in.y0) - in.y0) * fac;
            const int v1 = (std::min(j + 1, in.y1) - in.y0) * fac;
            for (int i = in.x0; i <= in.x1; ++i) {
                const int u0 = (std::max(i - 1, in.x0) - in.x0) * fac;
                const int u1 = (std::min(i + 1, in.x1) - in.x0) * fac;
                std::uint16_t m = 65535;
                for (int v = v0; v <= v1; ++v) {
                    const std::uint16_t* row = raw.data() + static_cast<std::size_t>(v) * fw;
                    m = std::min(m, *std::min_element(row + u0, row + u1 + 1));
                }
                low.raw.push_back(m);
            }
        }
        lowerings_.push_back(std::move(low));
    }
}

void InsetNesting::lowerRows(int y0, int rows, std::uint16_t* heights) const {
    for (const InsetLowering& low : lowerings_) {
        const int a = std::max(y0, low.y0), b = std::min(y0 + rows - 1, low.y1);
        const int lw = low.x1 - low.x0 + 1;
        for (int j = a; j <= b; ++j) {
            std::copy_n(low.raw.data() + static_cast<std::size_t>(j - low.y0) * lw, lw,
                        heights + static_cast<std::size_t>(j - y0) * grid_.width + low.x0);
        }
    }
}

void InsetNesting::window(std::size_t k, int& x0, int& y0, int& x1, int& y1) const {
    const Inset& in = placed_[k];
    mapExtent(grid_, in, x1, y1);
    x0 = in.mapX0;
    y0 = in.mapY0;
    // The bilinear reads at the map's far samples take the next global sample where there is one.
    x1 = std::min(x1 + 1, grid_.width - 1);
    y1 = std::min(y1 + 1, grid_.height - 1);
}

Inset InsetNesting::nest(std::size_t k, const TerrainMap& lowered, int ox, int oy,
                         std::uint16_t floorRaw) const {
    Inset in = placed_[k];
    const TerrainMap& f = sources_[k].fine;
    const std::vector<std::uint16_t>& raw = fineRaw_[k];
    const int fw = f.width(), fh = f.height(), fac = in.factor;
    const int gw = grid_.width, gh = grid_.height;
    {
        int wx0, wy0, wx1, wy1;
        window(k, wx0, wy0, wx1, wy1);
        CHECK(ox <= wx0 && oy <= wy0 && wx1 - ox < lowered.width() && wy1 - oy < lowered.height())
            << "the window does not cover " << in.name;
    }
    auto rawAt = [&](int x, int y) { return lowered.raw(x - ox, y - oy); };
    auto colorAt = [&](int x, int y) { return lowered.colorAt(x - ox, y - oy); };
    // The inset's map: the fine samples, their outer `blendCells` cells blended toward the
    // (lowered) global surface and colours, inside a skirt of the global surface (samples
    // rounded up, so it stays on or over the global one), its box reaching down to the
    // global floor. The eye is then never under the box, which the fast caster's vertical
    // coherence needs (a ray entering the box from below breaks the chain of starts up its
    // column), and a ray enters the map over the skirt, never through the side of the
    // inset's own data: one that meets the skirt, or its side, has met the global surface
    // there as near or nearer, so the composite keeps the global hit.
    int mapX1, mapY1;
    mapExtent(grid_, in, mapX1, mapY1);
    const int sx = (in.x0 - in.mapX0) * fac, sy = (in.y0 - in.mapY0) * fac;
    const int mw = (mapX1 - in.mapX0) * fac + 1, mh = (mapY1 - in.mapY0) * fac + 1;
    const double scale = grid_.heightScale, offset = grid_.heightOffset;
    in.map = TerrainMap(mw, mh, f.spacingX(), f.spacingY(), scale, offset);
    const double inv = 1.0 / fac;
    for (int mv = 0; mv < mh; ++mv) {
        for (int mu = 0; mu < mw; ++mu) {
            const int u = mu - sx, v = mv - sy;  // fine sample, when inside
            const bool inside = u >= 0 && v >= 0 && u < fw && v < fh;
            const int b = inside ? std::min({u, v, fw - 1 - u, fh - 1 - v}) : -1;
            double h = inside ? raw[static_cast<std::size_t>(v) * fw + u] : 0.0;
            Rgb8 c = inside ? f.colorAt(u, v) : Rgb8{};
            if (b < blendCells_) {
                const double t = b < 0 ? 0.0 : static_cast<double>(b) / blendCells_;
                const double w = t * t * (3.0 - 2.0 * t);
                const double gx = in.mapX0 + mu * inv, gy = in.mapY0 + mv * inv;
                const double g0 = bilinearAt(
                    gw, gh, gx, gy, [&](int x, int y) { return static_cast<double>(rawAt(x, y)); });
                // Rounded up: the inset stays on or over the global surface (the fine
                // samples are at least the lowered global ones around them).
                h = std::ceil(w * h + (1.0 - w) * g0 - 1e-9);
                double rgb[3];
                for (int ch = 0; ch < 3; ++ch) {
                    const double g = bilinearAt(gw, gh, gx, gy, [&](int x, int y) {
                        const Rgb8 gc = colorAt(x, y);
                        return static_cast<double>(ch == 0 ? gc.r : ch == 1 ? gc.g : gc.b);
                    });
                    const double own = ch == 0 ? c.r : ch == 1 ? c.g : c.b;
                    rgb[ch] = w * own + (1.0 - w) * g;
                }
                c = Rgb8{toByte(rgb[0]), toByte(rgb[1]), toByte(rgb[2])};
            }
            in.map.setRaw(mu, mv, toRaw(h));
            in.map.setColor(mu, mv, c);
        }
    }
    in.map.updateRange();
    in.map.extendFloor(floorRaw * scale + offset);
    return in;
}

NestedTerrain::NestedTerrain(TerrainMap global, std::vector<InsetSource> sources, int blendCells)
    : global_(std::move(global)) {
    const InsetNesting nesting(GlobalGrid::of(global_), std::move(sources), blendCells);
    for (const InsetLowering& low : nesting.lowerings()) {
        std::size_t i = 0;
        for (int j = low.y0; j <= low.y1; ++j) {
            for (int x = low.x0; x <= low.x1; ++x)
                global_.setRaw(x, j, low.raw[i++]);
        }
    }
    // The lowest global sample: the floor of every inset's map.
    const std::uint16_t floorRaw =
        *std::min_element(global_.rawHeights().begin(), global_.rawHeights().end());
    for (std::size_t k = 0; k < nesting.size(); ++k)
        insets_.push_back(nesting.nest(k, global_, 0, 0, floorRaw));
    global_.updateRange();
}

void checkNestedInsets(const GlobalGrid& g, std::span<const Inset> insets,
                       std::span<const TerrainMap* const> maps) {
    CHECK(insets.size() == maps.size());
    for (std::size_t k = 0; k < insets.size(); ++k) {
        const Inset& in = insets[k];
        const std::string& n = in.name;
        if (!isPowerOfTwo(in.factor) || in.factor < 2 || in.factor > 256 || in.x0 < 0 ||
            in.y0 < 0 || in.x1 <= in.x0 || in.y1 <= in.y0 || in.x1 > g.width - 1 ||
            in.y1 > g.height - 1 || in.mapX0 != std::max(in.x0 - kSkirtCells, 0) ||
            in.mapY0 != std::max(in.y0 - kSkirtCells, 0)) {
            throw InputError(n + ": placement out of the global map or its rules");
        }
        int mapX1, mapY1;
        mapExtent(g, in, mapX1, mapY1);
        const int mw = (mapX1 - in.mapX0) * in.factor + 1;
        const int mh = (mapY1 - in.mapY0) * in.factor + 1;
        const TerrainMap& m = *maps[k];
        if (m.width() != mw || m.height() != mh) {
            throw InputError(n + ": map of " + std::to_string(m.width()) + " x " +
                             std::to_string(m.height()) + " samples, its placement needs " +
                             std::to_string(mw) + " x " + std::to_string(mh));
        }
        const double sx = g.spacingX / in.factor, sy = g.spacingY / in.factor;
        if (std::abs(m.spacingX() - sx) > 1e-9 * sx || std::abs(m.spacingY() - sy) > 1e-9 * sy ||
            m.heightScale() != g.heightScale || m.heightOffset() != g.heightOffset) {
            throw InputError(n + ": spacing or height quantisation is not the global map's " +
                             "at factor " + std::to_string(in.factor));
        }
        for (std::size_t o = 0; o < k; ++o) {
            const Inset& other = insets[o];
            if (in.x0 <= other.x1 && in.x1 >= other.x0 && in.y0 <= other.y1 && in.y1 >= other.y0) {
                throw InputError(n + ": overlaps or touches " + other.name);
            }
        }
    }
}

NestedTerrain NestedTerrain::fromNested(TerrainMap global, std::vector<Inset> insets) {
    NestedTerrain t;
    t.global_ = std::move(global);
    const GlobalGrid g = GlobalGrid::of(t.global_);
    std::vector<const TerrainMap*> maps;
    for (const Inset& in : insets)
        maps.push_back(&in.map);
    checkNestedInsets(g, insets, maps);
    for (Inset& in : insets) {
        in.coverMin = {in.x0 * g.spacingX, in.y0 * g.spacingY};
        in.coverMax = {in.x1 * g.spacingX, in.y1 * g.spacingY};
        in.origin = {in.mapX0 * g.spacingX, in.mapY0 * g.spacingY};
    }
    t.insets_ = std::move(insets);
    return t;
}

NestedMaps NestedTerrain::maps() const {
    NestedMaps m;
    m.global = &global_;
    for (const Inset& in : insets_)
        m.insets.push_back({&in, &in.map});
    return m;
}

double NestedTerrain::surfaceHeight(double x, double y) const {
    return maps().surfaceHeight(x, y);
}

RayHit NestedTerrain::intersect(const glm::dvec3& origin, const glm::dvec3& dir) const {
    return maps().intersect(origin, dir);
}

double NestedTerrain::entryBeyond(const glm::dvec3& origin, const glm::dvec3& dir, double ta,
                                  double tb) const {
    return maps().entryBeyond(origin, dir, ta, tb);
}

double NestedMaps::surfaceHeight(double x, double y) const {
    for (const Part& p : insets) {
        if (p.placement->covers(x, y)) {
            return p.map->surfaceHeight(x - p.placement->origin.x, y - p.placement->origin.y);
        }
    }
    return global->surfaceHeight(x, y);
}

RayHit NestedMaps::intersect(const glm::dvec3& origin, const glm::dvec3& dir) const {
    const glm::dvec3 d = glm::normalize(dir);
    RayHit best = intersectTerrain(*global, origin, d);
    for (const Part& p : insets) {
        const glm::dvec3 shift{p.placement->origin, 0.0};
        RayHit h = intersectTerrain(*p.map, origin - shift, d);
        if (h.hit && (!best.hit || h.distance <= best.distance)) {
            h.point += shift;
            best = h;
        }
    }
    return best;
}

double NestedMaps::entryBeyond(const glm::dvec3& origin, const glm::dvec3& dir, double ta,
                               double tb) const {
    double best = ig::entryBeyond(*global, TerrainRay(*global, origin, dir), ta, tb);
    for (const Part& p : insets) {
        const TerrainRay ray(*p.map, origin - glm::dvec3{p.placement->origin, 0.0}, dir);
        const double t = ig::entryBeyond(*p.map, ray, ta, tb);
        if (t >= 0.0 && (best < 0.0 || t <= best)) best = t;
    }
    return best;
}

TerrainMap NestedTerrain::fineEquivalent() const {
    int f = 1;
    for (const Inset& in : insets_)
        f = std::max(f, in.factor);
    const TerrainMap& g = global_;
    TerrainMap m((g.width() - 1) * f + 1, (g.height() - 1) * f + 1, g.spacingX() / f,
                 g.spacingY() / f, g.heightScale(), g.heightOffset());
    for (int v = 0; v < m.height(); ++v) {
        for (int u = 0; u < m.width(); ++u) {
            const Inset* own = nullptr;
            for (const Inset& in : insets_) {
                if (in.factor == f && u >= in.x0 * f && v >= in.y0 * f && u <= in.x1 * f &&
                    v <= in.y1 * f) {
                    own = &in;
                }
            }
            if (own) {
                const int lu = u - own->mapX0 * f, lv = v - own->mapY0 * f;
                m.setRaw(u, v, own->map.raw(lu, lv));
                m.setColor(u, v, own->map.colorAt(lu, lv));
                continue;
            }
            const double x = u * m.spacingX(), y = v * m.spacingY();
            const TerrainMap* src = &g;
            glm::dvec2 at{x, y};
            for (const Inset& in : insets_) {
                if (in.covers(x, y)) {
                    src = &in.map;
                    at -= in.origin;
                }
            }
            m.setRaw(u, v,
                     toRaw((src->surfaceHeight(at.x, at.y) - g.heightOffset()) / g.heightScale()));
            float rgb[3];
            src->surfaceColor(at.x, at.y, rgb);
            m.setColor(u, v, Rgb8{toByte(rgb[0]), toByte(rgb[1]), toByte(rgb[2])});
        }
    }
    m.updateRange();
    return m;
}

void NestedTerrain::applyRamp() {
    for (Inset& in : insets_)
        in.map.colors() = elevationRampAlbedo(in.map, global_);
    global_.colors() = elevationRampAlbedo(global_);
}

TerrainMap NestedTerrain::upperGround() const {
    TerrainMap g = global_;
    for (const Inset& in : insets_) {
        const int fac = in.factor;
        const int sx = (in.x0 - in.mapX0) * fac, sy = (in.y0 - in.mapY0) * fac;
        for (int j = in.y0; j <= in.y1; ++j) {
            const int v0 = sy + (std::max(j - 1, in.y0) - in.y0) * fac;
            const int v1 = sy + (std::min(j + 1, in.y1) - in.y0) * fac;
            for (int i = in.x0; i <= in.x1; ++i) {
                const int u0 = sx + (std::max(i - 1, in.x0) - in.x0) * fac;
                const int u1 = sx + (std::min(i + 1, in.x1) - in.x0) * fac;
                std::uint16_t m = 0;
                for (int v = v0; v <= v1; ++v) {
                    for (int u = u0; u <= u1; ++u)
                        m = std::max(m, in.map.raw(u, v));
                }
                g.setRaw(i, j, m);
            }
        }
    }
    g.updateRange();
    return g;
}

namespace {

// The columns [first, second) of `camera`'s image where the inset's box (its square, from the
// lowest of its and the global surface to its highest point) can show; the whole width when a
// corner lies behind the camera plane.
std::pair<int, int> insetColumns(const Camera& camera, const NestedMaps::Part& in, double low) {
    const int w = camera.intrinsics().width;
    const glm::dvec2 origin = in.placement->origin;
    const double z0 = std::min(low, in.map->minHeight()), z1 = in.map->maxHeight();
    double lo = kInf, hi = -kInf;
    for (const double x : {origin.x, origin.x + in.map->extentX()}) {
        for (const double y : {origin.y, origin.y + in.map->extentY()}) {
            for (const double z : {z0, z1}) {
                const auto p = camera.project({x, y, z});
                if (!p) return {0, w};
                lo = std::min(lo, p->x);
                hi = std::max(hi, p->x);
            }
        }
    }
    // A pixel's rays lie within it (supersampling stacks them vertically): one pixel of slack.
    const int first = static_cast<int>(std::clamp(std::floor(lo) - 1.0, 0.0, double(w)));
    const int last = static_cast<int>(std::clamp(std::ceil(hi) + 1.0, 0.0, double(w)));
    return {first, last};
}

}  // namespace

std::vector<RenderOptions> insetPassOptions(const NestedMaps& maps,
                                            const std::vector<RenderOptions>& insetOptions) {
    CHECK(insetOptions.size() == maps.insets.size());
    std::vector<RenderOptions> out;
    out.reserve(insetOptions.size());
    for (std::size_t k = 0; k < insetOptions.size(); ++k) {
        // Each map lit by its own normals (the lighting pass runs on each pass's frame).
        RenderOptions o = insetOptions[k];
        o.objects.clear();
        if (o.lighting) {
            auto lit = std::make_shared<SunLighting>(*o.lighting);
            lit->normals = std::make_shared<const TerrainNormals>(*maps.insets[k].map);
            o.lighting = std::move(lit);
        }
        out.push_back(std::move(o));
    }
    return out;
}

namespace {

class NestedCaster final : public Caster {
  public:
    NestedCaster(CasterKind kind, const NestedMaps& maps, const RenderOptions& options,
                 const std::vector<RenderOptions>& insetOptions)
        : maps_(maps), options_(options) {
        CHECK(insetOptions.size() == maps.insets.size());
        if (kind == CasterKind::Span) {
            throw InputError(
                "insets: the span caster does not draw insets (use fast, naive or "
                "reference)");
        }
        // The objects are drawn by the global pass (their layer is over the global grid; they
        // stand on the nested surface, over the lowered global one), and the composite hides
        // them where an inset's surface lies nearer.
        global_ = makeCaster(kind, *maps.global, options);
        const std::vector<RenderOptions> own = insetPassOptions(maps, insetOptions);
        for (std::size_t k = 0; k < maps.insets.size(); ++k)
            inner_.push_back(makeCaster(kind, *maps.insets[k].map, own[k]));
    }

    CasterKind kind() const override { return global_->kind(); }
    std::string_view kernelName() const override { return global_->kernelName(); }

    void render(const Camera& camera, RenderedFrame& frame) const override {
        UnitCounters counters;
        runWithThreads(options_.threads, [&] { renderAll(camera, frame, counters); });
        frame.stats.steps = counters.steps;
        frame.stats.restarts = counters.restarts;
        frame.stats.rays =
            static_cast<std::uint64_t>(camera.intrinsics().width) * camera.intrinsics().height;
    }
    // Every map's passes (near plane, height haze) run on its own frame before the composite.
    void finishFrame(const Camera&, RenderedFrame&) const override {}

    int workUnits(const Camera&) const override { return 1; }
    void renderUnit(const Camera& camera, RenderedFrame& frame, int unit,
                    UnitCounters& counters) const override {
        CHECK(unit == 0) << "a nested caster renders one unit";
        renderAll(camera, frame, counters);
    }

  private:
    // Renders the units of `caster` over `frame` whose columns meet [c0, c1) (all of a caster
    // whose units are rows), then its passes.
    static void renderColumns(const Caster& caster, const Camera& camera, RenderedFrame& frame,
                              int c0, int c1, UnitCounters& counters) {
        std::vector<int> units;
        const int n = caster.workUnits(camera);
        for (int u = 0; u < n; ++u) {
            const auto [a, b] = caster.unitColumns(camera, u);
            if ((a == 0 && b == 0) || (a < c1 && b > c0)) units.push_back(u);
        }
        tbb::combinable<UnitCounters> local;
        tbb::parallel_for(0, static_cast<int>(units.size()), [&](int i) {
            caster.renderUnit(camera, frame, units[i], local.local());
        });
        local.combine_each([&](const UnitCounters& c) {
            counters.steps += c.steps;
            counters.restarts += c.restarts;
        });
        caster.finishFrame(camera, frame);
    }

    void renderAll(const Camera& camera, RenderedFrame& frame, UnitCounters& counters) const {
        const Intrinsics& intr = camera.intrinsics();
        // The global caster's units draw the objects over their columns into the id image.
        if (options_.objects.empty()) {
            frame.objectId.clear();
        } else {
            frame.objectId.assign(static_cast<std::size_t>(intr.width) * intr.height, 0);
        }
        renderColumns(*global_, camera, frame, 0, intr.width, counters);
        for (std::size_t k = 0; k < maps_.insets.size(); ++k) {
            const NestedMaps::Part& in = maps_.insets[k];
            const auto [c0, c1] = insetColumns(camera, in, maps_.global->minHeight());
            if (c0 >= c1) continue;
            Pose pose = camera.pose();
            pose.position -= glm::dvec3{in.placement->origin, 0.0};
            const Camera local(pose, intr);
            RenderedFrame part;
            part.intrinsics = intr;
            part.pose = pose;
            part.nearM = frame.nearM;
            part.time = frame.time;  // the sun's
            part.color.resize(frame.color.size());
            part.depth.assign(frame.depth.size(), std::numeric_limits<float>::infinity());
            renderColumns(*inner_[k], local, part, c0, c1, counters);
            // The nearer surface, pixel by pixel (ties to the inset: its surface is the finer;
            // an object is nearer than the surface it stands on).
            const bool ids = !frame.objectId.empty();
            for (int y = 0; y < intr.height; ++y) {
                const std::size_t row = static_cast<std::size_t>(y) * intr.width;
                for (std::size_t i = row + c0; i < row + c1; ++i) {
                    if (part.depth[i] <= frame.depth[i] &&
                        !(ids && frame.objectId[i] != 0 && part.depth[i] == frame.depth[i])) {
                        frame.depth[i] = part.depth[i];
                        frame.color[i] = part.color[i];
                        if (ids) frame.objectId[i] = 0;
                    }
                }
            }
        }
    }

  public:
    const Caster& globalPass() const { return *global_; }

  private:
    NestedMaps maps_;
    RenderOptions options_;
    std::unique_ptr<Caster> global_;
    std::vector<std::unique_ptr<Caster>> inner_;
};

}  // namespace

const Caster* nestedGlobalCaster(const Caster& caster) {
    const auto* nested = dynamic_cast<const NestedCaster*>(&caster);
    return nested ? &nested->globalPass() : nullptr;
}

std::unique_ptr<Caster> makeNestedCaster(CasterKind kind, const NestedTerrain& terrain,
                                         const RenderOptions& options) {
    if (options.pyramid || options.slopes) {
        throw InputError("insets: a paged map's pyramid is its own (use the maps' overload)");
    }
    return std::make_unique<NestedCaster>(
        kind, terrain.maps(), options,
        std::vector<RenderOptions>(terrain.insets().size(), options));
}

std::unique_ptr<Caster> makeNestedCaster(CasterKind kind, const NestedMaps& maps,
                                         const RenderOptions& globalOptions,
                                         const std::vector<RenderOptions>& insetOptions) {
    return std::make_unique<NestedCaster>(kind, maps, globalOptions, insetOptions);
}

RenderedFrame renderNestedFrame(const Caster& caster, const NestedTerrain& terrain,
                                const Pose& pose, const Intrinsics& intrinsics, double time,
                                std::uint64_t sequence, double nearM) {
    return renderNestedFrame(caster, terrain.maps(), pose, intrinsics, time, sequence, nearM);
}

RenderedFrame renderNestedFrame(const Caster& caster, const NestedMaps& terrain, const Pose& pose,
                                const Intrinsics& intrinsics, double time, std::uint64_t sequence,
                                double nearM) {
    checkNearPlane(nearM);
    validateNestedView(terrain, pose, intrinsics);
    RenderedFrame frame = newFrame(*terrain.global, pose, intrinsics, time, sequence);
    frame.nearM = nearM;
    const Camera camera(pose, intrinsics);
    renderPixels(caster, camera, frame);
    castNestedControlPoints(terrain, camera, frame);
    return frame;
}

void validateNestedView(const NestedMaps& terrain, const Pose& pose, const Intrinsics& intrinsics) {
    for (const NestedMaps::Part& part : terrain.insets) {
        const Inset& in = *part.placement;
        const glm::dvec3& p = pose.position;
        if (in.covers(p.x, p.y) && p.z <= terrain.surfaceHeight(p.x, p.y)) {
            throw InputError("pose: camera at z = " + std::to_string(p.z) +
                             " m is on or below the surface of " + in.name + " (" +
                             std::to_string(terrain.surfaceHeight(p.x, p.y)) + " m)");
        }
    }
    validateView(*terrain.global, pose, intrinsics);
}

void castNestedControlPoints(const NestedMaps& terrain, const Camera& camera,
                             RenderedFrame& frame) {
    const glm::dvec3& eye = camera.pose().position;
    const auto pixels = controlPointPixels(camera.intrinsics());
    for (int i = 0; i < kControlPointCount; ++i) {
        const glm::dvec3 dir = glm::normalize(camera.rayDirection(pixels[i].x, pixels[i].y));
        frame.controlPoints[i].pixel = pixels[i];
        if (frame.nearM > 0.0) {
            const double t =
                terrain.entryBeyond(eye, dir, nearPlaneRange(camera, dir, frame.nearM), kInf);
            frame.controlPoints[i].world =
                t >= 0.0 ? glm::dvec4{eye + t * dir, 1.0} : glm::dvec4{dir, 0.0};
            continue;
        }
        const RayHit hit = terrain.intersect(eye, dir);
        frame.controlPoints[i].world = hit.hit ? glm::dvec4{hit.point, 1.0} : glm::dvec4{dir, 0.0};
    }
}

InsetSource syntheticInset(std::uint64_t seed, double spacing, int x0, int y0, int cellsX,
                           int cellsY, int factor) {
    InsetSource src;
    src.x0 = x0;
    src.y0 = y0;
    src.factor = factor;
    if (!isPowerOfTwo(factor) || factor < 2 || factor > 256 || cellsX < 1 || cellsY < 1 || x0 < 0 ||
        y0 < 0) {
        throw InputError(
            "synthetic inset: cells must be positive, the corner not negative and "
            "the factor a power of two from 2 to 256");
    }
    const double fine = spacing / factor;
    const long long need =
        std::max(static_cast<long long>(x0 + cellsX), static_cast<long long>(y0 + cellsY)) *
            factor +
        1;
    long long size = 2;
    while (size < need)
        size *= 2;
    if (size > kMaxSyntheticStreamSize) {
        throw InputError("synthetic inset: the finer map would need " + std::to_string(size) +
                         " samples a side, more than the generator's " +
                         std::to_string(kMaxSyntheticStreamSize));
    }
    const int n = static_cast<int>(size);
    const int w = cellsX * factor + 1, h = cellsY * factor + 1;
    const int j0 = y0 * factor, u0 = x0 * factor;
    src.fine = TerrainMap(w, h, fine, fine, kSyntheticHeightScale, kSyntheticHeightOffset);
    generateSyntheticWindow(n, seed, fine, u0, u0 + w, j0, j0 + h, src.fine.rawHeights().data(),
                            src.fine.colors().data());
    src.fine.updateRange();
    src.name = "synthetic inset at cell (" + std::to_string(x0) + ", " + std::to_string(y0) + ")";
    return src;
}

}  // namespace ig
