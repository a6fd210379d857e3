// Right eye by reprojection of the left (Wan et al. 2000; Adelson & Hodges), then a second pass
// that ray casts the marked pixels column by column. docs/design/stereo.md explains the choices.
//
// Geometry: the right eye is the left moved e metres along the camera's right vector, same
// orientation. A point at camera coordinates (X right, Y up, Z forward) of the left eye is seen
// at x_l = cx + f X / Z; the right eye sees it at X - e, so x_r = x_l - f e / Z on the same row.
// Z = d f / L with d the Euclidean depth and L = |(x_l - cx, y_l - cy, f)|, so the disparity is
// f e / Z = e L / d. Sky (d = +inf) has disparity 0.
#include "ig/stereo.hpp"

#include "ig/caster_impl.hpp"
#include "ig/error.hpp"
#include "ig/grid_march.hpp"
#include "ig/shading.hpp"
#include "ig/surface_hit.hpp"

#include <tbb/blocked_range.h>
#include <tbb/combinable.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>
#include <glm/geometric.hpp>

#if defined(__SSE__)
#include <xmmintrin.h>
#endif

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

#include <time.h>

namespace ig {

std::string_view rightEyeMethodName(RightEyeMethod method) {
    return method == RightEyeMethod::Reproject ? "reproject" : "raycast";
}

RightEyeMethod parseRightEyeMethod(std::string_view name) {
    if (name == "reproject") return RightEyeMethod::Reproject;
    if (name == "raycast") return RightEyeMethod::Raycast;
    throw InputError("--right '" + std::string(name) + "': expected reproject or raycast");
}

void validateStereoOptions(const StereoOptions& options) {
    if (!std::isfinite(options.eyeSeparation) || options.eyeSeparation < 0.0) {
        throw InputError("--stereo: the eye separation must be a finite number of metres >= 0");
    }
    if (!std::isfinite(options.gapThreshold) || options.gapThreshold < 0.0) {
        throw InputError("--gap-threshold: must be a finite number of pixels >= 0");
    }
}

Pose rightEyePose(const Pose& left, double eyeSeparation) {
    Pose right = left;
    right.position += eyeSeparation * CameraBasis::fromPose(left).right;
    return right;
}

double threadCpuMs() {
    timespec ts{};
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
    return ts.tv_sec * 1e3 + ts.tv_nsec * 1e-6;
}

double stereoDisparity(const Intrinsics& intrinsics, int x, int y, double depth,
                       double eyeSeparation) {
    if (!std::isfinite(depth)) return 0.0;
    const double dx = x + 0.5 - intrinsics.cx(), dy = y + 0.5 - intrinsics.cy();
    const double len = std::sqrt(intrinsics.focal * intrinsics.focal + dx * dx + dy * dy);
    return eyeSeparation * len / depth;
}

namespace {

using Clock = std::chrono::steady_clock;

constexpr int kSubpixels = 8;  // the A-buffer's 1x8 coverage mask, slots per pixel
constexpr float kInf = std::numeric_limits<float>::infinity();
// Sky's right-eye depth inside the reprojection: finite, so that slot counts times depth never
// make 0 x inf; any mean at or above kSkyMean is written out as +inf.
constexpr float kSkySentinel = 1e30f;
constexpr float kSkyMean = 1e29f;
// Reprojections further left than this are all simply out of the view.
constexpr float kFarLeft = -1e6f;

// Rounding to an integer without a library call (|x| far inside long's range).
inline long ceilLong(double x) {
    const long i = static_cast<long>(x);
    return i + (x > static_cast<double>(i));
}
inline long floorLong(double x) {
    const long i = static_cast<long>(x);
    return i - (x < static_cast<double>(i));
}

// An RGB colour as three 16-bit lanes of one integer, so that the sums of up to 8 x 255 per
// channel take one multiply-add.
inline std::uint64_t packRgb(Rgb8 c) {
    return c.r | static_cast<std::uint64_t>(c.g) << 16 | static_cast<std::uint64_t>(c.b) << 32;
}

// What the slots of one right pixel accumulate (16 bytes: a row of them stays in L1).
struct PixelAcc {
    std::uint64_t rgb = 0;  // packed colour (packRgb) summed over covered slots
    std::uint8_t cast = 0;  // slots left to the second pass
    bool sampled = false;   // a left pixel's own footprint covers part of it
    float depthSum = 0.0f;  // right-eye depth summed over covered slots (sky: kSkySentinel)
};

// Reprojects rows of the left image into the right image. A row has S slots per pixel: 8 with
// the A-buffer (a 1x8 coverage mask), 1 with integer placement (positions snapped to the centre
// of the pixel they fall in). Slot k of the row has its centre at (k + 0.5) / S; a region
// [u, v) of the continuous x axis owns the slots whose centres it holds, i.e. slots
// ceil(S u - 0.5) up to (not including) ceil(S v - 0.5), so abutting regions share no slot and
// leave none out.
class RowReprojector {
  public:
    RowReprojector(const RenderedFrame& left, const StereoOptions& options)
        : left_(left),
          w_(left.width()),
          slots_(options.abuffer && options.variant == ReprojectVariant::Wan ? kSubpixels : 1),
          shift_(slots_ == kSubpixels ? 3 : 0),
          total_(static_cast<long>(w_) * slots_),
          e_(options.eyeSeparation),
          gap_(options.gapThreshold),
          pos_(static_cast<std::size_t>(w_)),
          depth_(static_cast<std::size_t>(w_)),
          acc_(static_cast<std::size_t>(w_) + 1),
          castInColumn_(static_cast<std::size_t>(w_), 0) {}

