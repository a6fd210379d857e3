// Span renderer: cost per terrain sample, not per pixel. See docs/design/span_renderer.md.
//
// The frame is drawn on a vertical image plane (the same eye, heading and focal length, no
// pitch): each of its columns is a vertical plane through the eye, in which the height field is
// drawn exactly front to back with a y-buffer. The column's ground line is sampled at the major
// grid lines of the display level that matches the distance (the multiresolution caster's bands
// and blend), at minor grid-line crossings on level 0, and the rows between the y-buffer and a
// sample's projection are filled by intersecting each row's ray with the straight segment
// between consecutive samples (the surface is piecewise linear along the column, exact on the
// grid lines). The rows of the vertical plane are not its own pixel rows but the pitched image's
// rows: a rotation about the camera's horizontal axis maps rows to rows, so each output row has
// one elevation per vertical column and only a horizontal resample remains (linear, a copy at
// pitch 0: ig/span_resample.cpp). Where that stretch is too large (steep views) the frame goes
// to the fast caster.
#include "base/check.hpp"
#include "ig/caster_impl.hpp"
#include "ig/error.hpp"
#include "ig/near_clip.hpp"
#include "ig/object_pass.hpp"
#include "ig/pyramid.hpp"
#include "ig/shading.hpp"
#include "ig/span_resample.hpp"

#include <tbb/combinable.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

namespace ig {

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

// Per-frame geometry shared by all columns.
struct SpanFrame {
    int width = 0, height = 0;  // output image
    int columns = 0;            // vertical-plane columns
    double focal = 0.0, cx = 0.0;
    double lodFocal = 0.0;          // Intrinsics::lodFocal: where the levels begin
    double half = 0.0;              // columns / 2
    std::vector<double> up;         // per output row: elevation offset in vertical-plane px
    std::vector<double> stretch;    // per output row: vertical-plane columns per output px
    std::vector<int> rowLo, rowHi;  // per column: rows the resample reads (inclusive)
    glm::dvec3 eye{0.0};
    double headingX = 0.0, headingY = 0.0;  // unit heading
    double rightX = 0.0, rightY = 0.0;      // unit right, horizontal
};

// Fractional vertical-plane column read for output pixel x of a row with the given stretch.
inline double columnAt(const SpanFrame& sf, int x, double stretch) {
    return (x + 0.5 - sf.cx) * stretch + sf.half - 0.5;
}

// Per-frame buffers (column-major colour and depth), reused across frames.
struct SpanBuffers {
    std::vector<std::uint32_t> color;
    std::vector<float> depth;
};
// Per-thread scratch of the resample: a strip of plane rows, row-major.
struct SpanScratch {
    std::vector<std::uint32_t> color;
    std::vector<float> depth;
};

inline std::uint32_t pack(Rgb8 c) {
    return static_cast<std::uint32_t>(c.r) | static_cast<std::uint32_t>(c.g) << 8 |
           static_cast<std::uint32_t>(c.b) << 16;
}

// floor() of a double as an integer, without the library call a generic x86-64 build makes.
inline long floorL(double x) {
    const long i = static_cast<long>(x);
    return i - (x < static_cast<double>(i));
}

// Cell and weights of display level `l` at its own grid coordinates, clamped to its edge.
struct BilinearAt {
    std::size_t i00, i01;
    double fx, fy;
};
inline BilinearAt bilinearAt(const PyramidLevel& l, double gx, double gy) {
    const double x = std::clamp(gx, 0.0, l.width - 1.0), y = std::clamp(gy, 0.0, l.height - 1.0);
    const int ix = std::min(static_cast<int>(x), l.width - 2);
    const int iy = std::min(static_cast<int>(y), l.height - 2);
    const std::size_t i00 = l.index(ix, iy);
    return {i00, i00 + static_cast<std::size_t>(l.width), x - ix, y - iy};
}
// Bilinear height, raw units.
inline double bilinearHeight(const PyramidLevel& l, const BilinearAt& p) {
    const double h0 = l.heights[p.i00] + p.fx * (l.heights[p.i00 + 1] - l.heights[p.i00]);
    const double h1 = l.heights[p.i01] + p.fx * (l.heights[p.i01 + 1] - l.heights[p.i01]);
    return h0 + p.fy * (h1 - h0);
}
// Bilinear colour, 0..255 per channel.
inline void bilinearColor(const PyramidLevel& l, const BilinearAt& p, float rgb[3]) {
    const Rgb8 c00 = l.colors[p.i00], c10 = l.colors[p.i00 + 1], c01 = l.colors[p.i01],
               c11 = l.colors[p.i01 + 1];
    const float fx = static_cast<float>(p.fx), fy = static_cast<float>(p.fy);
    auto mix = [fx, fy](float a, float b, float c, float d) {
        const float u = a + fx * (b - a), v = c + fx * (d - c);
        return u + fy * (v - u);
    };
    rgb[0] = mix(c00.r, c10.r, c01.r, c11.r);
    rgb[1] = mix(c00.g, c10.g, c01.g, c11.g);
    rgb[2] = mix(c00.b, c10.b, c01.b, c11.b);
}

// A sample's colour, worked out only when the sample draws a row: linear between two samples
// `a`, `b` of level `l` (weight fr toward b), blended toward level `l1` (bilinear at p1) by w.
struct ColorSource {
    const PyramidLevel* l = nullptr;  // nullptr: rgb holds the colour
    std::size_t a = 0, b = 0;
    float fr = 0.0f;
    const PyramidLevel* l1 = nullptr;
    float w = 0.0f;
    BilinearAt p1{};
    float rgb[3] = {0.0f, 0.0f, 0.0f};

