// Fast caster (Cohen-Or sec. 2.1): the image is cast column by column, bottom to top, each ray
// starting where the ray below it hit (vertical ray coherence), with the discrete grid march.
//
// With pitch, a column's rays are not in one vertical plane: their ground tracks fan out in
// azimuth, so the ray below may have passed beside a feature this ray meets. Coherence is used
// only where it is provably safe: where this ray's climb over the ray below outruns the most the
// terrain can rise across the gap between their tracks (the map's maximum slope bounds it).
// Elsewhere (near the nadir, where tracks fan widely or turn behind the camera, or on very steep
// maps) the ray starts afresh: it descends the max-height pyramid to the first node it may reach
// (hierarchical first hit), then marches. See docs/design/ray_casting.md.
//
// Multiresolution (RenderOptions::levels): up to the distance d0 where a level-0 voxel shrinks
// to a pixel the march is exact on level 0; beyond it the ray steps over coarser display levels,
// adjacent levels blended by distance. See docs/design/multires.md.
#include "base/check.hpp"
#include "base/cpu_features.hpp"
#include "ig/caster_impl.hpp"
#include "ig/caster_lanes.hpp"
#include "ig/coherence.hpp"
#include "ig/error.hpp"
#include "ig/far_march.hpp"
#include "ig/fast_column.hpp"
#include "ig/grid_march.hpp"
#include "ig/level0_march.hpp"
#include "ig/multires_march.hpp"
#include "ig/node_skip.hpp"
#include "ig/pyramid.hpp"
#include "ig/shading.hpp"
#include "ig/slope_bound.hpp"

#include <tbb/combinable.h>
#include <tbb/parallel_for.h>
#include <glm/geometric.hpp>

#include <charconv>
#include <cmath>
#include <cstring>
#include <limits>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <utility>

namespace ig {

int parseLevels(std::string_view text) {
    if (text == "auto") return kLevelsAuto;
    int n = -1;
    const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), n);
    if (ec != std::errc() || end != text.data() + text.size() || n < 0 || n > 30) {
        throw InputError("--levels '" + std::string(text) + "': expected auto or a count 0..30");
    }
    return n;
}

namespace fast {

// (fast_column.hpp)
bool climbsClear(const ColumnContext& cc, ColumnState& st, bool majorX, double rn, double rz) {
    const double sMajor = majorX ? cc.spacingX : cc.spacingY;
    const double sMinor = majorX ? cc.spacingY : cc.spacingX;
    const double gap = std::abs(rn - st.prevRn), climb = rz - st.prevRz;
    if (climbsClearOf(climb, cc.maxSlope, sMinor, gap)) return true;
    // Both rays' tracks stay within this horizontal distance of the eye up to prevU.
    const double reach = st.prevU * (sMajor + std::max(std::abs(rn), std::abs(st.prevRn)) * sMinor);
    return climbsClearOf(climb, st.wedge.upTo(reach), sMinor, gap);
}

}  // namespace fast

namespace {

// A restarted ray descends the max-height pyramid only when its way through the map box spans
// more cells than this; shorter ones (near the nadir) are cheaper to march.
constexpr double kSkipMinCells = 16.0;

using namespace fast;

class FastCaster final : public Caster {
  public:
    FastCaster(const TerrainMap& map, const RenderOptions& options,
               std::shared_ptr<const TerrainPyramid> pyramid)
        : map_(map), options_(options) {
        if (options_.supersample < 1 || options_.supersample > 8) {
            throw InputError("supersample " + std::to_string(options_.supersample) +
                             ": expected 1..8 rays per pixel");
        }
        if (options_.levels < kLevelsAuto) {
            throw InputError("levels " + std::to_string(options_.levels) +
                             ": expected auto or a count >= 0");
        }
        chooseKernel();
        pyramid_ = pyramid ? std::move(pyramid)
                           : std::make_shared<const TerrainPyramid>(map, options_.levels);
        topLevel_ = pyramid_->levelCount() - 1;
        slopes_ = std::make_unique<SlopeBlocks>(map);
        far_.emplace(map_, *pyramid_, options_.sky);
        rows_ = RowsCaster{&options_.sky, pyramid_.get(), options_.skipNodes, &*far_};
    }
    CasterKind kind() const override { return CasterKind::Fast; }
    std::string_view kernelName() const override { return casterKernelName(kernel_); }

    void render(const Camera& camera, RenderedFrame& frame) const override {
        checkRoll(camera);
        const int units = workUnits(camera);
        tbb::combinable<UnitCounters> counters;
        runWithThreads(options_.threads, [&] {
            // The image is a pool of columns (or groups of four); idle workers take the next.
            // Each is independent, so the image does not depend on the thread count.
            tbb::parallel_for(0, units,
                              [&](int unit) { renderUnit(camera, frame, unit, counters.local()); });
        });
        const UnitCounters total = counters.combine([](UnitCounters a, UnitCounters b) {
            return UnitCounters{a.steps + b.steps, a.restarts + b.restarts};
        });
        frame.stats.steps = total.steps;
        frame.stats.restarts = total.restarts;
        frame.stats.rays = static_cast<std::uint64_t>(camera.intrinsics().width) *
                           camera.intrinsics().height *
                           static_cast<std::uint64_t>(options_.supersample);
    }

    int workUnits(const Camera& camera) const override {
        const int w = camera.intrinsics().width;
        return (w + columnsPerUnit_ - 1) / columnsPerUnit_;
    }

    std::pair<int, int> unitColumns(const Camera& camera, int unit) const override {
        const int w = camera.intrinsics().width;
        return {columnsPerUnit_ * unit, std::min(columnsPerUnit_ * (unit + 1), w)};
    }

    void renderUnit(const Camera& camera, RenderedFrame& frame, int unit,
                    UnitCounters& counters) const override {
        checkRoll(camera);
        // Level 0 is used out to where a voxel spans one pixel across the view.
        const double d0 =
            topLevel_ > 0 ? camera.intrinsics().focal * std::max(map_.spacingX(), map_.spacingY())
                          : std::numeric_limits<double>::infinity();
        const double scale = map_.heightScale(), offset = map_.heightOffset();
        const MapView mv{map_.rawHeights().data(),
                         map_.cellMaxData(),
                         map_.colors().data(),
                         map_.width(),
                         map_.height(),
                         scale,
                         offset,
                         1.0 / scale,
                         (map_.maxHeight() - offset) / scale};
        (this->*renderUnit_)(mv, camera, d0, unit, frame, counters);
    }

  private:
    static void checkRoll(const Camera& camera) {
        CHECK(camera.pose().roll == 0.0)
            << "fast caster renders roll = 0 (the PRP applies roll); use naive or reference";
    }

    // Renders work unit `unit` (a column, or a group of four adjacent columns).
    using UnitRenderer = void (FastCaster::*)(const MapView& mv, const Camera& camera, double d0,
                                              int unit, RenderedFrame& frame,
                                              UnitCounters& counters) const;

    // The kernel and the function that renders a work unit with it, chosen once. The
    // multiresolution caster (levels != 0): coherent rays find their level-0 hit between the
    // major grid lines where they pass from above to below the surface, by linear
    // interpolation (the paper's discrete traversal, no exact solve; see linearRay), on rows
    // batched over vector lanes where the kernel has them. The single level: columns, four at
    // a time with AVX2 where the kernel has them and one ray per pixel.
    void chooseKernel() {
        CasterKernel k = options_.kernel;
        // The vector gathers index colour bytes with 32-bit offsets.
        const bool fits = 3.0 * map_.width() * map_.height() < 2147483647.0;
        if (k == CasterKernel::Auto) {
            const base::CpuFeatures& cpu = base::cpuFeatures();
            k = !VIG_CASTER_PACKETS || !fits    ? CasterKernel::Scalar
                : VIG_CASTER_WIDE && cpu.avx512 ? CasterKernel::Avx512
                : cpu.avx2                      ? CasterKernel::Avx2
                                                : CasterKernel::Scalar;
        } else if (k != CasterKernel::Scalar) {
            std::string missing = casterKernelMissing(k);
            if (!VIG_CASTER_PACKETS) missing = "this build's vector code (x86-64 only)";
            if (!missing.empty()) {
                throw InputError("kernel " + std::string(casterKernelName(k)) +
                                 ": the processor lacks " + missing);
            }
            if (!fits) {
                throw InputError("kernel " + std::string(casterKernelName(k)) + ": the map (" +
                                 std::to_string(map_.width()) + " x " +
                                 std::to_string(map_.height()) +
                                 ") is too large for the vector kernels' 32-bit offsets");
            }
        }
        const bool super = options_.supersample > 1;
        renderUnit_ = &FastCaster::renderColumnUnit;
        kernel_ = CasterKernel::Scalar;
        columnsPerUnit_ = 1;
        if (options_.levels != 0) {
            renderUnit_ = super ? &FastCaster::renderLinearColumn<true, 0>
                                : &FastCaster::renderLinearColumn<false, 0>;
            // The row batches, each compiled for its instruction set (caster_rows_*.cpp): four
            // lanes with AVX2; eight with AVX-512, and four where eight do not go.
#if VIG_CASTER_PACKETS
            if (k == CasterKernel::Avx2 || k == CasterKernel::Avx512) {
                rowsNarrow_ = rows_avx2::kernel();
                CHECK(rowsNarrow_.lanes == 4) << "this build lacks the AVX2 row batches";
            }
            if (k == CasterKernel::Avx2) {
                kernel_ = k;
                renderUnit_ = super ? &FastCaster::renderLinearColumn<true, 4>
                                    : &FastCaster::renderLinearColumn<false, 4>;
            }
#endif
#if VIG_CASTER_WIDE
            if (k == CasterKernel::Avx512) {
                rowsWide_ = rows_avx512::kernel();
                CHECK(rowsWide_.lanes == 8) << "this build lacks the AVX-512 row batches";
                kernel_ = k;
                renderUnit_ = super ? &FastCaster::renderLinearColumn<true, 8>
                                    : &FastCaster::renderLinearColumn<false, 8>;
            }
#endif
            return;
        }
#if VIG_CASTER_PACKETS
        // The single level has four-column packets (AVX2) only, for one ray per pixel.
        if (k != CasterKernel::Scalar && !super) {
            kernel_ = CasterKernel::Avx2;
            renderUnit_ = &FastCaster::renderPacketUnit;
            columnsPerUnit_ = 4;
        }
#endif
    }