    // Ray-cast pixels per column over the rows this worker reprojected.
    const std::vector<int>& castInColumn() const { return castInColumn_; }

    // Reprojects row y: writes the right frame's colour, depth and `source` for that row and
    // adds the count of each source to `counts`.
    void row(int y, bool adelsonHodges, RenderedFrame& right, RightPixelSource* source,
             std::uint64_t counts[3]) {
        const std::size_t rowStart = static_cast<std::size_t>(y) * w_;
        in_ = left_.color.data() + rowStart;
        out_ = Out{right.color.data() + rowStart, right.depth.data() + rowStart, source, counts};
        if (!project(y)) {
            // All sky: no disparity anywhere, so the right row is the left row.
            std::copy_n(in_, w_, out_.color);
            std::fill_n(out_.depth, w_, kSkyDepth);
            std::fill_n(out_.source, w_, RightPixelSource::Reprojected);
            counts[0] += static_cast<std::uint64_t>(w_);
            return;
        }
        if (adelsonHodges) {
            overwriteRow();
        } else {
            wanRow();
        }
    }

  private:
    struct Out {
        Rgb8* color;
        float* depth;
        RightPixelSource* source;
        std::uint64_t* counts;
    };

    // Right-image positions and right-eye depths of row y's left pixels:
    //   pos = x + 0.5 - e L / d,  d_r = |P - E_r| = d sqrt(1 + u (u - 2 dx / L)), u = e / d,
    // from |P - E_r|^2 = d^2 - 2 e X + e^2 with X = dx d / L the camera-right coordinate.
    // Sky (d = +inf) gives pos = x + 0.5 with no special case, and d_r = kSkySentinel.
    // Branch-free, four pixels at a time where SSE is available. Returns whether any pixel of
    // the row is terrain (finite depth).
    bool project(int y) {
        const Intrinsics& in = left_.intrinsics;
        const float* depth = left_.depth.data() + static_cast<std::size_t>(y) * w_;
        const double dy = y + 0.5 - in.cy();
        const auto base = static_cast<float>(in.focal * in.focal + dy * dy);
        const auto e = static_cast<float>(e_), cx = static_cast<float>(in.cx());
        float* __restrict__ pos = pos_.data();
        float* __restrict__ dr = depth_.data();
        int i = 0;
        bool terrain = false;
#if defined(__SSE__)
        int finiteMask = 0;
        const __m128 vInf = _mm_set1_ps(kInf);
        const __m128 vBase = _mm_set1_ps(base), vE = _mm_set1_ps(e), vOne = _mm_set1_ps(1.0f);
        const __m128 vZero = _mm_setzero_ps(), vStep = _mm_setr_ps(0.5f, 1.5f, 2.5f, 3.5f);
        const __m128 vFar = _mm_set1_ps(kFarLeft);
        for (; i + 4 <= w_; i += 4) {
            const __m128 x = _mm_add_ps(_mm_set1_ps(static_cast<float>(i)), vStep);
            const __m128 dx = _mm_sub_ps(x, _mm_set1_ps(cx));
            const __m128 len = _mm_sqrt_ps(_mm_add_ps(vBase, _mm_mul_ps(dx, dx)));
            const __m128 d = _mm_loadu_ps(depth + i);
            finiteMask |= _mm_movemask_ps(_mm_cmplt_ps(d, vInf));
            const __m128 invD = _mm_div_ps(vOne, d);
            // Far left of the view is all the same; the floor also turns a NaN into it.
            _mm_storeu_ps(pos + i,
                          _mm_max_ps(_mm_sub_ps(x, _mm_mul_ps(vE, _mm_mul_ps(len, invD))), vFar));
            const __m128 u = _mm_mul_ps(vE, invD);
            const __m128 eps = _mm_mul_ps(u, _mm_sub_ps(u, _mm_div_ps(_mm_add_ps(dx, dx), len)));
            const __m128 root = _mm_sqrt_ps(_mm_max_ps(vZero, _mm_add_ps(vOne, eps)));
            _mm_storeu_ps(dr + i, _mm_min_ps(_mm_mul_ps(d, root), _mm_set1_ps(kSkySentinel)));
        }
        terrain = finiteMask != 0;
#endif
        for (; i < w_; ++i) {
            const float x = static_cast<float>(i) + 0.5f, dx = x - cx;
            terrain = terrain || depth[i] < kInf;
            const float len = std::sqrt(base + dx * dx);
            const float d = depth[i], invD = 1.0f / d, u = e * invD;
            pos[i] = std::max(kFarLeft, x - e * (len * invD));
            dr[i] = std::min(d * std::sqrt(std::max(0.0f, 1.0f + u * (u - (dx + dx) / len))),
                             kSkySentinel);
        }
        if (slots_ == 1) {
            for (int k = 0; k < w_; ++k)
                pos[k] = static_cast<float>(floorLong(pos[k])) + 0.5f;
        }
        return terrain;
    }

