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
//
// This file holds the class (caster_fast.hpp), the kernel choice, the render loop and the
// one-ray paths; the four-column packets are in caster_packets.cpp, the march past the level-0
// distance in far_march.cpp, the row batches in caster_rows.hpp (one object per instruction
// set: caster_rows_avx2.cpp, caster_rows_avx512.cpp).
#include "ig/caster_fast.hpp"
#include "base/check.hpp"
#include "base/cpu_features.hpp"
#include "ig/caster_impl.hpp"
#include "ig/coherence.hpp"
#include "ig/error.hpp"
#include "ig/grid_march.hpp"
#include "ig/level0_march.hpp"
#include "ig/multires_march.hpp"
#include "ig/near_clip.hpp"
#include "ig/node_skip.hpp"
#include "ig/object_pass.hpp"
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

// (fast_column.hpp) Out of line, for the row batches; the caster's own paths inline it.
bool climbsClear(const ColumnContext& cc, ColumnState& st, bool majorX, double rn, double rz) {
    return FastCaster::climbsClear(cc, st, majorX, rn, rz);
}

namespace {

// A restarted ray descends the max-height pyramid only when its way through the map box spans
// more cells than this; shorter ones (near the nadir) are cheaper to march.
constexpr double kSkipMinCells = 16.0;

}  // namespace

FastCaster::FastCaster(const TerrainMap& map, const RenderOptions& options,
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
    if (!pyramid) pyramid = options_.pyramid;
    pyramid_ =
        pyramid ? std::move(pyramid) : std::make_shared<const TerrainPyramid>(map, options_.levels);
    CHECK(&pyramid_->map() == &map) << "the pyramid is another map's";
    topLevel_ = pyramid_->levelCount() - 1;
    slopes_ = options_.slopes ? options_.slopes : std::make_shared<const SlopeBlocks>(map);
    far_.emplace(map_, *pyramid_, options_.sky);
    rows_ = RowsCaster{&options_.sky, pyramid_.get(), options_.skipNodes, &*far_};
}

void FastCaster::render(const Camera& camera, RenderedFrame& frame) const {
    checkRoll(camera);
    const int units = workUnits(camera);
    tbb::combinable<UnitCounters> counters;
    frame.objectId.clear();  // the units draw terrain; the objects follow in one pass
    runWithThreads(options_.threads, [&] {
        // The image is a pool of columns (or groups of four); idle workers take the next.
        // Each is independent, so the image does not depend on the thread count.
        tbb::parallel_for(0, units,
                          [&](int unit) { renderUnit(camera, frame, unit, counters.local()); });
        drawObjectsOverTerrain(options_.objects, options_.sky, camera, frame);
    });
    const UnitCounters total = counters.combine([](UnitCounters a, UnitCounters b) {
        return UnitCounters{a.steps + b.steps, a.restarts + b.restarts};
    });
    frame.stats.steps = total.steps;
    frame.stats.restarts = total.restarts;
    frame.stats.rays = static_cast<std::uint64_t>(camera.intrinsics().width) *
                       camera.intrinsics().height *
                       static_cast<std::uint64_t>(options_.supersample);
    finishFrame(camera, frame);
}

void FastCaster::finishFrame(const Camera& camera, RenderedFrame& frame) const {
    // The levels renderUnit's march draws at each distance.
    const LevelBands bands{
        topLevel_ > 0 ? camera.intrinsics().lodFocal() * std::max(map_.spacingX(), map_.spacingY())
                      : std::numeric_limits<double>::infinity(),
        topLevel_};
    finishPasses(map_, options_, bands, camera, frame);
}

int FastCaster::workUnits(const Camera& camera) const {
    const int w = camera.intrinsics().width;
    return (w + columnsPerUnit_ - 1) / columnsPerUnit_;
}

std::pair<int, int> FastCaster::unitColumns(const Camera& camera, int unit) const {
    const int w = camera.intrinsics().width;
    return {columnsPerUnit_ * unit, std::min(columnsPerUnit_ * (unit + 1), w)};
}

void FastCaster::renderUnit(const Camera& camera, RenderedFrame& frame, int unit,
                            UnitCounters& counters) const {
    checkRoll(camera);
    // Level 0 is used out to where a voxel spans one pixel across the view.
    const double d0 =
        topLevel_ > 0 ? camera.intrinsics().lodFocal() * std::max(map_.spacingX(), map_.spacingY())
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
    if (!options_.objects.empty() && !frame.objectId.empty()) {  // a frame drawn by units
        const auto [x0, x1] = unitColumns(camera, unit);
        drawObjects(options_.objects, options_.sky, camera, frame, x0, x1, false);
    }
}