    // A fresh cast: its hit, if any, and where the ray stopped (the hit, or where it left the
    // map box; 0 when it misses the box).
    struct FreshCast {
        std::optional<LevelHit> hit;
        double tStop = 0.0;
    };

    // The fresh (t-parameterised) path: box clip, hierarchical skip where worthwhile, exact
    // level-0 march out to tNear, multiresolution march beyond.
    // The bottom ray always descends the max-height pyramid (hierarchical first hit); a restart
    // only when its way through the map box is long (near the nadir a march is cheaper).
    FreshCast castFresh(const TerrainRay& ray, double horiz, double d0, bool bottom,
                        std::uint64_t& steps) const {
        FreshCast r;
        double t0, t1;
        if (!clipToMapBox(map_, ray, t0, t1)) return r;
        double tStart = t0;
        if (bottom || std::max(std::abs(ray.gdx), std::abs(ray.gdy)) * (t1 - t0) > kSkipMinCells) {
            tStart = skipEmptySpace(*pyramid_, ray, t0, t1, steps);
        }
        if (tStart >= 0.0) r.hit = castFrom(ray, horiz, d0, tStart, t1, steps);
        r.tStop = r.hit ? r.hit->t : t1;
        return r;
    }

    // The hit from tStart on: exact on level 0 out to tNear, the multiresolution march beyond.
    std::optional<LevelHit> castFrom(const TerrainRay& ray, double horiz, double d0, double tStart,
                                     double t1, std::uint64_t& steps) const {
        const double tNear = horiz > 0.0 ? d0 / horiz : t1;
        if (tStart < tNear) {
            const double t = marchRay(map_, ray, tStart, std::min(tNear, t1), steps);
            if (t >= 0.0) return LevelHit{t, -1, 0.0};  // level 0, colour from the map
        }
        if (tNear < t1) {
            const LevelHit hit = marchLevels(*pyramid_, ray, horiz, d0, topLevel_,
                                             std::max(tStart, tNear), t1, steps);
            if (hit.t >= 0.0) return hit;
        }
        return std::nullopt;
    }

    Rgb8 shadeLevelHit(const LevelHit& hit, const glm::dvec3& p) const {
        float rgb[3];
        if (hit.level < 0) {
            map_.surfaceColor(p.x, p.y, rgb);
        } else {
            levelHitColor(*pyramid_, hit, p.x, p.y, rgb);
        }
        return haze(rgb, hit.t);
    }

    // The shared haze and quantization (shading.hpp).
    Rgb8 haze(float rgb[3], double t) const {
        applyHaze(options_.sky, rgb, t);
        return quantizeColor(rgb);
    }

    // A ray of a column in major-axis form: direction d (length len); per major grid unit u it
    // travels lenPerU along d, rn minor cells and rz metres up; inv = 1 / |major component|
    // (grid units); the major axis is x (majorX) or y, travelled in direction sgn.
    struct MajorRay {
        glm::dvec3 d;
        double len, lenPerU, inv;
        bool majorX;
        int sgn;
        double rn, rz;
    };

    // Starts a column's state: its slope bounds look at the wedge its rays sweep.
    void startColumn(const Camera& camera, const ColumnContext& cc, ColumnState& st) const {
        const glm::dvec3 last = cc.base + static_cast<double>(camera.intrinsics().height) * cc.down;
        double reach = 0.0;
        for (const double x : {0.0, map_.extentX()})
            for (const double y : {0.0, map_.extentY()})
                reach = std::max(reach, std::hypot(x - cc.eye.x, y - cc.eye.y));
        st.wedge.reset(slopes_.get(), {cc.eye.x, cc.eye.y}, {cc.base.x, cc.base.y},
                       {last.x, last.y}, reach, cc.maxSlope);
    }

    // One ray of a column, any case: coherent, restarted, past the level-0 distance, straight
    // down. Sets the colour and the hit distance (negative: sky) and moves the state on.
    [[gnu::noinline]] void castRay(const ColumnContext& cc, const glm::dvec3& d, ColumnState& st,
                                   Rgb8& c, double& tHit) const {
        const MapView& mv = *cc.mv;
        const SkyModel& sky = options_.sky;
        const double gx = d.x * cc.invSx, gy = d.y * cc.invSy;
        const bool majorX = std::abs(gx) >= std::abs(gy);
        const double gm = majorX ? gx : gy, gn = majorX ? gy : gx;
        const double len = std::sqrt(d.x * d.x + d.y * d.y + d.z * d.z);
        tHit = -1.0;
        if (!(std::abs(gm) > 1e-9 * len)) {
            // Straight down or up: no major axis.
            const TerrainRay ray(map_, cc.eye, d);
            const FreshCast f = castFresh(ray, 0.0, cc.d0, !st.havePrev, st.steps);
            if (f.hit) {
                tHit = f.hit->t;
                c = shadeLevelHit(*f.hit, ray.at(f.hit->t));
            } else {
                c = skyColor(sky, ray.dir.z);
            }
            st.havePrev = false;
            st.prevAbove = false;
            return;
        }
        const double inv = 1.0 / std::abs(gm);
        const int sgn = gm > 0 ? 1 : -1;
        const double rn = gn * inv, rz = d.z * inv, lenPerU = len * inv;
        // At equal u this ray is (rz - prevRz) * u higher than the ray below and |rn - prevRn| * u
        // minor cells to the side, where the terrain is at most its slope bound times that
        // higher: when the climb wins, it cannot meet the terrain before the ray below stopped.
        const bool sameAxis = st.havePrev && st.prevMajorX == majorX && st.prevSgn == sgn;
        const bool coherent = sameAxis && climbsClear(cc, st, majorX, rn, rz);
        if (st.havePrev && !coherent) ++st.restarts;
        bool resolved = false;
        if (coherent && st.prevAbove) {
            // The ray below climbed above the map's highest point before meeting anything; this
            // one climbs faster: sky.
            c = skyColor(sky, d.z / len);
            resolved = true;
        } else if (st.prevAbove = false; coherent) {
            // Level 0 reaches out to horizontal distance d0.
            double uNear = std::numeric_limits<double>::infinity();
            if (cc.multires) uNear = cc.d0 / (std::sqrt(d.x * d.x + d.y * d.y) * inv);
            const ColumnMarch r =
                majorX ? marchCoherent<true>(mv, cc.eg, sgn, rn, rz, st.prevU, uNear, st.steps)
                       : marchCoherent<false>(mv, cc.eg, sgn, rn, rz, st.prevU, uNear, st.steps);
            resolved = finishCoherent(cc, d, len, lenPerU, r, st, c, tHit);
        }
        st.prevMajorX = majorX;
        st.prevSgn = sgn;
        st.prevRn = rn;
        st.prevRz = rz;
        if (!resolved && st.havePrev && !coherent && sameAxis) {
            resolved = restartInChain(cc, MajorRay{d, len, lenPerU, inv, majorX, sgn, rn, rz}, st,
                                      c, tHit);
        }
        if (!resolved) {
            // Bottom ray, restart, or a coherent start outside the map.
            const TerrainRay ray(map_, cc.eye, d);
            const double horiz = std::sqrt(ray.dir.x * ray.dir.x + ray.dir.y * ray.dir.y);
            const FreshCast f = castFresh(ray, horiz, cc.d0, !st.havePrev, st.steps);
            if (f.hit) {
                tHit = f.hit->t;
                c = shadeLevelHit(*f.hit, ray.at(f.hit->t));
            } else {
                c = skyColor(sky, ray.dir.z);
            }
            st.prevU = f.tStop / lenPerU;
        }
        st.havePrev = true;
    }