    // Writes the row's right pixels from what their slots accumulated. Local restrict
    // pointers: the byte stores would otherwise force reloads of every member.
    void writeRow() {
        static constexpr float kInverse[9] = {0.0f,        1.0f,        0.5f,     1.0f / 3, 0.25f,
                                              1.0f / 5.0f, 1.0f / 6.0f, 1.0f / 7, 0.125f};
        // 2^16 / n rounded up: (sum * kScale[n] + 2^15) >> 16 is sum / n rounded, to within
        // 0.03 for sums up to 8 x 255.
        static constexpr std::uint32_t kScale[9] = {0,     65536, 32768, 21846, 16384,
                                                    13108, 10923, 9363,  8192};
        PixelAcc* __restrict__ acc = acc_.data();
        int* __restrict__ castInColumn = castInColumn_.data();
        Rgb8* __restrict__ color = out_.color;
        float* __restrict__ depth = out_.depth;
        RightPixelSource* __restrict__ source = out_.source;
        const int slots = slots_, w = w_, shift = shift_;
        const std::uint64_t roundAll =
            static_cast<std::uint64_t>((1 << shift) >> 1) * 0x100010001ULL;
        const float inverseAll = kInverse[slots];
        // Counted in registers (an indexed counter in memory would chain every pixel on a
        // store-to-load round trip); interpolated = the rest.
        std::uint64_t sampled = 0, cast = 0;
        for (int p = 0; p < w; ++p) {
            const PixelAcc a = acc[p];
            if (2 * a.cast >= slots) {
                source[p] = RightPixelSource::RayCast;
                color[p] = Rgb8{255, 0, 255};  // overwritten by the second pass
                depth[p] = kSkyDepth;
                ++cast;
                ++castInColumn[p];
                continue;
            }
            float mean;
            if (a.cast == 0) {
                // All S slots covered (the common case): S is a power of two, so the rounded
                // mean of each lane is (sum + S / 2) >> shift, all three lanes at once (a lane
                // holds at most 8 x 255 + 4, so nothing carries; the low byte of each lane is
                // the result). Equal to the general case below.
                const std::uint64_t v = (a.rgb + roundAll) >> shift;
                color[p] = Rgb8{static_cast<std::uint8_t>(v), static_cast<std::uint8_t>(v >> 16),
                                static_cast<std::uint8_t>(v >> 32)};
                mean = a.depthSum * inverseAll;
            } else {
                const int covered = slots - a.cast;
                const std::uint32_t scale = kScale[covered];
                auto q = [scale](std::uint64_t sum) {
                    return static_cast<std::uint8_t>(((sum & 0xffff) * scale + 32768) >> 16);
                };
                color[p] = Rgb8{q(a.rgb), q(a.rgb >> 16), q(a.rgb >> 32)};
                mean = a.depthSum * kInverse[covered];
            }
            depth[p] = mean < kSkyMean ? mean : kSkyDepth;
            source[p] = a.sampled ? RightPixelSource::Reprojected : RightPixelSource::Interpolated;
            sampled += a.sampled;
        }
        out_.counts[0] += sampled;
        out_.counts[1] += static_cast<std::uint64_t>(w) - sampled - cast;
        out_.counts[2] += cast;
    }