void FastCaster::chooseKernel() {
    CasterKernel k = options_.kernel;
    const bool portable = k == CasterKernel::Rows4Portable || k == CasterKernel::Rows8Portable;
    if (k == CasterKernel::Auto) {
        const base::CpuFeatures& cpu = base::cpuFeatures();
        k = !VIG_CASTER_PACKETS             ? CasterKernel::Scalar
            : VIG_CASTER_WIDE && cpu.avx512 ? CasterKernel::Avx512
            : cpu.avx2                      ? CasterKernel::Avx2
                                            : CasterKernel::Scalar;
    } else if (k != CasterKernel::Scalar) {
        std::string missing = casterKernelMissing(k);
        if (!portable && !VIG_CASTER_PACKETS) missing = "this build's vector code (x86-64 only)";
        if (portable && !VIG_CASTER_ROWS) missing = "this build's vector types (GCC or Clang)";
        if (!missing.empty()) {
            throw InputError("kernel " + std::string(casterKernelName(k)) +
                             ": the processor lacks " + missing);
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
        // lanes with AVX2; eight with AVX-512, and four where eight do not go. Their portable
        // twins the same, on lanes compiled for no instruction set.
#if VIG_CASTER_ROWS
        if (k == CasterKernel::Rows4Portable || k == CasterKernel::Rows8Portable) {
            rowsNarrow_ = rows_portable::kernel4();
            CHECK(rowsNarrow_.lanes == 4) << "this build lacks the portable row batches";
        }
        if (k == CasterKernel::Rows8Portable) {
            rowsWide_ = rows_portable::kernel8();
            CHECK(rowsWide_.lanes == 8) << "this build lacks the portable row batches";
        }
        if (portable) {
            kernel_ = k;
            const bool wide = k == CasterKernel::Rows8Portable;
            renderUnit_ = super  ? (wide ? &FastCaster::renderLinearColumn<true, 8>
                                         : &FastCaster::renderLinearColumn<true, 4>)
                          : wide ? &FastCaster::renderLinearColumn<false, 8>
                                 : &FastCaster::renderLinearColumn<false, 4>;
        }
#endif
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
    // The single level has four-column packets (AVX2) only, for one ray per pixel (their twin
    // is the scalar kernel, which the portable kernels run there).
    if ((k == CasterKernel::Avx2 || k == CasterKernel::Avx512) && !super) {
        kernel_ = CasterKernel::Avx2;
        renderUnit_ = &FastCaster::renderPacketUnit;
        columnsPerUnit_ = 4;
    }
#endif
}

[[gnu::always_inline]] inline FastCaster::FreshCast FastCaster::castFresh(
    const TerrainRay& ray, double horiz, double d0, bool bottom, std::uint64_t& steps) const {
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

inline std::optional<LevelHit> FastCaster::castFrom(const TerrainRay& ray, double horiz, double d0,
                                                    double tStart, double t1,
                                                    std::uint64_t& steps) const {
    const double tNear = horiz > 0.0 ? d0 / horiz : t1;
    if (tStart < tNear) {
        const double t = marchRay(map_, ray, tStart, std::min(tNear, t1), steps);
        if (t >= 0.0) return LevelHit{t, -1, 0.0};  // level 0, colour from the map
    }
    if (tNear < t1) {
        const LevelHit hit =
            marchLevels(*pyramid_, ray, horiz, d0, topLevel_, std::max(tStart, tNear), t1, steps);
        if (hit.t >= 0.0) return hit;
    }
    return std::nullopt;
}

inline Rgb8 FastCaster::shadeLevelHit(const LevelHit& hit, const glm::dvec3& p) const {
    float rgb[3];
    if (hit.level < 0) {
        map_.surfaceColor(p.x, p.y, rgb);
    } else {
        levelHitColor(*pyramid_, hit, p.x, p.y, rgb);
    }
    return haze(rgb, hit.t);
}

void FastCaster::startColumn(const Camera& camera, const ColumnContext& cc, ColumnState& st) const {
    const glm::dvec3 last = cc.base + static_cast<double>(camera.intrinsics().height) * cc.down;
    double reach = 0.0;
    for (const double x : {0.0, map_.extentX()})
        for (const double y : {0.0, map_.extentY()})
            reach = std::max(reach, std::hypot(x - cc.eye.x, y - cc.eye.y));
    st.wedge.reset(slopes_.get(), {cc.eye.x, cc.eye.y}, {cc.base.x, cc.base.y}, {last.x, last.y},
                   reach, cc.maxSlope);
}

[[gnu::noinline]] void FastCaster::castRay(const ColumnContext& cc, const glm::dvec3& d,
                                           ColumnState& st, Rgb8& c, double& tHit) const {
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
        resolved =
            restartInChain(cc, MajorRay{d, len, lenPerU, inv, majorX, sgn, rn, rz}, st, c, tHit);
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

[[gnu::always_inline]] inline bool FastCaster::linearRay(const ColumnContext& cc,
                                                         const glm::dvec3& d, ColumnState& st,
                                                         Rgb8& c, double& tHit) const {
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
        const ColumnMarch r = majorX ? marchLinear<true>(*cc.mv, cc.eg, skipPyramid(), sgn, rn, rz,
                                                         st.prevU, uNear, st.steps)
                                     : marchLinear<false>(*cc.mv, cc.eg, skipPyramid(), sgn, rn, rz,
                                                          st.prevU, uNear, st.steps);
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

template <bool kMajorX>
[[gnu::always_inline]] inline ColumnMarch FastCaster::marchLinear(
    const MapView& mv, const EyeGrid& eg, const TerrainPyramid* pyr, int sgn, double rn, double rz,
    double uStart, double uNear, std::uint64_t& steps) {
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

template <bool kMajorX>
[[gnu::always_inline]] inline FastCaster::LineSample FastCaster::lineSample(
    const std::uint16_t* heights, int w, int minorCount, long line, double n) {
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

[[gnu::always_inline]] inline FastCaster::MinorNode FastCaster::minorNode(const LineSample& sA,
                                                                          const LineSample& sB,
                                                                          double nA, double invRn,
                                                                          double zA, double zB) {
    const bool up = sB.i > sA.i;
    const double c = up ? sB.i : sA.i;
    const double hA = up ? sA.h1 : sA.h0, hB = up ? sB.h0 : sB.h1;
    const double s = (c - nA) * invRn;
    // The ray's height over the minor line's samples at A and B, interpolated.
    const double dA = zA - hA, dB = zB - hB;
    return {s, dA + s * (dB - dA)};
}

inline PyramidLevel FastCaster::levelZero(const MapView& mv) {
    PyramidLevel l;
    l.width = mv.width;
    l.height = mv.height;
    l.heights = mv.heights;
    return l;
}

inline bool FastCaster::restartInChain(const ColumnContext& cc, const MajorRay& ray,
                                       ColumnState& st, Rgb8& c, double& tHit) const {
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
    const double clear = majorX ? clearanceScan<true>(*cc.mv, cc.eg, sgn, rn, rz, start, st.steps)
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

template <bool kMajorX>
inline double FastCaster::clearanceScan(const MapView& mv, const EyeGrid& eg, int sgn, double rn,
                                        double rz, double uStart, std::uint64_t& steps) {
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
        const std::uint16_t* cell =
            cellMax + (kMajorX ? mc : mc * stride) + static_cast<std::ptrdiff_t>(lo) * minorStride;
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

[[gnu::always_inline]] inline bool FastCaster::finishCoherent(const ColumnContext& cc,
                                                              const glm::dvec3& d, double len,
                                                              double lenPerU, const ColumnMarch& r,
                                                              ColumnState& st, Rgb8& c,
                                                              double& tHit) const {
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

[[gnu::noinline]] void FastCaster::continueFar(const ColumnContext& cc, const glm::dvec3& d,
                                               double lenPerU, const ColumnMarch& r,
                                               ColumnState& st, Rgb8& c, double& tHit) const {
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

ColumnContext FastCaster::columnContext(const MapView& mv, const Camera& camera, double d0,
                                        int x) const {
    const CameraBasis& b = camera.basis();
    const double focal = camera.intrinsics().focal;
    const glm::dvec3 eye = camera.pose().position;
    const double invSx = 1.0 / map_.spacingX(), invSy = 1.0 / map_.spacingY();
    const bool eyeInside =
        eye.x >= 0.0 && eye.y >= 0.0 && eye.x <= map_.extentX() && eye.y <= map_.extentY();
    return ColumnContext{
        &mv,
        focal * b.forward + (x + 0.5 - camera.intrinsics().cx()) * b.right +
            camera.intrinsics().cy() * b.up,
        -b.up,
        eye,
        EyeGrid{eye.x * invSx, eye.y * invSy, eye.z, eyeInside, (eye.z - mv.offset) * mv.invScale},
        d0,
        invSx,
        invSy,
        map_.maxSlope(),
        map_.spacingX(),
        map_.spacingY(),
        topLevel_ > 0};
}

template <bool kSuper, int kLanes>
inline void FastCaster::renderLinearColumn(const MapView& mv, const Camera& camera, double d0,
                                           int x, RenderedFrame& frame,
                                           UnitCounters& counters) const {
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
#if VIG_CASTER_ROWS
    constexpr bool rows = kLanes >= 4;
    constexpr bool wide = kLanes == 8;
#endif
    const int rays = h * sub;
    int single = 0;  // rays to cast one by one before trying a batch again
    for (int v = rays - 1; v >= 0;) {
#if VIG_CASTER_ROWS
        // Sky above the map's highest point goes in batches again.
        if (single > 0 && st.prevAbove) single = 0;
        if (!kSuper && rows && single == 0 && v >= 3 && st.havePrev) {
            // Batches run inside the vector code, as many at a time as go.
            RowsOutcome r = RowsOutcome::kOther;
            bool tried = false;
#if VIG_CASTER_ROWS
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
#if VIG_CASTER_ROWS
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

inline void FastCaster::renderColumnUnit(const MapView& mv, const Camera& camera, double d0, int x,
                                         RenderedFrame& frame, UnitCounters& counters) const {
    renderColumn(mv, camera, d0, x, frame, counters);
}

void FastCaster::renderColumn(const MapView& mv, const Camera& camera, double d0, int x,
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

}  // namespace fast

std::unique_ptr<Caster> makeFastCaster(const TerrainMap& map, const RenderOptions& options,
                                       std::shared_ptr<const TerrainPyramid> pyramid) {
    return std::make_unique<fast::FastCaster>(map, options, std::move(pyramid));
}

}  // namespace ig