    // The multiresolution caster's coherent ray (levels != 0): where the ray climbs clear of the
    // ray below (the same proof as castRay's), it marches from where that ray stopped, sampling
    // the surface where it crosses major grid lines (the bilinear surface there, linear along
    // the line) and taking its hit between the last line it passed above and the first it is
    // under, by linear interpolation of its height over the surface. False (state untouched)
    // for every other case, which castRay then casts.
    [[gnu::always_inline]] bool linearRay(const ColumnContext& cc, const glm::dvec3& d,
                                          ColumnState& st, Rgb8& c, double& tHit) const {
        if (!st.havePrev) return false;
        const double gx = d.x * cc.invSx, gy = d.y * cc.invSy;
        const bool majorX = std::abs(gx) >= std::abs(gy);
        const double gm = majorX ? gx : gy, gn = majorX ? gy : gx;
        const int sgn = gm > 0 ? 1 : -1;
        if (st.prevMajorX != majorX || st.prevSgn != sgn) return false;
        const double len = std::sqrt(d.x * d.x + d.y * d.y + d.z * d.z);
        if (!(std::abs(gm) > 1e-9 * len)) return false;
        const double inv = 1.0 / std::abs(gm);
        const double rn = gn * inv, rz = d.z * inv;
        if (!climbsClear(cc, st, majorX, rn, rz)) return false;
        tHit = -1.0;
        if (st.prevAbove) {
            c = skyColor(options_.sky, d.z / len);
        } else {
            double uNear = std::numeric_limits<double>::infinity();
            if (cc.multires) uNear = cc.d0 / (std::sqrt(d.x * d.x + d.y * d.y) * inv);
            const ColumnMarch r = majorX ? marchLinear<true>(*cc.mv, cc.eg, skipPyramid(), sgn, rn,
                                                             rz, st.prevU, uNear, st.steps)
                                         : marchLinear<false>(*cc.mv, cc.eg, skipPyramid(), sgn, rn,
                                                              rz, st.prevU, uNear, st.steps);
            if (r.kind == ColumnMarch::kFresh) return false;
            if (r.kind == ColumnMarch::kFar) {
                far_->linearFar(cc, d.x, d.y, d.z, len, inv, majorX, sgn, rn, rz, r.u, st.prevU,
                                st.prevAbove, st.steps, c, tHit);
            } else {
                finishCoherent(cc, d, len, len * inv, r, st, c, tHit);
            }
        }
        st.prevRn = rn;
        st.prevRz = rz;
        return true;
    }

    // The pyramid whose nodes long marches pass, or none (RenderOptions::skipNodes).
    const TerrainPyramid* skipPyramid() const {
        return options_.skipNodes ? pyramid_.get() : nullptr;
    }

    // marchCoherent's march on the surface sampled at major grid lines, linear between them.
    // The march goes from node A (the grid line at or before uStart; uStart itself when that
    // line is behind the eye) to the following lines; the hit lies between the last node the
    // ray passed above and the first it is under. Long marches pass max-height nodes where they
    // can (skipNodes; not without pyr).
    template <bool kMajorX>
    [[gnu::always_inline]] static ColumnMarch marchLinear(const MapView& mv, const EyeGrid& eg,
                                                          const TerrainPyramid* pyr, int sgn,
                                                          double rn, double rz, double uStart,
                                                          double uNear, std::uint64_t& steps) {
        const std::uint16_t* __restrict__ heights = mv.heights;
        const int w = mv.width;
        const int majorCount = kMajorX ? w : mv.height, minorCount = kMajorX ? mv.height : w;
        const double em = kMajorX ? eg.gx : eg.gy, en = kMajorX ? eg.gy : eg.gx;
        ColumnMarch out;
        out.u = uStart;
        const double gm0 = em + sgn * uStart;
        const long m = sgn > 0 ? floorToLong(gm0) : -floorToLong(-gm0);
        const double u = (m - em) * sgn;
        const double dzr = rz * mv.invScale;
        const bool rising = dzr >= 0.0;
        double uA, above, zA;
        // Node A on a major line: its minor coordinate and the samples either side.
        bool onLine = false;
        double nA = 0.0;
        LineSample sA;
        if (u >= 0.0) {
            if (m < 0 || m > majorCount - 1) {
                const bool ahead = sgn > 0 ? m < 0 : m > majorCount - 1;
                out.kind = ahead || !eg.inside ? ColumnMarch::kFresh : ColumnMarch::kStop;
                return out;
            }
            nA = en + rn * u;
            if (!(nA >= 0.0) || nA > minorCount - 1.0) {
                out.kind = !eg.inside ? ColumnMarch::kFresh : ColumnMarch::kStop;
                return out;
            }
            uA = u;
            zA = eg.zRaw + dzr * u;
            sA = lineSample<kMajorX>(heights, w, minorCount, m, nA);
            above = zA - sA.h;
            onLine = true;
        } else {
            // Line m is behind the eye: node A is the start itself, inside the map.
            const double gn0 = en + rn * uStart;
            if (!eg.inside || !(gm0 >= 0.0) || gm0 > majorCount - 1.0 || !(gn0 >= 0.0) ||
                gn0 > minorCount - 1.0) {
                out.kind = ColumnMarch::kFresh;
                return out;
            }
            uA = uStart;
            zA = eg.zRaw + dzr * uStart;
            above = zA - levelSurface<kMajorX>(levelZero(mv), gm0, gn0);
        }
        // Lines m + sgn, m + 2 sgn, ... up to the major end or the level-0 distance.
        constexpr std::int64_t kMany = std::int64_t{1} << 40;
        const std::int64_t majorSteps = sgn > 0 ? majorCount - 1 - m : m;
        std::int64_t nearSteps = kMany;
        if (uNear < 1e12) nearSteps = std::max<long>(0, -floorToLong(u - uNear));
        const std::int64_t total = std::min(majorSteps, nearSteps);
        std::int64_t k = 0;
        double uHit = -1.0;
        const double invRn = 1.0 / rn;
        // Steps the ray cannot end on but by a hit (as linearRows' kSafe), where nodes may be
        // passed: found when the march first gets long.
        std::int64_t kSafe = -1, tryAt = pyr && onLine ? kSkipAfter : total, skipped = 0;
        std::int64_t retry = kSkipRetry;
        const double nStart = nA;
        int skipLevel = kSkipFirstLevel;
        if (above <= 0.0) {
            uHit = uA;
        } else {
            for (; k < total; ++k) {
                if (k >= tryAt && kSafe < 0) {
                    const double toSide = rn > 0.0 ? minorCount - 1.0 - nStart : nStart;
                    double safe = static_cast<double>(total);
                    if (rn != 0.0) safe = std::min(safe, (toSide - 1e-6) / std::abs(rn) - 2.0);
                    if (dzr > 0.0) safe = std::min(safe, (mv.maxRaw - eg.zRaw) / dzr - u - 2.0);
                    kSafe = safe > 0.0 ? static_cast<std::int64_t>(safe) : 0;
                }
                if (k >= tryAt && k < kSafe) {
                    const long lineA = m + sgn * k;
                    const long lines = skipNodes<kMajorX>(*pyr, skipLevel, lineA, sgn, kSafe - k,
                                                          RayFan{em, en, eg.zRaw, dzr, rn, rn});
                    if (lines > 0) {
                        // Line A moves on by `lines`: the loop's values there.
                        k += lines;
                        skipped += lines - 1;
                        const long lineNew = m + sgn * k;
                        uA = (static_cast<double>(lineNew) - em) * sgn;
                        nA = en + rn * uA;
                        zA = eg.zRaw + dzr * uA;
                        sA = lineSample<kMajorX>(heights, w, minorCount, lineNew, nA);
                        above = zA - sA.h;
                        if (k >= total) break;
                        retry = kSkipRetry;
                    } else {
                        tryAt = k + retry;
                        retry *= 2;
                    }
                }
                const long lineB = m + sgn * (k + 1);
                const double uB = (static_cast<double>(lineB) - em) * sgn;
                const double nB = en + rn * uB;
                if (!(nB >= 0.0) || nB > minorCount - 1.0) {
                    steps += static_cast<std::uint64_t>(k + 1 - skipped);
                    out.kind = ColumnMarch::kStop;
                    out.u = std::max(uA, uStart);
                    return out;
                }
                if (rising && zA > mv.maxRaw) {
                    steps += static_cast<std::uint64_t>(k + 1 - skipped);
                    out.kind = ColumnMarch::kAbove;
                    out.u = std::max(uA, uStart);
                    return out;
                }
                const double zB = eg.zRaw + dzr * uB;
                const LineSample sB = lineSample<kMajorX>(heights, w, minorCount, lineB, nB);
                const double below = zB - sB.h;
                if (below <= 0.0) {
                    if (onLine && sB.i != sA.i) {
                        // The track crosses a minor grid line between A and B: the hit is
                        // between A, the node there and B.
                        const MinorNode p = minorNode(sA, sB, nA, invRn, zA, zB);
                        const double uP = uA + p.s * (uB - uA);
                        uHit = p.diff <= 0.0 ? uA + (uP - uA) * (above / (above - p.diff))
                                             : uP + (uB - uP) * (p.diff / (p.diff - below));
                    } else {
                        uHit = uA + (uB - uA) * (above / (above - below));
                    }
                    break;
                }
                above = below;
                uA = uB;
                zA = zB;
                nA = nB;
                sA = sB;
                onLine = true;
            }
        }
        steps += static_cast<std::uint64_t>(k + 1 - skipped);
        if (uHit < 0.0) {
            out.u = std::max(uA, uStart);
            out.kind = total == nearSteps && nearSteps < majorSteps + 1 ? ColumnMarch::kFar
                                                                        : ColumnMarch::kStop;
            return out;
        }
        out.kind = ColumnMarch::kHit;
        out.u = uHit;
        const double pm = em + sgn * uHit, pn = en + rn * uHit;
        const int cm = std::clamp(static_cast<int>(pm), 0, majorCount - 2);
        const int cn = std::clamp(static_cast<int>(pn), 0, minorCount - 2);
        out.cx = kMajorX ? cm : cn;
        out.cy = kMajorX ? cn : cm;
        out.fx = kMajorX ? pm - cm : pn - cn;
        out.fy = kMajorX ? pn - cn : pm - cm;
        return out;
    }