    // Wan fig. 5-6: right to left, keeping the left-most accepted reprojection; a reprojection
    // on or right of it is hidden. An accepted reprojection covers up to half a pixel on either
    // side (its left pixel's extent), meeting a neighbour closer than a pixel at the midpoint,
    // so with no disparity every right pixel is exactly its left pixel. Between two footprints
    // the colour is interpolated when the reprojections are up to the gap threshold apart, else
    // the slots are left to the second pass. The end gaps are the right eye's own view: right
    // of the right-most reprojection, and left of the last one when all further left is hidden.
    void wanRow() {
        const int S = slots_;
        const double slots = slots_;
        // Local restrict copies: the byte-sized stores below could otherwise alias the members.
        const float* __restrict__ posOf = pos_.data();
        const float* __restrict__ depthOf = depth_.data();
        const Rgb8* __restrict__ colorOf = in_;
        const long total = total_;
        const int shift = shift_;
        auto slotAt = [slots](double x) { return ceilLong(slots * x - 0.5); };
        // The regions come right to left and abut, each ending where the last began (`edge`),
        // so the slots are filled as one sweep from the right end: pixel `cur` (slots base ..
        // base + S) is accumulated in the scalars below (separate registers, no packed struct
        // on the loop-carried path) and stored to acc_ once the sweep passes its left end.
        // acc_ has a spare entry past the row, the target of stores that are not needed.
        PixelAcc* __restrict__ out = acc_.data();
        long cur = w_ - 1, base = cur << shift, edge = total;
        std::uint64_t aRgb = 0;
        float aDepth = 0.0f;
        int aCast = 0;
        bool aSampled = false;
        auto store = [&](long p) {
            out[p] = PixelAcc{aRgb, static_cast<std::uint8_t>(aCast), aSampled, aDepth};
        };
        // A footprint: slots [lo, edge) of left pixel i. It holds at most S slots, so it ends
        // in the current pixel or the next one to the left: no branch decides which.
        auto run = [&](long lo, int i) {
            lo = std::clamp(lo, 0L, edge);
            const std::uint64_t c = packRgb(colorOf[i]);
            const float d = depthOf[i];
            const bool crossed = lo < base;
            const long split = crossed ? base : lo;
            const long n0 = edge - split, n1 = split - lo;
            aRgb += static_cast<std::uint64_t>(n0) * c;
            aDepth += static_cast<float>(n0) * d;
            aSampled = aSampled || n0 > 0;
            store(crossed ? cur : w_);
            const std::uint64_t nextRgb = static_cast<std::uint64_t>(n1) * c;
            const float nextDepth = static_cast<float>(n1) * d;
            aRgb = crossed ? nextRgb : aRgb;
            aDepth = crossed ? nextDepth : aDepth;
            aCast = crossed ? 0 : aCast;
            aSampled = crossed ? n1 > 0 : aSampled;
            cur -= crossed;
            base -= crossed ? S : 0;
            edge = lo;
        };
        // Any region [lo, edge): add(s0, s1) accumulates slots [s0, s1) of pixel cur.
        auto emit = [&](long lo, auto&& add) {
            lo = std::clamp(lo, 0L, edge);
            while (lo < base) {
                add(base, edge);
                store(cur);
                aRgb = 0;
                aDepth = 0.0f;
                aCast = 0;
                aSampled = false;
                --cur;
                edge = base;
                base -= S;
            }
            add(lo, edge);
            edge = lo;
        };
        auto gap = [&](long lo) {
            emit(lo, [&](long s0, long s1) { aCast += static_cast<int>(s1 - s0); });
        };
        auto interpolate = [&](long lo, int i, int j) {  // from left pixel i to j
            const double x0 = posOf[i];
            const double inv = 1.0 / (posOf[j] - x0);
            const Rgb8 ci = colorOf[i], cj = colorOf[j];
            const float di = depthOf[i], dj = depthOf[j];
            const bool finite = di < kSkySentinel && dj < kSkySentinel;
            emit(lo, [&](long s0, long s1) {
                if (s0 >= s1) return;
                const auto n = static_cast<float>(s1 - s0);
                // Linear, so its sum over the slots is n times its value at their mean centre.
                const auto t = static_cast<float>((0.5 * (s0 + s1) / S - x0) * inv);
                auto lerp = [n, t](int u, int v) {
                    return static_cast<std::uint64_t>(n * (u + (v - u) * t) + 0.5f);
                };
                aRgb += lerp(ci.r, cj.r) + (lerp(ci.g, cj.g) << 16) + (lerp(ci.b, cj.b) << 32);
                aDepth += n * (finite ? di + (dj - di) * t : (t < 0.5f ? di : dj));
            });
        };

        int prev = -1;  // the left-most accepted reprojection so far
        for (int i = w_ - 1; i >= 0; --i) {
            const double pos = posOf[i];
            if (prev < 0) {
                gap(slotAt(pos + 0.5));
            } else {
                const double pp = posOf[prev];
                if (!(pos < pp)) continue;  // hidden reprojection
                const double distance = pp - pos;
                if (distance <= 1.0) {
                    run(slotAt(0.5 * (pos + pp)), prev);
                } else {
                    run(slotAt(pp - 0.5), prev);
                    if (distance <= gap_) {
                        interpolate(slotAt(pos + 0.5), i, prev);
                    } else {
                        gap(slotAt(pos + 0.5));
                    }
                }
            }
            prev = i;
            if (pos <= -0.5) break;  // the rest of the row lands left of the view
        }
        run(slotAt(posOf[prev] - 0.5), prev);
        gap(0);
        store(cur);
        writeRow();
    }