    void resolve() {
        if (!l) return;
        const Rgb8 ca = l->colors[a], cb = l->colors[b];
        rgb[0] = ca.r + (cb.r - ca.r) * fr;
        rgb[1] = ca.g + (cb.g - ca.g) * fr;
        rgb[2] = ca.b + (cb.b - ca.b) * fr;
        if (l1) {
            float c1[3];
            bilinearColor(*l1, p1, c1);
            for (int i = 0; i < 3; ++i)
                rgb[i] += (c1[i] - rgb[i]) * w;
        }
        l = nullptr;
    }
};

// A straight segment of the surface along a column between two samples (ground distance, height
// over the eye, colour 0..255 per channel).
struct SpanSegment {
    float pd, ph, d, h;
    float ca[3], cb[3];
};

// Fills rows yb, yb - 1, ... down to yLo while the row's ray passes under the segment's far
// end (up[y] d <= lim, the y-buffer test, in double): each row's ray meets the segment at
// w = (t pd - ph) / ((t pd - ph) - (t d - h)) with t = up[y] / L (one division), which gives its
// colour (linear between the ends) and its distance ((pd + w (d - pd)) sqrt(1 + t^2)). Returns
// the first row left unfilled.
inline int fillSegment(const SpanSegment& s, const double* __restrict__ up, int yb, int yLo,
                       double d, double lim, float invL, std::uint32_t* __restrict__ color,
                       float* __restrict__ depth) {
    // Colours biased by one half (rounding to nearest by truncation), with the differences.
    const float r0 = s.ca[0] + 0.5f, g0 = s.ca[1] + 0.5f, b0 = s.ca[2] + 0.5f;
    const float dr = s.cb[0] - s.ca[0], dg = s.cb[1] - s.ca[1], db = s.cb[2] - s.ca[2];
    const float dd = s.d - s.pd, dh = s.h - s.ph;
    do {
        const float t = static_cast<float>(up[yb]) * invL;
        const float ga = t * s.pd - s.ph;
        const float den = dh - t * dd;  // ga - (t d - h)
        const float w = den > 0.0f ? std::clamp(ga / den, 0.0f, 1.0f) : 1.0f;
        depth[yb] = (s.pd + w * dd) * std::sqrt(1.0f + t * t);
        // Every colour is a convex mix of 0..255 values: no clamp.
        color[yb] = static_cast<std::uint32_t>(r0 + dr * w) |
                    static_cast<std::uint32_t>(g0 + dg * w) << 8 |
                    static_cast<std::uint32_t>(b0 + db * w) << 16;
        --yb;
    } while (yb >= yLo && up[yb] * d <= lim);
    return yb;
}

class SpanCaster final : public Caster {
  public:
    SpanCaster(const TerrainMap& map, const RenderOptions& options) : map_(map), options_(options) {
        if (options_.supersample != 1) {
            throw InputError("supersample " + std::to_string(options_.supersample) +
                             ": the span caster draws one sample per pixel (use --caster fast)");
        }
        if (!(options_.spanMaxStretch >= 1.0 && options_.spanMaxStretch <= 16.0)) {
            throw InputError("span stretch limit " + std::to_string(options_.spanMaxStretch) +
                             ": expected 1..16");
        }
        if (options_.pyramid || options_.slopes) {
            throw InputError(
                "the span caster renders a map in memory, not one paged from a "
                "terrain database (use --caster fast)");
        }
        RenderOptions fast = options_;
        fast.objects.clear();  // drawn by this caster over either path's terrain
        fast.levels = options_.levels == 0 ? kLevelsAuto : options_.levels;
        pyramid_ = std::make_shared<const TerrainPyramid>(map, fast.levels);
        // Built now, on the span caster's pyramid: a steep frame in flight neither waits for a
        // pyramid nor holds a second one.
        fallback_.caster = makeFastCaster(map_, fast, pyramid_);
        for (int j = 0; j < pyramid_->nodeLevelCount(); ++j) {
            nodeSizeX_.push_back(std::ldexp(map.spacingX(), j));
            nodeSizeY_.push_back(std::ldexp(map.spacingY(), j));
            nodeInvX_.push_back(1.0 / nodeSizeX_.back());
            nodeInvY_.push_back(1.0 / nodeSizeY_.back());
        }
    }
    CasterKind kind() const override { return CasterKind::Span; }