    // The surface (raw) where the ray crosses a level-0 major line at minor coordinate n >= 0:
    // linear along the line between the samples h0 (minor i) and h1 (minor i + 1).
    struct LineSample {
        double h = 0.0, h0 = 0.0, h1 = 0.0;
        int i = 0;
    };
    template <bool kMajorX>
    [[gnu::always_inline]] static LineSample lineSample(const std::uint16_t* heights, int w,
                                                        int minorCount, long line, double n) {
        LineSample r;
        r.i = std::min(static_cast<int>(n), minorCount - 2);
        const double f = n - r.i;
        const std::uint16_t* p = heights + (kMajorX ? line + static_cast<std::ptrdiff_t>(r.i) * w
                                                    : line * static_cast<std::ptrdiff_t>(w) + r.i);
        r.h0 = p[0];
        r.h1 = p[kMajorX ? w : 1];
        r.h = r.h0 + f * (r.h1 - r.h0);
        return r;
    }

    // Where the track crosses the minor grid line between major lines A and B (their samples
    // sA and sB in adjacent minor cells): the fraction s of the way from A to B, and the ray's
    // height over the surface there (linear along that minor line between A's and B's samples
    // on it). With these nodes the hit does not depend on which axis the ray marches along.
    // (invRn: 1 / rn, the major units per minor cell.)
    struct MinorNode {
        double s, diff;
    };
    [[gnu::always_inline]] static MinorNode minorNode(const LineSample& sA, const LineSample& sB,
                                                      double nA, double invRn, double zA,
                                                      double zB) {
        const bool up = sB.i > sA.i;
        const double c = up ? sB.i : sA.i;
        const double hA = up ? sA.h1 : sA.h0, hB = up ? sB.h0 : sB.h1;
        const double s = (c - nA) * invRn;
        // The ray's height over the minor line's samples at A and B, interpolated.
        const double dA = zA - hA, dB = zB - hB;
        return {s, dA + s * (dB - dA)};
    }

    static PyramidLevel levelZero(const MapView& mv) {
        PyramidLevel l;
        l.width = mv.width;
        l.height = mv.height;
        l.heights = mv.heights;
        return l;
    }

    // A restarted ray (its climb over the ray below does not outrun the slope bound: steep
    // features around) starts as far out as the column's clearance chain proves it clear:
    // any ray whose track stays within one minor cell of a ray X's at equal u, and which climbs
    // at least as fast, is above the terrain wherever X passed above the cell maxima within one
    // minor cell of its own track. The ray then scans on from there against those widened maxima
    // to where it first comes near the terrain (its own link of the chain), and marches
    // coherently from there to its hit. Without a chain to start from it scans from the eye,
    // but only where the ray below stopped within kChainReach major cells (a long empty march is
    // left to the hierarchical fresh cast). False when the march cannot run (the eye is off the
    // map, or a start off it): the ray is cast fresh.
    static constexpr double kChainReach = 4096.0;

    bool restartInChain(const ColumnContext& cc, const MajorRay& ray, ColumnState& st, Rgb8& c,
                        double& tHit) const {
        const glm::dvec3& d = ray.d;
        const double len = ray.len, lenPerU = ray.lenPerU, inv = ray.inv;
        const bool majorX = ray.majorX;
        const int sgn = ray.sgn;
        const double rn = ray.rn, rz = ray.rz;
        if (st.chainLength == 0 || st.chainMajorX != majorX || st.chainSgn != sgn) {
            st.chainLength = 0;
            st.chainMajorX = majorX;
            st.chainSgn = sgn;
        }
        // The links that hold for this ray, from the eye on (a little under one cell of gap
        // allows for the fixed-point tracks).
        double start = 0.0;
        int held = 0;
        for (; held < st.chainLength; ++held) {
            const ColumnState::Segment& g = st.chain[held];
            const double gap = std::max(std::abs(rn - g.rnLo), std::abs(rn - g.rnHi));
            if (!(rz >= g.rzHi) || !(gap * g.end <= 0.99)) break;
            start = g.end;
        }
        st.chainLength = held;
        if (start == 0.0) {
            // A new chain: worth it where this ray's track stays near the one below (not near the
            // nadir, where tracks fan out) and the march is short; it starts where the ray comes
            // down through the map's highest point.
            if (!cc.eg.inside || !(st.prevU <= kChainReach) ||
                !(std::abs(rn - st.prevRn) * st.prevU <= 0.99)) {
                return false;
            }
            const double dzr = rz * cc.mv->invScale;
            if (cc.eg.zRaw > cc.mv->maxRaw) {
                if (!(dzr < 0.0)) return false;
                start = (cc.eg.zRaw - cc.mv->maxRaw) / -dzr;
            }
        }
        const double clear =
            majorX ? clearanceScan<true>(*cc.mv, cc.eg, sgn, rn, rz, start, st.steps)
                   : clearanceScan<false>(*cc.mv, cc.eg, sgn, rn, rz, start, st.steps);
        if (clear > start) {
            if (st.chainLength == ColumnState::kChain) {
                // Full: the two oldest links become one covering both rays.
                ColumnState::Segment& a = st.chain[0];
                const ColumnState::Segment& b = st.chain[1];
                a = {std::min(a.rnLo, b.rnLo), std::max(a.rnHi, b.rnHi), std::max(a.rzHi, b.rzHi),
                     b.end};
                std::copy(st.chain + 2, st.chain + st.chainLength, st.chain + 1);
                --st.chainLength;
            }
            st.chain[st.chainLength++] = {rn, rn, rz, clear};
        }
        double uNear = std::numeric_limits<double>::infinity();
        if (cc.multires) uNear = cc.d0 / (std::sqrt(d.x * d.x + d.y * d.y) * inv);
        const ColumnMarch r =
            majorX ? marchCoherent<true>(*cc.mv, cc.eg, sgn, rn, rz, clear, uNear, st.steps)
                   : marchCoherent<false>(*cc.mv, cc.eg, sgn, rn, rz, clear, uNear, st.steps);
        return finishCoherent(cc, d, len, lenPerU, r, st, c, tHit);
    }