    // Adelson-Hodges: left to right at integer positions, each reprojection overwriting what is
    // there (a later left pixel landing on the same right pixel is nearer); when neighbouring
    // left pixels land more than one pixel apart the pixels between are emptied. Whatever is
    // empty at the end is cast.
    void overwriteRow() {
        // Not `sampled` means empty.
        std::fill(acc_.begin(), acc_.end(), PixelAcc{});
        PixelAcc* __restrict__ acc = acc_.data();
        long prevP = 0;
        for (int i = 0; i < w_; ++i) {
            const long p = floorLong(pos_[static_cast<std::size_t>(i)]);
            if (i > 0 && p - prevP > 1) {
                for (long q = std::max(0L, prevP + 1); q < std::min<long>(p, w_); ++q)
                    acc[q] = PixelAcc{};
            }
            if (p >= 0 && p < w_) {
                const Rgb8 c = in_[i];
                const float d = depth_[static_cast<std::size_t>(i)];
                acc[p] = PixelAcc{packRgb(c), 0, true, d};
            }
            prevP = p;
        }
        for (int p = 0; p < w_; ++p) {
            if (!acc[p].sampled) acc[p].cast = 1;
        }
        writeRow();
    }

    const RenderedFrame& left_;
    int w_;
    int slots_, shift_;
    long total_;
    double e_, gap_;
    const Rgb8* in_ = nullptr;  // the row's left colours
    Out out_{};
    std::vector<float> pos_;
    std::vector<float> depth_;
    std::vector<PixelAcc> acc_;
    std::vector<int> castInColumn_;
};

// Direction facts of a unit ray that the coherence test uses.
struct RayGeom {
    double horiz = 0.0;  // horizontal length of the unit direction
    double slope = 0.0;  // rise per horizontal metre
    glm::dvec2 track{0.0};
};

RayGeom rayGeom(const glm::dvec3& unitDir) {
    RayGeom g;
    g.horiz = std::sqrt(unitDir.x * unitDir.x + unitDir.y * unitDir.y);
    if (g.horiz > 1e-12) {
        g.track = glm::dvec2{unitDir.x, unitDir.y} / g.horiz;
        g.slope = unitDir.z / g.horiz;
    }
    return g;
}

// The fast caster's safety test (docs/design/ray_casting.md): `upper` stays above the terrain
// wherever `lower` was, because its climb over `lower` outruns the most the terrain can rise
// across the gap between their tracks.
bool coherent(const RayGeom& lower, const RayGeom& upper, double maxSlope) {
    return lower.horiz > 1e-9 && upper.horiz > 1e-9 && glm::dot(upper.track, lower.track) > 0.0 &&
           upper.slope - lower.slope >= maxSlope * glm::length(upper.track - lower.track);
}

struct CastCounters {
    std::uint64_t steps = 0, restarts = 0, sky = 0;
};

// Second pass (Wan sec. 3.1-3.2, fig. 7): cast the marked pixels of one column bottom to top.
// Each run of marked pixels starts from the depth of the reprojected or interpolated pixel
// below it (less a margin), then each ray starts where the one below hit, both only where the
// coherence test allows. Once a ray has missed by leaving the map box through its top (eye over
// the map), the marked pixels above it that pass the same test against that ray are sky without
// casting: they are above it over the whole map, and above the highest terrain beyond it.
class ColumnCaster {
  public:
    ColumnCaster(const TerrainMap& map, const Camera& camera, const SkyModel& sky,
                 const std::vector<RightPixelSource>& source)
        : map_(map), camera_(camera), sky_(sky), source_(source) {
        const glm::dvec3& p = camera.pose().position;
        eyeOverMap_ = p.x >= 0.0 && p.y >= 0.0 && p.x <= map.extentX() && p.y <= map.extentY();
        backoff_ = 2.0 * std::max(map.spacingX(), map.spacingY());
    }