    void render(const Camera& camera, RenderedFrame& frame) const override {
        UnitCounters c;
        renderUnit(camera, frame, 0, c);
        frame.stats.steps = c.steps;
        frame.stats.restarts = c.restarts;
        frame.stats.rays =
            static_cast<std::uint64_t>(camera.intrinsics().width) * camera.intrinsics().height;
        finishFrame(camera, frame);
    }
    // A steep frame was lit by the fast caster it went to; the spans by level 0's normals.
    void finishFrame(const Camera& camera, RenderedFrame& frame) const override {
        if (frame.stats.path == "span") finishPasses(map_, options_, LevelBands{}, camera, frame);
    }

    // One unit: the whole frame (the resample reads across columns); columns and rows inside it
    // go to the library's workers.
    int workUnits(const Camera&) const override { return 1; }

    void renderUnit(const Camera& camera, RenderedFrame& frame, int unit,
                    UnitCounters& counters) const override {
        CHECK(unit == 0) << "the span caster renders a frame as one unit";
        CHECK(camera.pose().roll == 0.0)
            << "span caster renders roll = 0 (the PRP applies roll); use naive or reference";
        const double stretch = spanStretch(camera);
        if (!(stretch <= options_.spanMaxStretch)) {
            frame.stats.path = "fast";
            fallback_.renderUnitsInto(camera, frame, counters);
        } else {
            frame.stats.path = "span";
            renderSpans(camera, frame, counters);
        }
        runWithThreads(options_.threads, [&] {
            drawObjectsOverTerrain(options_.objects, options_.sky, camera, frame);
        });
    }

  private:
    // The fast caster the steep frames go to.
    struct Fallback {
        std::unique_ptr<Caster> caster;
        void renderUnitsInto(const Camera& camera, RenderedFrame& frame,
                             UnitCounters& counters) const {
            caster->render(camera, frame);
            counters.steps += frame.stats.steps;
            counters.restarts += frame.stats.restarts;
        }
    };

    std::unique_ptr<SpanBuffers> takeBuffers() const {
        std::lock_guard lock(poolMutex_);
        if (pool_.empty()) return std::make_unique<SpanBuffers>();
        auto b = std::move(pool_.back());
        pool_.pop_back();
        return b;
    }
    void giveBuffers(std::unique_ptr<SpanBuffers> b) const {
        std::lock_guard lock(poolMutex_);
        pool_.push_back(std::move(b));
    }

    SpanFrame setUp(const Camera& camera) const;
    std::uint64_t renderColumn(const SpanFrame& sf, int j, std::uint32_t* __restrict__ color,
                               float* __restrict__ depth) const;
    void renderSpans(const Camera& camera, RenderedFrame& frame, UnitCounters& counters) const;