    // From u = uStart, the first step (its start u, not before uStart) where the ray comes down
    // to the largest cell maximum within one minor cell of the cells it crosses; where it
    // leaves the map or climbs over its highest point first, there. The step loop of
    // marchCoherent with the widened bound.
    template <bool kMajorX>
    static double clearanceScan(const MapView& mv, const EyeGrid& eg, int sgn, double rn, double rz,
                                double uStart, std::uint64_t& steps) {
        const std::uint16_t* __restrict__ cellMax = mv.cellMax;
        const std::ptrdiff_t stride = mv.width - 1;
        const int majorCount = kMajorX ? mv.width : mv.height;
        const int minorCount = kMajorX ? mv.height : mv.width;
        const int lastMinorCell = minorCount - 2;
        const double em = kMajorX ? eg.gx : eg.gy, en = kMajorX ? eg.gy : eg.gx;
        const double gm0 = em + sgn * uStart;
        const long m = sgn > 0 ? floorToLong(gm0) : -floorToLong(-gm0);
        if (m < 0 || m > majorCount - 1) return uStart;
        const double u = (m - em) * sgn;
        constexpr double kFix = 4294967296.0;  // 2^32
        std::int64_t n = roundToInt64((en + rn * u) * kFix);
        const std::int64_t dn = roundToInt64(rn * kFix);
        const std::int64_t minorLimit = static_cast<std::int64_t>(minorCount - 1) << 32;
        if (n < 0 || n > minorLimit) return uStart;
        const double dzr = rz * mv.invScale;
        const bool rising = dzr >= 0.0;
        double zLow = eg.zRaw + dzr * u + (rising ? 0.0 : dzr);
        const std::int64_t majorSteps = sgn > 0 ? majorCount - 1 - m : m;
        const std::ptrdiff_t minorStride = kMajorX ? stride : 1;
        for (std::int64_t k = 0; k < majorSteps; ++k) {
            const std::int64_t next = n + dn;
            if (static_cast<std::uint64_t>(next) > static_cast<std::uint64_t>(minorLimit)) {
                steps += static_cast<std::uint64_t>(k);
                return std::max(uStart, u + static_cast<double>(k));
            }
            const int ca = std::min(static_cast<int>(n >> 32), lastMinorCell);
            const int cb = std::min(static_cast<int>(next >> 32), lastMinorCell);
            const int lo = std::max(std::min(ca, cb) - 1, 0);
            const int hi = std::min(std::max(ca, cb) + 1, lastMinorCell);
            const std::ptrdiff_t mc = m + sgn * k + (sgn > 0 ? 0 : -1);
            const std::uint16_t* cell = cellMax + (kMajorX ? mc : mc * stride) +
                                        static_cast<std::ptrdiff_t>(lo) * minorStride;
            int bound = 0;
            for (int i = lo; i <= hi; ++i, cell += minorStride)
                bound = std::max(bound, static_cast<int>(*cell));
            if (zLow <= bound) {
                steps += static_cast<std::uint64_t>(k + 1);
                return std::max(uStart, u + static_cast<double>(k));
            }
            if (rising && zLow > mv.maxRaw) {
                // Over the map's highest point, climbing: clear to the end.
                steps += static_cast<std::uint64_t>(k + 1);
                return std::max(uStart, u + static_cast<double>(majorSteps));
            }
            n = next;
            zLow += dzr;
        }
        steps += static_cast<std::uint64_t>(majorSteps);
        return std::max(uStart, u + static_cast<double>(majorSteps));
    }

    // The outcome of a coherent march: colour, hit distance and the next start. False when the
    // march started outside the map (the ray must be cast fresh).
    [[gnu::always_inline]] bool finishCoherent(const ColumnContext& cc, const glm::dvec3& d,
                                               double len, double lenPerU, const ColumnMarch& r,
                                               ColumnState& st, Rgb8& c, double& tHit) const {
        if (r.kind == ColumnMarch::kHit) {
            tHit = r.u * lenPerU;
            float rgb[3];
            cellColor(*cc.mv, r.cx, r.cy, r.fx, r.fy, rgb);
            c = haze(rgb, tHit);
            st.prevU = r.u;
            return true;
        }
        if (r.kind == ColumnMarch::kStop || r.kind == ColumnMarch::kAbove) {
            c = skyColor(options_.sky, d.z / len);
            st.prevU = r.u;
            st.prevAbove = r.kind == ColumnMarch::kAbove;
            return true;
        }
        if (r.kind == ColumnMarch::kFar) {
            continueFar(cc, d, lenPerU, r, st, c, tHit);
            return true;
        }
        return false;
    }

    // A coherent ray that reached the level-0 distance: the multiresolution march from there.
    [[gnu::noinline]] void continueFar(const ColumnContext& cc, const glm::dvec3& d, double lenPerU,
                                       const ColumnMarch& r, ColumnState& st, Rgb8& c,
                                       double& tHit) const {
        const TerrainRay ray(map_, cc.eye, d);
        const double horiz = std::sqrt(ray.dir.x * ray.dir.x + ray.dir.y * ray.dir.y);
        double t0, t1;
        std::optional<LevelHit> hit;
        double tStop = 0.0;
        if (clipToMapBox(map_, ray, t0, t1)) {
            hit = castFrom(ray, horiz, cc.d0, std::max(t0, r.u * lenPerU), t1, st.steps);
            tStop = hit ? hit->t : t1;
        }
        if (hit) {
            tHit = hit->t;
            c = shadeLevelHit(*hit, ray.at(hit->t));
        } else {
            c = skyColor(options_.sky, ray.dir.z);
        }
        st.prevU = std::max(tStop / lenPerU, r.u);
    }

    ColumnContext columnContext(const MapView& mv, const Camera& camera, double d0, int x) const {
        const CameraBasis& b = camera.basis();
        const double focal = camera.intrinsics().focal;
        const glm::dvec3 eye = camera.pose().position;
        const double invSx = 1.0 / map_.spacingX(), invSy = 1.0 / map_.spacingY();
        const bool eyeInside =
            eye.x >= 0.0 && eye.y >= 0.0 && eye.x <= map_.extentX() && eye.y <= map_.extentY();
        return ColumnContext{&mv,
                             focal * b.forward + (x + 0.5 - camera.intrinsics().cx()) * b.right +
                                 camera.intrinsics().cy() * b.up,
                             -b.up,
                             eye,
                             EyeGrid{eye.x * invSx, eye.y * invSy, eye.z, eyeInside,
                                     (eye.z - mv.offset) * mv.invScale},
                             d0,
                             invSx,
                             invSy,
                             map_.maxSlope(),
                             map_.spacingX(),
                             map_.spacingY(),
                             topLevel_ > 0};
    }

    // One column of the multiresolution caster, bottom to top: kLanes rays at a time (eight with
    // AVX-512, with four where eight do not go; four with AVX2; 0: none) where they are
    // coherent with the ray below them, else one by one. With kSuper, the supersample rays of
    // each pixel are stacked in the column (as renderColumn casts them) and averaged, the depth
    // the nearest.
    template <bool kSuper, int kLanes>
    void renderLinearColumn(const MapView& mv, const Camera& camera, double d0, int x,
                            RenderedFrame& frame, UnitCounters& counters) const {
        const int w = camera.intrinsics().width, h = camera.intrinsics().height;
        const int sub = kSuper ? options_.supersample : 1;
        const double subStep = 1.0 / sub;
        const ColumnContext cc = columnContext(mv, camera, d0, x);
        ColumnState st;
        startColumn(camera, cc, st);
        Rgb8* colorOut = frame.color.data() + x;
        float* depthOut = frame.depth.data() + x;
        // Ray v of the column (from the top) runs through image row y + (s + 0.5) / sub,
        // v = y * sub + s.
        auto rowOf = [&](int v) {
            if constexpr (kSuper) return (v / sub) + ((v % sub) + 0.5) * subStep;
            return v + 0.5;
        };
        int sum[3] = {0, 0, 0};
        float nearest = kSkyDepth;
        auto put = [&](int v, Rgb8 c, double tHit) {
            if constexpr (kSuper) {
                if (tHit >= 0.0) nearest = std::min(nearest, static_cast<float>(tHit));
                sum[0] += c.r;
                sum[1] += c.g;
                sum[2] += c.b;
                if (v % sub != 0) return;
                const std::size_t idx = static_cast<std::size_t>(v / sub) * w;
                const int half = sub / 2;
                colorOut[idx] = Rgb8{static_cast<std::uint8_t>((sum[0] + half) / sub),
                                     static_cast<std::uint8_t>((sum[1] + half) / sub),
                                     static_cast<std::uint8_t>((sum[2] + half) / sub)};
                depthOut[idx] = nearest;
                sum[0] = sum[1] = sum[2] = 0;
                nearest = kSkyDepth;
            } else {
                const std::size_t idx = static_cast<std::size_t>(v) * w;
                colorOut[idx] = c;
                depthOut[idx] = tHit >= 0.0 ? static_cast<float>(tHit) : kSkyDepth;
            }
        };
#if VIG_CASTER_PACKETS
        constexpr bool rows = kLanes >= 4;
        constexpr bool wide = kLanes == 8;
#endif
        const int rays = h * sub;
        int single = 0;  // rays to cast one by one before trying a batch again
        for (int v = rays - 1; v >= 0;) {
#if VIG_CASTER_PACKETS
            // Sky above the map's highest point goes in batches again.
            if (single > 0 && st.prevAbove) single = 0;
            if (!kSuper && rows && single == 0 && v >= 3 && st.havePrev) {
                // Batches run inside the vector code, as many at a time as go.
                RowsOutcome r = RowsOutcome::kOther;
                bool tried = false;
#if VIG_CASTER_WIDE
                if (wide && v >= 7) {
                    v = rowsWide_.run(rows_, cc, st, v, rays, colorOut, depthOut,
                                      static_cast<std::size_t>(w), r);
                    tried = r != RowsOutcome::kOther;
                }
#endif
                // Where eight do not go together (or fewer are left), four may: one batch.
                if (!tried && v >= 3) {
                    v = rowsNarrow_.run(rows_, cc, st, v, wide ? 1 : rays, colorOut, depthOut,
                                        static_cast<std::size_t>(w), r);
                }
                if (r == RowsOutcome::kDone) continue;
                if (r == RowsOutcome::kFar) {
                    // Every ray above starts past the level-0 distance too.
                    single = rays;
                } else {
                    single = 4;
                }
            }
            if (kSuper && rows && single == 0 && v >= 3 && st.havePrev) {
                // The supersample rays of the pixels, stacked in the column, a batch at a time.
                Rgb8 c[8];
                double tHit[8];
                int n = 4;
                RowsOutcome r = RowsOutcome::kOther;
#if VIG_CASTER_WIDE
                if (wide && v >= 7) {
                    n = 8;
                    double yy[8];
                    for (int l = 0; l < 8; ++l)
                        yy[l] = rowOf(v - l);
                    r = rowsWide_.cast(rows_, cc, st, yy, c, tHit);
                    // Where eight do not go together, four may.
                    if (r == RowsOutcome::kOther) n = 4;
                }
#endif
                if (n == 4) {
                    const double yy[4] = {rowOf(v), rowOf(v - 1), rowOf(v - 2), rowOf(v - 3)};
                    r = rowsNarrow_.cast(rows_, cc, st, yy, c, tHit);
                }
                if (r == RowsOutcome::kFar) {
                    // Every ray above starts past the level-0 distance too.
                    single = rays;
                } else if (r == RowsOutcome::kOther) {
                    single = 4;
                } else {
                    for (int l = 0; l < n; ++l)
                        put(v - l, c[l], tHit[l]);
                    v -= n;
                    continue;
                }
            }
            if (single > 0) --single;
#endif
            const glm::dvec3 d = cc.base + rowOf(v) * cc.down;
            Rgb8 c;
            double tHit = -1.0;
            if (!linearRay(cc, d, st, c, tHit)) castRay(cc, d, st, c, tHit);
            put(v, c, tHit);
            --v;
        }
        counters.steps += st.steps;
        counters.restarts += st.restarts;
    }