    void column(int x, RenderedFrame& right, CastCounters& counters) const {
        const Intrinsics& in = camera_.intrinsics();
        const int w = in.width, h = in.height;
        const CameraBasis& b = camera_.basis();
        const glm::dvec3 base =
            in.focal * b.forward + (x + 0.5 - in.cx()) * b.right + in.cy() * b.up;
        const glm::dvec3 down = -b.up;
        const glm::dvec3 eye = camera_.pose().position;
        const double maxSlope = map_.maxSlope();
        const double topExit = map_.maxHeight() - 1e-9 * (1.0 + std::abs(map_.maxHeight()));

        bool havePrev = false, haveSkyRef = false;
        RayGeom prev, skyRef;
        double prevDist = 0.0;
        for (int y = h - 1; y >= 0; --y) {
            const std::size_t idx = static_cast<std::size_t>(y) * w + x;
            if (source_[idx] != RightPixelSource::RayCast) {
                havePrev = false;
                continue;
            }
            const TerrainRay ray(map_, eye, base + (y + 0.5) * down);
            const RayGeom g = rayGeom(ray.dir);
            if (haveSkyRef && coherent(skyRef, g, maxSlope)) {
                right.color[idx] = skyColor(sky_, ray.dir.z);
                right.depth[idx] = kSkyDepth;
                ++counters.sky;
                havePrev = false;
                continue;
            }
            if (!havePrev && y + 1 < h) {
                const float below = right.depth[idx + w];
                if (std::isfinite(below)) {
                    prev = rayGeom(glm::normalize(base + (y + 1.5) * down));
                    prevDist = std::max(0.0, below * prev.horiz * 0.99 - backoff_);
                    havePrev = true;
                }
            }
            double t0, t1, t = -1.0;
            if (clipToMapBox(map_, ray, t0, t1)) {
                double tStart = t0;
                if (havePrev && coherent(prev, g, maxSlope)) {
                    tStart = std::max(t0, prevDist / g.horiz);
                } else {
                    ++counters.restarts;
                }
                t = marchRay(map_, ray, tStart, t1, counters.steps);
                prevDist = (t >= 0.0 ? t : t1) * g.horiz;
                if (t < 0.0 && eyeOverMap_ && ray.at(t1).z >= topExit) {
                    haveSkyRef = true;
                    skyRef = g;
                }
            } else {
                prevDist = 0.0;
                // The eye is over the map but outside its box: above it, and this ray never
                // comes down into it.
                if (eyeOverMap_) {
                    haveSkyRef = true;
                    skyRef = g;
                }
            }
            havePrev = true;
            prev = g;
            if (t >= 0.0) {
                const glm::dvec3 p = ray.at(t);
                right.color[idx] = terrainColor(map_, sky_, p.x, p.y, t);
                right.depth[idx] = static_cast<float>(t);
            } else {
                right.color[idx] = skyColor(sky_, ray.dir.z);
                right.depth[idx] = kSkyDepth;
            }
        }
    }