    const TerrainMap& map_;
    RenderOptions options_;
    std::shared_ptr<const TerrainPyramid> pyramid_;
    // Node sizes in metres per node level, and their inverses.
    std::vector<double> nodeSizeX_, nodeSizeY_, nodeInvX_, nodeInvY_;
    Fallback fallback_;
    mutable std::mutex poolMutex_;
    mutable std::vector<std::unique_ptr<SpanBuffers>> pool_;
    mutable tbb::enumerable_thread_specific<SpanScratch> scratch_;
};

SpanFrame SpanCaster::setUp(const Camera& camera) const {
    const Intrinsics& in = camera.intrinsics();
    const Pose& pose = camera.pose();
    SpanFrame sf;
    sf.width = in.width;
    sf.height = in.height;
    sf.focal = in.focal;
    sf.lodFocal = in.lodFocal();
    sf.cx = in.cx();
    const double f = in.focal, cy = in.cy();
    const double sp = std::sin(pose.pitch), cp = std::cos(pose.pitch);
    sf.up.resize(in.height);
    sf.stretch.resize(in.height);
    double smax = 0.0;
    for (int y = 0; y < in.height; ++y) {
        // Output pixel row y seen on the vertical plane: forward component D, up component U
        // (per unit of the pixel's focal-plane offsets); the vertical plane sees it at the
        // elevation offset f U / D and at columns stretched by f / D.
        const double yc = y + 0.5 - cy;
        const double D = f * cp + yc * sp;
        const double U = f * sp - yc * cp;
        sf.up[y] = f * U / D;
        sf.stretch[y] = f / D;
        smax = std::max(smax, sf.stretch[y]);
    }
    const int pad = static_cast<int>(std::ceil(0.5 * in.width * (smax - 1.0))) + 2;
    sf.columns = in.width + 2 * pad;
    sf.half = 0.5 * sf.columns;
    // Columns each row reads, then rows each column must hold (two rows of margin).
    sf.rowLo.assign(sf.columns, in.height);
    sf.rowHi.assign(sf.columns, -1);
    // The rows' column intervals are nested (the stretch is monotonic in y), so their union
    // grows one end at a time: each column's first row from the top, its last from the bottom.
    std::vector<int> c0(in.height), c1(in.height);
    for (int y = 0; y < in.height; ++y) {
        c0[y] = std::max(0, static_cast<int>(std::floor(columnAt(sf, 0, sf.stretch[y]))));
        c1[y] =
            std::min(sf.columns - 1,
                     static_cast<int>(std::floor(columnAt(sf, in.width - 1, sf.stretch[y]))) + 1);
    }
    auto sweep = [&](int yFirst, int yStep, std::vector<int>& rows) {
        int lo = sf.columns, hi = -1;  // union so far
        for (int y = yFirst; y >= 0 && y < in.height; y += yStep) {
            for (int j = c0[y]; j <= c1[y] && j < lo; ++j)
                rows[j] = y;
            for (int j = std::max(c0[y], hi + 1); j <= c1[y]; ++j)
                rows[j] = y;
            lo = std::min(lo, c0[y]);
            hi = std::max(hi, c1[y]);
        }
    };
    sweep(0, 1, sf.rowLo);
    sweep(in.height - 1, -1, sf.rowHi);
    for (int j = 0; j < sf.columns; ++j) {
        if (sf.rowLo[j] > sf.rowHi[j]) continue;
        sf.rowLo[j] = std::max(0, sf.rowLo[j] - 2);
        sf.rowHi[j] = std::min(in.height - 1, sf.rowHi[j] + 2);
    }
    sf.eye = pose.position;
    sf.headingX = std::sin(pose.yaw);
    sf.headingY = std::cos(pose.yaw);
    sf.rightX = std::cos(pose.yaw);
    sf.rightY = -std::sin(pose.yaw);
    return sf;
}

}  // namespace

double spanStretch(const Camera& camera) {
    const Intrinsics& in = camera.intrinsics();
    const double f = in.focal, cy = in.cy();
    const double sp = std::sin(camera.pose().pitch), cp = std::cos(camera.pose().pitch);
    double smax = 0.0;
    for (const double y : {0.5, in.height - 0.5}) {
        const double D = f * cp + (y - cy) * sp;
        if (!(D > 1e-6 * f)) return kInf;
        smax = std::max(smax, f / D);
    }
    return smax;
}