    void renderColumnUnit(const MapView& mv, const Camera& camera, double d0, int x,
                          RenderedFrame& frame, UnitCounters& counters) const {
        renderColumn(mv, camera, d0, x, frame, counters);
    }

#if VIG_CASTER_PACKETS
    // Four adjacent columns with AVX2 (the image's last columns one at a time).
    void renderPacketUnit(const MapView& mv, const Camera& camera, double d0, int unit,
                          RenderedFrame& frame, UnitCounters& counters) const {
        const int w = camera.intrinsics().width;
        const int x0 = 4 * unit;
        if (x0 + 4 <= w) {
            renderPacket(mv, camera, d0, x0, frame, counters);
        } else {
            for (int x = x0; x < w; ++x)
                renderColumn(mv, camera, d0, x, frame, counters);
        }
    }
#endif

    // One column of the single-level caster, bottom to top, the supersample rays of a pixel
    // stacked inside it and averaged (depth: the nearest).
    void renderColumn(const MapView& mv, const Camera& camera, double d0, int x,
                      RenderedFrame& frame, UnitCounters& counters) const {
        const int w = camera.intrinsics().width, h = camera.intrinsics().height;
        const ColumnContext cc = columnContext(mv, camera, d0, x);
        ColumnState st;
        startColumn(camera, cc, st);
        Rgb8* colorOut = frame.color.data() + x;
        float* depthOut = frame.depth.data() + x;
        const int sub = options_.supersample;
        const double subStep = 1.0 / sub;
        for (int y = h - 1; y >= 0; --y) {
            int sum[3] = {0, 0, 0};
            float nearest = kSkyDepth;
            for (int s = sub - 1; s >= 0; --s) {
                const glm::dvec3 d = cc.base + (y + (s + 0.5) * subStep) * cc.down;
                Rgb8 c;
                double tHit = -1.0;
                castRay(cc, d, st, c, tHit);
                if (tHit >= 0.0) nearest = std::min(nearest, static_cast<float>(tHit));
                sum[0] += c.r;
                sum[1] += c.g;
                sum[2] += c.b;
            }
            const std::size_t idx = static_cast<std::size_t>(y) * w;
            const int half = sub / 2;
            colorOut[idx] = Rgb8{static_cast<std::uint8_t>((sum[0] + half) / sub),
                                 static_cast<std::uint8_t>((sum[1] + half) / sub),
                                 static_cast<std::uint8_t>((sum[2] + half) / sub)};
            depthOut[idx] = nearest;
        }
        counters.steps += st.steps;
        counters.restarts += st.restarts;
    }

#if VIG_CASTER_PACKETS
    // Four adjacent columns cast together, row by row, with AVX2: the rays' set-up, the
    // coherent march's set-up, the exact solve of the steps they reach and the colour run on
    // four lanes; each lane's bound scan is its own scalar loop. A row is cast this way when all
    // four rays are coherent on the same major axis and direction. A lane that ends without a
    // hit (past the map's far edge, over its highest point) ends here too, one that reaches
    // the level-0 distance goes on into the multiresolution march; one that leaves through a
    // minor side of the map is cast again from its unchanged state by castRay, as are the rows
    // where some ray is not coherent (bottom ray, restart, sky above the map's top). Every
    // operation is the scalar path's, in the same order and precision (no fused multiply-add),
    // so the image is bit for bit the one column at a time gives.
    // One lane's bound scan (marchCoherent's inner loop) from step k on, and how it ended.
    struct LaneScan {
        std::int64_t n, dn;  // minor coordinate at the step's start (32.32) and per step
        double zLow, dzr;    // the step's lowest ray height and its change per step (raw)
        std::ptrdiff_t ia;   // cell-max index of the step's first cell
        int ca;              // its minor cell
        std::int64_t k, total;
        // Of the reached step: its second cell and the next step's minor coordinate.
        int cb;
        std::ptrdiff_t ib;
        std::int64_t next;
    };
    enum class ScanEnd { kReach, kLeave, kExhausted, kClimb };

    template <bool kMajorX>
    [[gnu::always_inline]] static ScanEnd scanLane(const MapView& mv, LaneScan& q,
                                                   std::int64_t minorLimit, int lastMinorCell,
                                                   std::ptrdiff_t minorStride,
                                                   std::ptrdiff_t majorStep) {
        const std::uint16_t* __restrict__ cellMax = mv.cellMax;
        const bool rising = q.dzr >= 0.0;
        std::int64_t n = q.n, k = q.k;
        std::ptrdiff_t ia = q.ia;
        int ca = q.ca;
        double zLow = q.zLow;
        ScanEnd end = ScanEnd::kExhausted;
        for (; k < q.total; ++k) {
            const std::int64_t next = n + q.dn;
            if (static_cast<std::uint64_t>(next) > static_cast<std::uint64_t>(minorLimit)) {
                end = ScanEnd::kLeave;
                break;
            }
            const int cb = std::min(static_cast<int>(next >> 32), lastMinorCell);
            const std::ptrdiff_t ib = ia + (cb - ca) * minorStride;
            if (zLow <= std::max(cellMax[ia], cellMax[ib])) {
                q.cb = cb;
                q.ib = ib;
                q.next = next;
                end = ScanEnd::kReach;
                break;
            }
            if (rising && zLow > mv.maxRaw) {
                end = ScanEnd::kClimb;
                break;
            }
            n = next;
            ca = cb;
            ia = ib + majorStep;
            zLow += q.dzr;
        }
        q.n = n;
        q.k = k;
        q.ia = ia;
        q.ca = ca;
        q.zLow = zLow;
        return end;
    }

    // roundToInt64 on four lanes, as an integer-valued double (exact below 2^53).
    [[gnu::always_inline]] VIG_CASTER_AVX2 static V4 vroundAway(V4 v) {
        const V4 h = v >= 0.0 ? v + 0.5 : v - 0.5;
        return reinterpret_cast<V4>(
            _mm256_round_pd(reinterpret_cast<__m256d>(h), _MM_FROUND_TO_ZERO | _MM_FROUND_NO_EXC));
    }
    // Two adjacent 16-bit samples at idx and idx + 1, four lanes.
    [[gnu::always_inline]] VIG_CASTER_AVX2 static void gatherPair(const std::uint16_t* base, V4 idx,
                                                                  V4& first, V4& second) {
        const __m128i g = gather32<2>(base, idx);
        first = toV4(_mm_and_si128(g, _mm_set1_epi32(0xFFFF)));
        second = toV4(_mm_srli_epi32(g, 16));
    }