  private:
    const TerrainMap& map_;
    const Camera& camera_;
    const SkyModel& sky_;
    const std::vector<RightPixelSource>& source_;
    bool eyeOverMap_ = false;
    double backoff_ = 0.0;
};

void fillControlPoints(const TerrainMap& map, RenderedFrame& frame) {
    const Camera camera(frame.pose, frame.intrinsics);
    const auto pixels = controlPointPixels(frame.intrinsics);
    for (int i = 0; i < kControlPointCount; ++i) {
        const glm::dvec3 dir = glm::normalize(camera.rayDirection(pixels[i].x, pixels[i].y));
        const RayHit hit = intersectTerrain(map, frame.pose.position, dir);
        frame.controlPoints[i].pixel = pixels[i];
        frame.controlPoints[i].world = hit.hit ? glm::dvec4{hit.point, 1.0} : glm::dvec4{dir, 0.0};
    }
}

}  // namespace

RenderedFrame reprojectRightEye(const TerrainMap& map, const RenderedFrame& left,
                                const StereoOptions& options, const RenderOptions& renderOptions,
                                std::vector<RightPixelSource>& source, StereoStats& stats) {
    validateStereoOptions(options);
    if (left.pose.roll != 0.0) {
        throw InputError("pose: stereo reprojection renders roll = 0 (the PRP applies roll)");
    }
    const int w = left.width(), h = left.height();
    const std::size_t n = static_cast<std::size_t>(w) * h;
    if (w <= 0 || h <= 0 || left.color.size() != n || left.depth.size() != n) {
        throw std::invalid_argument("reprojectRightEye: left frame without colour and depth");
    }
    RenderedFrame right;
    right.sequence = left.sequence;
    right.time = left.time;
    right.pose = rightEyePose(left.pose, options.eyeSeparation);
    right.intrinsics = left.intrinsics;
    validateView(map, right.pose, right.intrinsics);
    right.color.resize(n);
    right.depth.resize(n);
    source.assign(n, RightPixelSource::RayCast);
    const bool adelsonHodges = options.variant == ReprojectVariant::AdelsonHodges;
    const Camera camera(right.pose, right.intrinsics);

    const auto start = Clock::now();
    const double cpuStart = threadCpuMs();
    // One row buffer per worker.
    tbb::enumerable_thread_specific<RowReprojector> reprojectors(
        [&] { return RowReprojector(left, options); });
    tbb::combinable<std::array<std::uint64_t, 3>> counts([] {
        return std::array<std::uint64_t, 3>{0, 0, 0};
    });
    tbb::combinable<CastCounters> castCounters;
    const ColumnCaster caster(map, camera, renderOptions.sky, source);
    Clock::time_point castStart;
    runWithThreads(renderOptions.threads, [&] {
        // Reprojection: a pool of rows; each task reprojects a band of rows.
        tbb::parallel_for(tbb::blocked_range<int>(0, h, 8), [&](const tbb::blocked_range<int>& r) {
            RowReprojector& rows = reprojectors.local();
            std::uint64_t c[3] = {0, 0, 0};
            for (int y = r.begin(); y < r.end(); ++y) {
                const std::size_t at = static_cast<std::size_t>(y) * w;
                rows.row(y, adelsonHodges, right, source.data() + at, c);
            }
            auto& local = counts.local();
            for (int k = 0; k < 3; ++k)
                local[k] += c[k];
        });
        castStart = Clock::now();

        // Second pass: columns with marked pixels, most marked first (Wan sec. 3.2), one column
        // per task so idle workers take the next column.
        std::vector<int> marked(static_cast<std::size_t>(w), 0);
        for (const RowReprojector& rows : reprojectors) {
            for (int x = 0; x < w; ++x)
                marked[static_cast<std::size_t>(x)] +=
                    rows.castInColumn()[static_cast<std::size_t>(x)];
        }
        std::vector<int> queue;
        for (int x = 0; x < w; ++x) {
            if (marked[static_cast<std::size_t>(x)] > 0) queue.push_back(x);
        }
        std::stable_sort(queue.begin(), queue.end(), [&](int a, int b) {
            return marked[static_cast<std::size_t>(a)] > marked[static_cast<std::size_t>(b)];
        });
        tbb::parallel_for(
            tbb::blocked_range<std::size_t>(0, queue.size(), 1),
            [&](const tbb::blocked_range<std::size_t>& r) {
                CastCounters& c = castCounters.local();
                for (std::size_t i = r.begin(); i < r.end(); ++i)
                    caster.column(queue[i], right, c);
            },
            tbb::simple_partitioner());
    });
    const auto end = Clock::now();
    stats.rightCpuMs = threadCpuMs() - cpuStart;
    const auto total =
        counts.combine([](std::array<std::uint64_t, 3> a, std::array<std::uint64_t, 3> b) {
            return std::array<std::uint64_t, 3>{a[0] + b[0], a[1] + b[1], a[2] + b[2]};
        });
    stats.reprojected = total[0];
    stats.interpolated = total[1];
    stats.rayCast = total[2];
    const CastCounters cast = castCounters.combine([](CastCounters a, CastCounters b) {
        return CastCounters{a.steps + b.steps, a.restarts + b.restarts, a.sky + b.sky};
    });
    stats.steps = cast.steps;
    stats.restarts = cast.restarts;
    stats.skyWithoutCast = cast.sky;
    stats.reprojectMs = std::chrono::duration<double, std::milli>(castStart - start).count();
    stats.castMs = std::chrono::duration<double, std::milli>(end - castStart).count();
    stats.rightMs = stats.reprojectMs + stats.castMs;

    right.stats.renderMs = stats.rightMs;
    right.stats.steps = cast.steps;
    right.stats.restarts = cast.restarts;
    right.stats.rays = stats.rayCast - cast.sky;
    fillControlPoints(map, right);
    return right;
}

StereoFrame renderStereo(const TerrainMap& map, const Pose& pose, const Intrinsics& intrinsics,
                         const StereoOptions& options, const RenderOptions& renderOptions) {
    validateStereoOptions(options);
    if (pose.roll != 0.0) {
        throw InputError(
            "pose: stereo renders roll = 0 (the post-rendering processor applies roll)");
    }
    const auto caster = makeCaster(CasterKind::Fast, map, renderOptions);
    StereoFrame out;
    out.left = renderFrame(*caster, map, pose, intrinsics);
    out.stats.leftMs = out.left.stats.renderMs;
    if (options.method == RightEyeMethod::Raycast) {
        out.right = renderFrame(*caster, map, rightEyePose(pose, options.eyeSeparation), intrinsics,
                                out.left.time, out.left.sequence);
        out.stats.rightMs = out.right.stats.renderMs;
        out.stats.castMs = out.stats.rightMs;
        out.stats.rayCast = out.right.color.size();
        out.stats.steps = out.right.stats.steps;
        out.stats.restarts = out.right.stats.restarts;
        return out;
    }
    out.right = reprojectRightEye(map, out.left, options, renderOptions, out.source, out.stats);
    return out;
}

std::vector<Rgb8> sideBySide(const RenderedFrame& left, const RenderedFrame& right) {
    const int w = left.width(), h = left.height();
    std::vector<Rgb8> out(static_cast<std::size_t>(2 * w) * h);
    for (int y = 0; y < h; ++y) {
        const std::size_t src = static_cast<std::size_t>(y) * w;
        std::copy_n(left.color.begin() + src, w, out.begin() + 2 * src);
        std::copy_n(right.color.begin() + src, w, out.begin() + 2 * src + w);
    }
    return out;
}

std::vector<Rgb8> anaglyph(const RenderedFrame& left, const RenderedFrame& right) {
    std::vector<Rgb8> out(left.color.size());
    for (std::size_t i = 0; i < out.size(); ++i)
        out[i] = Rgb8{left.color[i].r, right.color[i].g, right.color[i].b};
    return out;
}

std::vector<Rgb8> rayCastMask(const RenderedFrame& right,
                              const std::vector<RightPixelSource>& source) {
    std::vector<Rgb8> out(right.color.size());
    for (std::size_t i = 0; i < out.size(); ++i) {
        if (i < source.size() && source[i] == RightPixelSource::RayCast) {
            out[i] = Rgb8{255, 0, 0};
        } else {
            const Rgb8 c = right.color[i];
            const auto grey =
                static_cast<std::uint8_t>(32 + (77 * c.r + 150 * c.g + 29 * c.b) / 512);
            out[i] = Rgb8{grey, grey, grey};
        }
    }
    return out;
}

}  // namespace ig