namespace {

// One vertical-plane column: front to back along its ground line, filling rows from the bottom
// of its row range up. Returns the number of terrain samples taken.
std::uint64_t SpanCaster::renderColumn(const SpanFrame& sf, int j,
                                       std::uint32_t* __restrict__ color,
                                       float* __restrict__ depth) const {
    const int yLo = sf.rowLo[j];
    int yb = sf.rowHi[j];
    if (yb < yLo) return 0;
    const SkyModel& sky = options_.sky;
    const double* __restrict__ up = sf.up.data();
    const double uc = j + 0.5 - sf.half;
    // Ground direction of the column (unit) and the column's horizontal length per focal unit:
    // a row with elevation offset up[y] climbs up[y] / L metres per metre along the ground.
    const double gx = sf.focal * sf.headingX + uc * sf.rightX;
    const double gy = sf.focal * sf.headingY + uc * sf.rightY;
    const double L = std::sqrt(gx * gx + gy * gy), invL = 1.0 / L;
    const double dx = gx * invL, dy = gy * invL;
    const double ez = sf.eye.z;
    const double scale = map_.heightScale(), offset = map_.heightOffset();
    std::uint64_t samples = 0;

    // The previous sample: ground distance, height over the eye, colour.
    double pd = 0.0, ph = 0.0;
    ColorSource slot[2];
    int prev = 0;  // slot[prev]: the previous sample's colour; slot[prev ^ 1]: the next one's

    auto writeSky = [&](int y) {
        const double t = up[y] * invL;
        color[y] = pack(skyColor(sky, t / std::sqrt(1.0 + t * t)));
        depth[y] = kSkyDepth;
    };
    // Takes the sample (d, h) whose colour is in slot[prev ^ 1]: fills the rows whose rays pass
    // under it, between the previous sample and it (colours worked out only then).
    auto emit = [&](double d, double h) {
        ++samples;
        const double lim = h * L;
        ColorSource& cur = slot[prev ^ 1];
        if (yb >= yLo && up[yb] * d <= lim) {
            ColorSource& last = slot[prev];
            last.resolve();
            cur.resolve();
            SpanSegment seg{static_cast<float>(pd), static_cast<float>(ph), static_cast<float>(d),
                            static_cast<float>(h)};
            for (int i = 0; i < 3; ++i) {
                seg.ca[i] = last.rgb[i];
                seg.cb[i] = cur.rgb[i];
            }
            if (hazeInKernel(sky)) {
                // The endpoints hazed at their own distances, linear between them.
                applyHaze(sky, seg.ca, std::sqrt(pd * pd + ph * ph));
                applyHaze(sky, seg.cb, std::sqrt(d * d + h * h));
            }
            yb = fillSegment(seg, up, yb, yLo, d, lim, static_cast<float>(invL), color, depth);
        }
        pd = d;
        ph = h;
        prev ^= 1;
    };

    // The ground line inside the map box: [dIn, dOut].
    double dIn = 0.0, dOut = kInf;
    auto clip = [&](double e, double dir, double hi) {
        if (dir == 0.0) {
            if (e < 0.0 || e > hi) dOut = -1.0;
            return;
        }
        double a = (0.0 - e) / dir, b = (hi - e) / dir;
        if (a > b) std::swap(a, b);
        dIn = std::max(dIn, a);
        dOut = std::min(dOut, b);
    };
    clip(sf.eye.x, dx, map_.extentX());
    clip(sf.eye.y, dy, map_.extentY());
    const double topLimit = (map_.maxHeight() - ez) * L;  // up * d at or above this: sky
    if (dIn <= dOut) {
        // First sample: the bilinear surface where the line enters (under the eye when inside).
        {
            const double x = sf.eye.x + dIn * dx, y = sf.eye.y + dIn * dy;
            float c[3];
            map_.surfaceColor(x, y, c);
            const double h = map_.surfaceHeight(x, y) - ez;
            // Rows under the surface already at the map's edge see that edge.
            while (yb >= yLo && up[yb] * dIn <= h * L) {
                const double t = up[yb] * invL;
                const double dist = dIn * std::sqrt(1.0 + t * t);
                float rgb[3] = {c[0], c[1], c[2]};
                applyHaze(sky, rgb, dist);
                color[yb] = pack(quantizeColor(rgb));
                depth[yb] = static_cast<float>(dist);
                --yb;
            }
            pd = dIn;
            ph = h;
            slot[prev].l = nullptr;
            for (int i = 0; i < 3; ++i)
                slot[prev].rgb[i] = c[i];
            ++samples;
        }
        const bool majorX = std::abs(dx / map_.spacingX()) >= std::abs(dy / map_.spacingY());
        const double spMaj0 = majorX ? map_.spacingX() : map_.spacingY();
        const double spMin0 = majorX ? map_.spacingY() : map_.spacingX();
        const double eMaj = majorX ? sf.eye.x : sf.eye.y, eMin = majorX ? sf.eye.y : sf.eye.x;
        const double dMaj = majorX ? dx : dy, dMin = majorX ? dy : dx;
        const int sgn = dMaj > 0.0 ? 1 : -1;
        const int top = pyramid_->levelCount() - 1;
        const double d0 = top > 0 ? sf.lodFocal * std::max(map_.spacingX(), map_.spacingY()) : kInf;

        const int topNode = pyramid_->nodeLevelCount() - 1;
        const double invDx = dx != 0.0 ? 1.0 / dx : kInf, invDy = dy != 0.0 ? 1.0 / dy : kInf;
        const double invSpX = 1.0 / map_.spacingX(), invSpY = 1.0 / map_.spacingY();
        const double nodeScale = scale * L, nodeOffset = (offset - ez) * L;
        bool done = false;
        for (int k = 0; k <= top && yb >= yLo && !done; ++k) {
            const PyramidLevel& lk = pyramid_->level(k);
            const PyramidLevel* lk1 = k < top ? &pyramid_->level(k + 1) : nullptr;
            const double bandEnd = k < top ? d0 * std::ldexp(1.0, k + 1) : kInf;
            const double blendFrom = d0 * std::ldexp(1.0, k);  // w = d / blendFrom - 1 past it
            if (pd >= bandEnd) continue;
            const double spMaj = std::ldexp(spMaj0, k), spMin = std::ldexp(spMin0, k);
            const int nMaj = majorX ? lk.width : lk.height, nMin = majorX ? lk.height : lk.width;
            const std::size_t sMaj = majorX ? 1 : static_cast<std::size_t>(lk.width);
            const std::size_t sMin = majorX ? static_cast<std::size_t>(lk.width) : 1;
            const double invDMaj = 1.0 / dMaj, invSpMaj = 1.0 / spMaj, invSpMin = 1.0 / spMin;
            const double dEnd = std::min(dOut, bandEnd);
            // The first line strictly past the previous sample.
            const double gm = (eMaj + pd * dMaj) * invSpMaj;
            long m = sgn > 0 ? static_cast<long>(std::floor(gm)) + 1
                             : static_cast<long>(std::ceil(gm)) - 1;
            // Minor coordinate of the previous sample (level 0: minor-line crossings).
            double pn = (eMin + pd * dMin) * invSpMin;

            // Samples level k where the line crosses major line m (and, on level 0, where it
            // crossed a minor line since the previous sample) and fills the rows under them.
            // False when the column is finished.
            auto line = [&](long mm, double d) -> bool {
                const double n = (eMin + d * dMin) * invSpMin;
                if (k == 0) {
                    const long fa = floorL(pn), fb = floorL(n);
                    if (fa != fb) {
                        const long nI = fb > fa ? fb : fa;
                        const double frac = (nI - pn) / (n - pn);
                        const double dN = pd + frac * (d - pd);
                        if (dN > pd && dN < d) {
                            // On the minor line: linear between its two grid samples.
                            const double gmN = (eMaj + dN * dMaj) * invSpMaj;
                            const int m0 = std::clamp(static_cast<int>(gmN), 0, nMaj - 2);
                            const int iN = std::clamp(static_cast<int>(nI), 0, nMin - 1);
                            const double fm = std::clamp(gmN - m0, 0.0, 1.0);
                            ColorSource& cs = slot[prev ^ 1];
                            cs.l = &lk;
                            cs.a = static_cast<std::size_t>(m0) * sMaj + iN * sMin;
                            cs.b = cs.a + sMaj;
                            cs.fr = static_cast<float>(fm);
                            cs.l1 = nullptr;
                            double h =
                                lk.heights[cs.a] +
                                fm * (static_cast<double>(lk.heights[cs.b]) - lk.heights[cs.a]);
                            if (lk1 && dN > blendFrom) {
                                // Past d0 level 0 blends toward level 1 (as on the lines).
                                const double w = std::min(1.0, dN / blendFrom - 1.0);
                                cs.p1 = bilinearAt(*lk1, 0.5 * (sf.eye.x + dN * dx) * invSpX,
                                                   0.5 * (sf.eye.y + dN * dy) * invSpY);
                                cs.l1 = lk1;
                                cs.w = static_cast<float>(w);
                                h += w * (bilinearHeight(*lk1, cs.p1) - h);
                            }
                            emit(dN, h * scale + offset - ez);
                            if (yb < yLo) return false;
                        }
                    }
                }
                pn = n;
                // Level k along the line: linear between the two samples either side.
                const double nc = std::clamp(n, 0.0, nMin - 1.0);
                const int i0 = std::min(static_cast<int>(nc), nMin - 2);
                const double fr = nc - i0;
                ColorSource& cs = slot[prev ^ 1];
                cs.l = &lk;
                cs.a = static_cast<std::size_t>(mm) * sMaj + i0 * sMin;
                cs.b = cs.a + sMin;
                cs.fr = static_cast<float>(fr);
                cs.l1 = nullptr;
                double h = lk.heights[cs.a] +
                           fr * (static_cast<double>(lk.heights[cs.b]) - lk.heights[cs.a]);
                if (lk1 && d > blendFrom) {
                    const double w = std::min(1.0, d / blendFrom - 1.0);
                    const double gMaj1 = 0.5 * static_cast<double>(mm), gMin1 = 0.5 * n;
                    cs.p1 =
                        majorX ? bilinearAt(*lk1, gMaj1, gMin1) : bilinearAt(*lk1, gMin1, gMaj1);
                    cs.l1 = lk1;
                    cs.w = static_cast<float>(w);
                    h += w * (bilinearHeight(*lk1, cs.p1) - h);
                }
                emit(d, h * scale + offset - ez);
                if (yb < yLo) return false;
                // Nothing further can rise over the next row's ray.
                return !(up[yb] >= 0.0 && up[yb] * d >= topLimit);
            };

            // Max-height nodes: a stretch of the line over a node whose bound stays under the
            // lowest row still to fill is passed without samples, but for the last line in it
            // (below that row too), which starts the next segment. Coarser nodes after a pass,
            // finer where a node may reach the row; at the finest, the lines inside are sampled.
            const int jMin = std::max(1, k + 2);
            int nl = std::min(topNode, jMin + 2);
            double cursor = pd;  // where the node search stands
            while (!done) {
                const double dm = (m * spMaj - eMaj) * invDMaj;
                if (m < 0 || m >= nMaj || dm > dEnd) break;
                double until = dm;  // sample the lines up to here
                if (topNode >= jMin) {
                    for (;;) {
                        const double sx = nodeSizeX_[nl], sy = nodeSizeY_[nl];
                        const double px = sf.eye.x + cursor * dx, py = sf.eye.y + cursor * dy;
                        const double gxn = px * nodeInvX_[nl], gyn = py * nodeInvY_[nl];
                        const int nx = static_cast<int>(
                            std::clamp(dx >= 0.0 ? floorL(gxn) : -floorL(-gxn) - 1, 0L,
                                       static_cast<long>(pyramid_->nodesX(nl) - 1)));
                        const int ny = static_cast<int>(
                            std::clamp(dy >= 0.0 ? floorL(gyn) : -floorL(-gyn) - 1, 0L,
                                       static_cast<long>(pyramid_->nodesY(nl) - 1)));
                        const double tx =
                            dx != 0.0 ? ((dx > 0.0 ? nx + 1 : nx) * sx - sf.eye.x) * invDx : kInf;
                        const double ty =
                            dy != 0.0 ? ((dy > 0.0 ? ny + 1 : ny) * sy - sf.eye.y) * invDy : kInf;
                        const double exitD = std::min({tx, ty, dEnd});
                        const double u = up[yb];
                        const double low = u * (u >= 0.0 ? cursor : exitD);
                        const bool below =
                            pyramid_->nodeMaxRaw(nl, nx, ny) * nodeScale + nodeOffset < low;
                        if (exitD > cursor && below) {
                            // Pass the node: jump to the last line in it.
                            const double ge = (eMaj + exitD * dMaj) * invSpMaj;
                            const long last = sgn > 0 ? static_cast<long>(std::floor(ge))
                                                      : static_cast<long>(std::ceil(ge));
                            if ((last - m) * sgn > 0) m = last;
                            cursor = exitD;
                            nl = std::min(topNode, nl + 1);
                            until = (m * spMaj - eMaj) * invDMaj;
                            break;
                        }
                        if (nl > jMin && exitD > cursor) {
                            --nl;
                            continue;
                        }
                        // At the finest node: sample every line up to its exit.
                        until = std::max(dm, exitD);
                        cursor = std::max(cursor, exitD);
                        nl = std::min(topNode, jMin + 1);
                        break;
                    }
                }
                for (;;) {
                    const double d = (m * spMaj - eMaj) * invDMaj;
                    if (m < 0 || m >= nMaj || d > dEnd || d > until) break;
                    if (!line(m, d)) {
                        done = true;
                        break;
                    }
                    m += sgn;
                }
                cursor = std::max(cursor, pd);
            }
        }
    }
    for (; yb >= yLo; --yb)
        writeSky(yb);
    return samples;
}

void SpanCaster::renderSpans(const Camera& camera, RenderedFrame& frame,
                             UnitCounters& counters) const {
    const SpanFrame sf = setUp(camera);
    const int H = sf.height, W = sf.width;
    std::unique_ptr<SpanBuffers> buf = takeBuffers();
    const std::size_t n = static_cast<std::size_t>(sf.columns) * H;
    if (buf->color.size() < n) {
        buf->color.resize(n);
        buf->depth.resize(n);
    }
    std::uint32_t* const colColor = buf->color.data();
    float* const colDepth = buf->depth.data();
    tbb::combinable<std::uint64_t> samples([] { return std::uint64_t{0}; });
    runWithThreads(options_.threads, [&] {
        // Columns are independent: the image does not depend on the thread count.
        tbb::parallel_for(tbb::blocked_range<int>(0, sf.columns, 16),
                          [&](const tbb::blocked_range<int>& r) {
                              std::uint64_t s = 0;
                              for (int j = r.begin(); j < r.end(); ++j) {
                                  const std::size_t o = static_cast<std::size_t>(j) * H;
                                  s += renderColumn(sf, j, colColor + o, colDepth + o);
                              }
                              samples.local() += s;
                          });
        // Rows, in strips of 16: the strip's rows of the columns its pixels read, transposed
        // into a row-major scratch that stays in cache, then each output row from its plane
        // row (a copy where the row's columns are the image's).
        constexpr int kStrip = 16;
        tbb::parallel_for(0, (H + kStrip - 1) / kStrip, [&](int strip) {
            const int y0 = strip * kStrip, y1 = std::min(H, y0 + kStrip);
            // Columns read: from the first pixel's (rounded down) to the last pixel's right
            // neighbour (+1 for the rounding of positions to 1/256 of a column).
            double first = kInf, last = -kInf;
            for (int y = y0; y < y1; ++y) {
                first = std::min(first, columnAt(sf, 0, sf.stretch[y]));
                last = std::max(last, columnAt(sf, W - 1, sf.stretch[y]));
            }
            const int jLo = std::max(0, static_cast<int>(std::floor(first)));
            const int jHi = std::min(sf.columns, static_cast<int>(std::floor(last)) + 3);
            const int stride = jHi - jLo;
            SpanScratch& scratch = scratch_.local();
            const std::size_t need = static_cast<std::size_t>(stride) * kStrip;
            if (scratch.color.size() < need) {
                scratch.color.resize(need);
                scratch.depth.resize(need);
            }
            spanTranspose(colColor, H, jLo, jHi, y0, y1, scratch.color.data(), stride);
            spanTranspose(colDepth, H, jLo, jHi, y0, y1, scratch.depth.data(), stride);
            for (int y = y0; y < y1; ++y) {
                const std::size_t o = static_cast<std::size_t>(y - y0) * stride;
                spanResampleRow(scratch.color.data() + o, scratch.depth.data() + o,
                                spanRowMap(columnAt(sf, 0, sf.stretch[y]) - jLo, sf.stretch[y]), W,
                                frame.color.data() + static_cast<std::size_t>(y) * W,
                                frame.depth.data() + static_cast<std::size_t>(y) * W);
            }
        });
    });
    giveBuffers(std::move(buf));
    counters.steps += samples.combine([](std::uint64_t a, std::uint64_t b) { return a + b; });
}

}  // namespace

std::unique_ptr<Caster> makeSpanCaster(const TerrainMap& map, const RenderOptions& options) {
    return std::make_unique<SpanCaster>(map, options);
}

}  // namespace ig