    // solveBilinear on four lanes, the same operations in the same order.
    [[gnu::always_inline]] VIG_CASTER_AVX2 static V4 solveBilinear4(V4 h00, V4 h10, V4 h01, V4 h11,
                                                                    V4 ua, V4 va, V4 du, V4 dv,
                                                                    V4 za, V4 dz, V4 len) {
        const V4 a = h10 - h00, b = h01 - h00, c = h00 - h10 - h01 + h11;
        const V4 C = za - (h00 + a * ua + b * va + c * ua * va);
        const V4 B = dz - (a * du + b * dv + c * (ua * dv + va * du));
        const V4 A = -c * du * dv;
        const V4 disc = B * B - 4.0 * A * C;
        const V4 zero = V4{} + 0.0;
        const V4 sq = vsqrt(vmax(disc, zero));
        // One division: C / (0.5 * (sq - B)) where B < 0, (-0.5 * (B + sq)) / A elsewhere.
        const M4 negB = B < 0.0;
        const V4 root0 = (negB ? C : -0.5 * (B + sq)) / (negB ? 0.5 * (sq - B) : A);
        V4 root = zero - 1.0;
        root = disc >= 0.0 && (negB || A < 0.0) ? root0 : root;
        const V4 endHit = C + B * len + A * len * len <= 0.0 ? len : zero - 1.0;
        root = root >= 0.0 && root <= len ? root : endHit;
        return C <= 0.0 ? zero : root;
    }

    // What a lane's march is about.
    struct PacketRay {
        V4 sgn, rn, rzr;  // major sign, minor cells and raw height per major unit
        double ezr;       // eye height, raw units
    };

    // StepSolver::piece on the lanes in `active`: the piece [s0, s1] of the step from major
    // line m (major cell mc) in minor cell cn; sets `got` and the hit (u, cell, local
    // coordinates) of the lanes whose piece meets the surface.
    template <bool kMajorX>
    [[gnu::always_inline]] VIG_CASTER_AVX2 static void piece4(
        const MapView& mv, const PacketRay& ray, M4 active, M4 ownBound, V4 m, V4 mc, V4 cn, V4 n,
        V4 u, V4 s0, V4 s1, M4& got, V4& outU, V4& outCx, V4& outCy, V4& outFx, V4& outFy) {
        active = active && s0 < s1;
        if (!vmask(active)) return;
        const V4 cx = kMajorX ? mc : cn, cy = kMajorX ? cn : mc;
        const V4 zero = V4{} + 0.0;
        const V4 cell = active ? cy * static_cast<double>(mv.width) + cx : zero;
        V4 h00, h10, h01, h11;
        gatherPair(mv.heights, cell, h00, h10);
        gatherPair(mv.heights, cell + static_cast<double>(mv.width), h01, h11);
        const V4 za = ray.ezr + ray.rzr * (u + s0);
        if (vmask(ownBound)) {
            const V4 bound = toV4(_mm_and_si128(
                gather32<2>(mv.cellMax,
                            active ? cy * static_cast<double>(mv.width - 1) + cx : zero),
                _mm_set1_epi32(0xFFFF)));
            const V4 zLow = ray.rzr >= 0.0 ? za : za + ray.rzr * (s1 - s0);
            active = active && !(ownBound && zLow > bound);
        }
        const V4 nD = n * (1.0 / 4294967296.0);
        const V4 majorLocal = m - mc;
        const V4 am = majorLocal + ray.sgn * s0, an = nD + ray.rn * s0 - cn;
        const V4 r =
            kMajorX
                ? solveBilinear4(h00, h10, h01, h11, am, an, ray.sgn, ray.rn, za, ray.rzr, s1 - s0)
                : solveBilinear4(h00, h10, h01, h11, an, am, ray.rn, ray.sgn, za, ray.rzr, s1 - s0);
        const M4 hit = active && r >= 0.0;
        const V4 sh = s0 + r;
        const V4 fm = majorLocal + ray.sgn * sh, fn = nD + ray.rn * sh - cn;
        outU = hit ? u + sh : outU;
        outCx = hit ? cx : outCx;
        outCy = hit ? cy : outCy;
        outFx = hit ? (kMajorX ? fm : fn) : outFx;
        outFy = hit ? (kMajorX ? fn : fm) : outFy;
        got = got || hit;
    }

    // Casts row y of the four columns where it can (see above); `done[l]` tells which lanes it
    // cast. The state of the other lanes is untouched.
    template <bool kMajorX>
    VIG_CASTER_AVX2 void packetRow(const ColumnContext* cc, ColumnState* st, V4 dx, V4 dy, V4 dz,
                                   V4 len, int sgnI, Rgb8* c, double* tHit, bool* done) const {
        const MapView& mv = *cc[0].mv;
        const EyeGrid& eg = cc[0].eg;
        const V4 zero = V4{} + 0.0, one = V4{} + 1.0;
        const V4 sgn = zero + static_cast<double>(sgnI);
        const V4 gx = dx * cc[0].invSx, gy = dy * cc[0].invSy;
        const V4 gm = kMajorX ? gx : gy, gn = kMajorX ? gy : gx;
        const V4 inv = 1.0 / (gm < 0.0 ? -gm : gm);
        const V4 rn = gn * inv, rz = dz * inv;
        V4 prevRn, prevRz, prevU;
        for (int l = 0; l < 4; ++l) {
            prevRn[l] = st[l].prevRn;
            prevRz[l] = st[l].prevRz;
            prevU[l] = st[l].prevU;
            done[l] = false;
        }
        const V4 dRn = rn - prevRn;
        const double sMinor = kMajorX ? cc[0].spacingY : cc[0].spacingX;
        M4 coherent;
        testClimb(V4(rz - prevRz), cc[0].maxSlope, sMinor, V4(dRn < 0.0 ? -dRn : dRn), coherent);
        if (vmask(coherent) != 15) {
            for (int l = 0; l < 4; ++l)
                coherent[l] = climbsClear(cc[l], st[l], kMajorX, rn[l], rz[l]) ? -1 : 0;
        }
        V4 uNear = zero + std::numeric_limits<double>::infinity();
        if (cc[0].multires) uNear = cc[0].d0 / (vsqrt(dx * dx + dy * dy) * inv);
        // marchCoherent's set-up.
        const int majorCount = kMajorX ? mv.width : mv.height;
        const int minorCount = kMajorX ? mv.height : mv.width;
        const double lastMinorCell = minorCount - 2;
        const double em = kMajorX ? eg.gx : eg.gy, en = kMajorX ? eg.gy : eg.gx;
        const V4 gm0 = em + sgn * prevU;
        const V4 fl = vfloor(sgnI > 0 ? gm0 : -gm0);
        const V4 m = sgnI > 0 ? fl : -fl;
        const V4 u = (m - em) * sgn;
        constexpr double kFix = 4294967296.0, kInvFix = 1.0 / 4294967296.0;
        V4 n = vroundAway((en + rn * u) * kFix);
        const V4 dn = vroundAway(rn * kFix);
        const double minorLimit = (minorCount - 1.0) * kFix;
        const V4 dzr = rz * mv.invScale;
        const V4 zr = eg.zRaw + dzr * u;
        const M4 ok = coherent && m >= 0.0 && m <= majorCount - 1.0 && n >= 0.0 && n <= minorLimit;
        if (!vmask(ok)) return;
        const V4 majorSteps = sgnI > 0 ? majorCount - 1.0 - m : m;
        const V4 nearSteps = uNear < 1e12 ? vmax(zero, -vfloor(u - uNear)) : zero + 1099511627776.0;
        const V4 total = vmin(majorSteps, nearSteps);
        const M4 far = total == nearSteps && nearSteps < majorSteps + 1.0;
        const V4 mc0 = m + (sgnI > 0 ? 0.0 : -1.0);
        const V4 sBegin0 = prevU - u;
        const V4 zLow = dzr >= 0.0 ? zr : zr + dzr;
        const double stride = mv.width - 1.0;
        const double minorStride = kMajorX ? stride : 1.0;
        const double majorStep = kMajorX ? sgnI : sgnI * stride;
        const V4 ca0 = vmin(vfloor(n * kInvFix), zero + lastMinorCell);
        const V4 ia0 = kMajorX ? ca0 * stride + mc0 : mc0 * stride + ca0;
        const PacketRay ray{sgn, rn, dzr, eg.zRaw};
        M4 failed = !ok, hit = {}, stop = {}, above = {}, farEnd = {};
        V4 endU = zero;  // where a lane that ended without a hit (sky) ended
        V4 hitU = zero, hitCx = zero, hitCy = zero, hitFx = zero, hitFy = zero;
        V4 stepsV = zero;
        // The bound scan runs per lane (scalar loops of a few instructions a step keep the
        // processor busier than masked lock step); the solve of the reached steps on four lanes.
        LaneScan lane[4];
        bool pending[4];
        const int okMask = vmask(ok);
        for (int l = 0; l < 4; ++l) {
            pending[l] = (okMask >> l) & 1;
            lane[l] = LaneScan{static_cast<std::int64_t>(n[l]),
                               static_cast<std::int64_t>(dn[l]),
                               zLow[l],
                               dzr[l],
                               static_cast<std::ptrdiff_t>(ia0[l]),
                               static_cast<int>(ca0[l]),
                               0,
                               static_cast<std::int64_t>(total[l]),
                               0,
                               0,
                               0};
        }
        const auto limit = static_cast<std::int64_t>(minorCount - 1) << 32;
        const auto mStride = static_cast<std::ptrdiff_t>(minorStride);
        const auto mStep = static_cast<std::ptrdiff_t>(majorStep);
        for (;;) {
            M4 parked = {};
            for (int l = 0; l < 4; ++l) {
                if (!pending[l]) continue;
                LaneScan& q = lane[l];
                const ScanEnd e = scanLane<kMajorX>(mv, q, limit, static_cast<int>(lastMinorCell),
                                                    mStride, mStep);
                pending[l] = false;
                if (e == ScanEnd::kReach) {
                    parked[l] = -1;
                    continue;
                }
                if (e == ScanEnd::kLeave) {
                    failed[l] = -1;
                } else if (e == ScanEnd::kExhausted && far[l]) {
                    // Reached the level-0 distance: the multiresolution march goes on from there.
                    farEnd[l] = -1;
                    endU[l] = u[l] + static_cast<double>(q.k);
                    stepsV[l] = static_cast<double>(q.k);
                } else {
                    endU[l] = u[l] + static_cast<double>(q.k);
                    stepsV[l] = static_cast<double>(e == ScanEnd::kClimb ? q.k + 1 : q.k);
                    (e == ScanEnd::kClimb ? above : stop)[l] = -1;
                }
            }
            if (!vmask(parked)) break;
            // The exact solve of each parked lane's step (StepSolver::solve).
            V4 k, ns, ca, cb;
            for (int l = 0; l < 4; ++l) {
                k[l] = static_cast<double>(lane[l].k);
                ns[l] = static_cast<double>(lane[l].n);
                ca[l] = lane[l].ca;
                cb[l] = lane[l].cb;
            }
            const V4 mK = m + sgn * k;
            const V4 mcK = mc0 + sgn * k;
            const V4 uK = u + k;
            const V4 sBegin = k == 0.0 ? sBegin0 : zero;
            const M4 split = ca != cb;
            const V4 nD = ns * kInvFix;
            const V4 line = ca < cb ? cb : ca;
            const V4 sSplit = vclamp01((line - nD) / rn);
            M4 got = {};
            piece4<kMajorX>(mv, ray, parked, split, mK, mcK, ca, ns, uK,
                            split ? vmax(sBegin, zero) : sBegin, split ? sSplit : one, got, hitU,
                            hitCx, hitCy, hitFx, hitFy);
            piece4<kMajorX>(mv, ray, parked && split && !got, split, mK, mcK, cb, ns, uK,
                            vmax(sBegin, sSplit), one, got, hitU, hitCx, hitCy, hitFx, hitFy);
            hit = hit || got;
            stepsV = got ? k + 1.0 : stepsV;
            // A lane whose step held no hit scans on from the next step.
            for (int l = 0; l < 4; ++l) {
                if (!parked[l] || got[l]) continue;
                LaneScan& q = lane[l];
                q.n = q.next;
                q.ca = q.cb;
                q.ia = q.ib + mStep;
                q.zLow += q.dzr;
                ++q.k;
                pending[l] = true;
            }
        }
        const int hitMask = vmask(hit), stopMask = vmask(stop || above), aboveMask = vmask(above);
        const int failMask = vmask(failed), farMask = vmask(farEnd);
        V4 rgb[3];
        if (hitMask) {
            cellColors(mv, hit ? hitCx : zero, hit ? hitCy : zero, hitFx, hitFy, rgb);
        }
        const V4 lenPerU = len * inv;
        for (int l = 0; l < 4; ++l) {
            if ((failMask >> l) & 1) continue;
            ColumnState& q = st[l];
            q.steps += static_cast<std::uint64_t>(stepsV[l]);
            q.prevRn = rn[l];
            q.prevRz = rz[l];
            if ((hitMask >> l) & 1) {
                tHit[l] = hitU[l] * lenPerU[l];
                float f[3] = {static_cast<float>(rgb[0][l]), static_cast<float>(rgb[1][l]),
                              static_cast<float>(rgb[2][l])};
                c[l] = haze(f, tHit[l]);
                q.prevU = hitU[l];
            } else if ((stopMask >> l) & 1) {
                c[l] = skyColor(options_.sky, dz[l] / len[l]);
                q.prevU = endU[l];
                q.prevAbove = (aboveMask >> l) & 1;
            } else if ((farMask >> l) & 1) {
                ColumnMarch r;
                r.kind = ColumnMarch::kFar;
                r.u = endU[l];
                continueFar(cc[l], glm::dvec3{dx[l], dy[l], dz[l]}, lenPerU[l], r, q, c[l],
                            tHit[l]);
            }
            done[l] = true;
        }
    }

    VIG_CASTER_AVX2 void renderPacket(const MapView& mv, const Camera& camera, double d0, int x0,
                                      RenderedFrame& frame, UnitCounters& counters) const {
        const int w = camera.intrinsics().width, h = camera.intrinsics().height;
        ColumnContext cc[4];
        ColumnState st[4];
        V4 bx, by, bz;
        for (int l = 0; l < 4; ++l) {
            cc[l] = columnContext(mv, camera, d0, x0 + l);
            startColumn(camera, cc[l], st[l]);
            bx[l] = cc[l].base.x;
            by[l] = cc[l].base.y;
            bz[l] = cc[l].base.z;
        }
        const glm::dvec3 down = cc[0].down;
        for (int y = h - 1; y >= 0; --y) {
            const double yy = y + 0.5;
            const V4 dx = bx + yy * down.x, dy = by + yy * down.y, dz = bz + yy * down.z;
            const V4 len = vsqrt(dx * dx + dy * dy + dz * dz);
            const V4 gx = dx * cc[0].invSx, gy = dy * cc[0].invSy;
            const M4 majorX = (gx < 0.0 ? -gx : gx) >= (gy < 0.0 ? -gy : gy);
            const int mx = vmask(majorX);
            const V4 gm = majorX ? gx : gy;
            const int pos = vmask(gm > 0.0);
            const int big = vmask((gm < 0.0 ? -gm : gm) > 1e-9 * len);
            Rgb8 c[4];
            double tHit[4] = {-1.0, -1.0, -1.0, -1.0};
            bool done[4] = {false, false, false, false};
            bool lanesOk = (mx == 0 || mx == 15) && (pos == 0 || pos == 15) && big == 15;
            for (int l = 0; l < 4 && lanesOk; ++l) {
                lanesOk = st[l].havePrev && !st[l].prevAbove && st[l].prevMajorX == (mx == 15) &&
                          st[l].prevSgn == (pos == 15 ? 1 : -1);
            }
            if (lanesOk) {
                if (mx == 15) {
                    packetRow<true>(cc, st, dx, dy, dz, len, pos == 15 ? 1 : -1, c, tHit, done);
                } else {
                    packetRow<false>(cc, st, dx, dy, dz, len, pos == 15 ? 1 : -1, c, tHit, done);
                }
            }
            const std::size_t row = static_cast<std::size_t>(y) * w + x0;
            for (int l = 0; l < 4; ++l) {
                if (!done[l]) {
                    const glm::dvec3 d = cc[l].base + yy * cc[l].down;
                    castRay(cc[l], d, st[l], c[l], tHit[l]);
                }
                frame.color[row + l] = c[l];
                frame.depth[row + l] = tHit[l] >= 0.0 ? static_cast<float>(tHit[l]) : kSkyDepth;
            }
        }
        for (int l = 0; l < 4; ++l) {
            counters.steps += st[l].steps;
            counters.restarts += st[l].restarts;
        }
    }
#endif

    const TerrainMap& map_;
    RenderOptions options_;
    CasterKernel kernel_ = CasterKernel::Scalar;  // the kernel that runs (chooseKernel)
    UnitRenderer renderUnit_ = nullptr;
    int columnsPerUnit_ = 1;
    std::shared_ptr<const TerrainPyramid> pyramid_;
    std::unique_ptr<SlopeBlocks> slopes_;
    int topLevel_ = 0;
    std::optional<FarMarch> far_;      // the multiresolution march past the level-0 distance
    RowsCaster rows_{};                // what the row batches read of this caster
    RowKernel rowsNarrow_, rowsWide_;  // four and eight lanes (chooseKernel)
};

}  // namespace

std::unique_ptr<Caster> makeFastCaster(const TerrainMap& map, const RenderOptions& options,
                                       std::shared_ptr<const TerrainPyramid> pyramid) {
    return std::make_unique<FastCaster>(map, options, std::move(pyramid));
}

}  // namespace ig
