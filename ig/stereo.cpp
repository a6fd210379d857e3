// Right eye by reprojection of the left (Wan et al. 2000; Adelson & Hodges), then a second pass
// that ray casts the marked pixels column by column. docs/design/stereo.md explains the choices.
//
// Geometry: the right eye is the left moved e metres along the camera's right vector, same
// orientation. A point at camera coordinates (X right, Y up, Z forward) of the left eye is seen
// at x_l = cx + f X / Z; the right eye sees it at X - e, so x_r = x_l - f e / Z on the same row.
// Z = d f / L with d the Euclidean depth and L = |(x_l - cx, y_l - cy, f)|, so the disparity is
// f e / Z = e L / d. Sky (d = +inf) has disparity 0.
#include "ig/stereo.hpp"
#include "base/check.hpp"
#include "base/cpu_features.hpp"

#include "ig/caster_impl.hpp"
#include "ig/coherence.hpp"
#include "ig/error.hpp"
#include "ig/grid_march.hpp"
#include "ig/haze_pass.hpp"
#include "ig/near_clip.hpp"
#include "ig/object_pass.hpp"
#include "ig/object_trace.hpp"
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
#if defined(__x86_64__)
#include <immintrin.h>
// Wan's rows on four lanes where the processor has AVX2 (chosen at run time).
#define VIG_STEREO_VECTOR 1
#define VIG_STEREO_AVX2 __attribute__((target("avx2")))
#else
#define VIG_STEREO_VECTOR 0
#endif

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstring>
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
    if (!std::isfinite(options.nearM) || options.nearM < 0.0) {
        throw InputError("--near: must be a finite distance of 0 (none) or more metres");
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
          sweep_(options.referenceSweep),
          avx2_(VIG_STEREO_VECTOR && base::cpuFeatures().avx2),
          pos_(static_cast<std::size_t>(w_)),
          depth_(static_cast<std::size_t>(w_)),
          acc_(static_cast<std::size_t>(w_) + 1),
          lo_(static_cast<std::size_t>(w_)),
          hi_(static_cast<std::size_t>(w_)),
          packed_(static_cast<std::size_t>(w_)),
          next_(static_cast<std::size_t>(w_)),
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
            if (sweep_) {
                overwriteRow();
            } else {
                overwriteRowDirect();
            }
        } else if (sweep_ || !avx2_) {
            wanRow();
        } else if (!wanRowVector()) {
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
#if VIG_STEREO_VECTOR
        if (avx2_) i = project8(depth, base, e, cx, w_, pos, dr, finiteMask);
#endif
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

#if VIG_STEREO_VECTOR
    // project's loop on eight lanes, the same operations (no fused multiply-adds); returns
    // where it stopped.
    VIG_STEREO_AVX2 static int project8(const float* depth, float base, float e, float cx, int w,
                                        float* __restrict__ pos, float* __restrict__ dr,
                                        int& finiteMask) {
        const __m256 vInf = _mm256_set1_ps(kInf), vBase = _mm256_set1_ps(base);
        const __m256 vE = _mm256_set1_ps(e), vOne = _mm256_set1_ps(1.0f);
        const __m256 vZero = _mm256_setzero_ps(), vFar = _mm256_set1_ps(kFarLeft);
        const __m256 vStep = _mm256_setr_ps(0.5f, 1.5f, 2.5f, 3.5f, 4.5f, 5.5f, 6.5f, 7.5f);
        int i = 0;
        for (; i + 8 <= w; i += 8) {
            const __m256 x = _mm256_add_ps(_mm256_set1_ps(static_cast<float>(i)), vStep);
            const __m256 dx = _mm256_sub_ps(x, _mm256_set1_ps(cx));
            const __m256 len = _mm256_sqrt_ps(_mm256_add_ps(vBase, _mm256_mul_ps(dx, dx)));
            const __m256 d = _mm256_loadu_ps(depth + i);
            finiteMask |= _mm256_movemask_ps(_mm256_cmp_ps(d, vInf, _CMP_LT_OQ));
            const __m256 invD = _mm256_div_ps(vOne, d);
            _mm256_storeu_ps(
                pos + i,
                _mm256_max_ps(_mm256_sub_ps(x, _mm256_mul_ps(vE, _mm256_mul_ps(len, invD))), vFar));
            const __m256 u = _mm256_mul_ps(vE, invD);
            const __m256 eps =
                _mm256_mul_ps(u, _mm256_sub_ps(u, _mm256_div_ps(_mm256_add_ps(dx, dx), len)));
            const __m256 root = _mm256_sqrt_ps(_mm256_max_ps(vZero, _mm256_add_ps(vOne, eps)));
            _mm256_storeu_ps(dr + i,
                             _mm256_min_ps(_mm256_mul_ps(d, root), _mm256_set1_ps(kSkySentinel)));
        }
        return i;
    }
#endif

    // The colour and depth interpolated between two neighbouring reprojections (left pixels
    // i and j, at x0 and x0 + 1 / inv) over a run of slots: linear, so its sum over the slots is
    // their count times its value at their mean centre.
    struct Interpolation {
        double x0, inv, slots;
        Rgb8 ci, cj;
        float di, dj;
        bool finite;

        Interpolation(const float* pos, const float* depth, const Rgb8* color, int i, int j,
                      double slotCount)
            : x0(pos[i]),
              inv(1.0 / (pos[j] - x0)),
              slots(slotCount),
              ci(color[i]),
              cj(color[j]),
              di(depth[i]),
              dj(depth[j]),
              finite(di < kSkySentinel && dj < kSkySentinel) {}

        // Adds slots [s0, s1) (s0 < s1) to the packed colour and depth sums.
        void add(long s0, long s1, std::uint64_t& rgb, float& depth) const {
            const auto n = static_cast<float>(s1 - s0);
            const auto t = static_cast<float>((0.5 * (s0 + s1) / slots - x0) * inv);
            auto lerp = [n, t](int u, int v) {
                return static_cast<std::uint64_t>(n * (u + (v - u) * t) + 0.5f);
            };
            rgb += lerp(ci.r, cj.r) + (lerp(ci.g, cj.g) << 16) + (lerp(ci.b, cj.b) << 32);
            depth += n * (finite ? di + (dj - di) * t : (t < 0.5f ? di : dj));
        }
    };

    // What finishes a right pixel from its slots' sums; `sampled` and `cast` count the pixels.
    struct Finisher {
        Rgb8* __restrict__ color;
        float* __restrict__ depth;
        RightPixelSource* __restrict__ source;
        int* __restrict__ castInColumn;
        int slots, shift;
        std::uint64_t roundAll;
        float inverseAll;
        std::uint64_t sampled = 0, cast = 0;

        static constexpr float kInverse[9] = {0.0f,        1.0f,        0.5f,     1.0f / 3, 0.25f,
                                              1.0f / 5.0f, 1.0f / 6.0f, 1.0f / 7, 0.125f};
        // 2^16 / n rounded up: (sum * kScale[n] + 2^15) >> 16 is sum / n rounded, to within
        // 0.03 for sums up to 8 x 255.
        static constexpr std::uint32_t kScale[9] = {0,     65536, 32768, 21846, 16384,
                                                    13108, 10923, 9363,  8192};

        Finisher(const Out& out, int* castCounts, int slotCount, int slotShift)
            : color(out.color),
              depth(out.depth),
              source(out.source),
              castInColumn(castCounts),
              slots(slotCount),
              shift(slotShift),
              roundAll(static_cast<std::uint64_t>((1 << slotShift) >> 1) * 0x100010001ULL),
              inverseAll(kInverse[slotCount]) {}

        [[gnu::always_inline]] void pixel(int p, const PixelAcc& a) {
            if (2 * a.cast >= slots) {
                source[p] = RightPixelSource::RayCast;
                color[p] = Rgb8{255, 0, 255};  // overwritten by the second pass
                depth[p] = kSkyDepth;
                ++cast;
                ++castInColumn[p];
                return;
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
        // Adds the counts of w pixels to `counts`; interpolated = the rest.
        void count(int w, std::uint64_t* counts) const {
            counts[0] += sampled;
            counts[1] += static_cast<std::uint64_t>(w) - sampled - cast;
            counts[2] += cast;
        }
    };

    // Writes the row's right pixels from what their slots accumulated. (The finisher's
    // restrict pointers: the byte stores would otherwise force reloads of every member; its
    // counts stay in registers, where an indexed counter in memory would chain every pixel
    // on a store-to-load round trip.)
    void writeRow() {
        const PixelAcc* __restrict__ acc = acc_.data();
        Finisher finish(out_, castInColumn_.data(), slots_, shift_);
        for (int p = 0; p < w_; ++p)
            finish.pixel(p, acc[p]);
        finish.count(w_, out_.counts);
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
            const Interpolation between(posOf, depthOf, colorOf, i, j, slots);
            emit(lo, [&](long s0, long s1) {
                if (s0 < s1) between.add(s0, s1, aRgb, aDepth);
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

    // wanRow's result by another route (false where the processor lacks AVX2: wanRow then does
    // the row). The regions wanRow sweeps are known pixel by pixel without the sweep: where no
    // reprojection is hidden, left pixel k's footprint ends at its midpoint with k + 1 (or half
    // a pixel right of k where they are more than a pixel apart), and the gap between holds the
    // slots whose centres lie more than half a pixel from both; four pairs at a time. (A row
    // with a hidden reprojection finds them in wanRow's order instead, without its sums.) Right
    // pixels then go four at a time: where each of the four is covered by two abutting
    // footprints (k - 1, k) with k advancing one per pixel (disparity changing slowly: nearly
    // everywhere), its sums are those two footprints' parts added in wanRow's order, so even
    // the float depth sums are wanRow's to the bit. Any other pixel (a gap, three footprints,
    // the row's ends) is summed region by region as wanRow meets them.
#if VIG_STEREO_VECTOR
    // slotAt on four lanes: ceil(slots x - 0.5) clamped to [0, total].
    [[gnu::always_inline]] VIG_STEREO_AVX2 static __m128i slotsAt4(__m256d x, __m256d slots,
                                                                   __m256d zero, __m256d total) {
        const __m256d c =
            _mm256_round_pd(_mm256_sub_pd(_mm256_mul_pd(slots, x), _mm256_set1_pd(0.5)),
                            _MM_FROUND_TO_POS_INF | _MM_FROUND_NO_EXC);
        return _mm256_cvttpd_epi32(_mm256_min_pd(_mm256_max_pd(c, zero), total));
    }
    // A count in each of four 32-bit lanes, to every 16-bit lane of four 64-bit ones.
    [[gnu::always_inline]] VIG_STEREO_AVX2 static __m256i spreadCounts(__m128i n) {
        __m256i m = _mm256_cvtepu32_epi64(n);
        m = _mm256_or_si256(m, _mm256_slli_epi64(m, 16));
        return _mm256_or_si256(m, _mm256_slli_epi64(m, 32));
    }

    // Four pixels' colours, the low bytes of the 16-bit lanes 0..2 of four 64-bit ones, to
    // out[0..4) (twelve bytes, nothing past them).
    [[gnu::always_inline]] VIG_STEREO_AVX2 static void storeColors(__m256i v, Rgb8* out) {
        const __m128i lo = _mm256_castsi256_si128(v), hi = _mm256_extracti128_si256(v, 1);
        const __m128i a = _mm_shuffle_epi8(
            lo, _mm_setr_epi8(0, 2, 4, 8, 10, 12, -1, -1, -1, -1, -1, -1, -1, -1, -1, -1));
        const __m128i b = _mm_shuffle_epi8(
            hi, _mm_setr_epi8(-1, -1, -1, -1, -1, -1, 0, 2, 4, 8, 10, 12, -1, -1, -1, -1));
        const __m128i rgb = _mm_or_si128(a, b);
        auto* bytes = reinterpret_cast<unsigned char*>(out);
        _mm_storel_epi64(reinterpret_cast<__m128i*>(bytes), rgb);
        const int last = _mm_extract_epi32(rgb, 2);
        std::memcpy(bytes + 8, &last, 4);
    }

    // Needs AVX2 (the caller tests avx2_: this function is compiled for it).
    VIG_STEREO_AVX2 bool wanRowVector() {
        const float* __restrict__ posOf = pos_.data();
        const float* __restrict__ depthOf = depth_.data();
        const Rgb8* __restrict__ colorOf = in_;
        std::int32_t* __restrict__ lo = lo_.data();
        std::int32_t* __restrict__ hi = hi_.data();
        std::uint64_t* __restrict__ packed = packed_.data();
        const int w = w_, shift = shift_, S = slots_;
        const long total = total_;
        const double slots = slots_;
        auto slotAt = [slots, total](double x) {
            return static_cast<std::int32_t>(std::clamp(ceilLong(slots * x - 0.5), 0L, total));
        };

        bool hiddenRow = false;
        // The footprints: lo[k + 1] where k + 1's begins (its midpoint with k, or half a pixel
        // left of k + 1), hi[k] where k's ends (there, or half a pixel right of k where the
        // gap between them holds slots). Four pairs at a time, in doubles, as slotAt.
        lo[0] = slotAt(static_cast<double>(posOf[0]) - 0.5);
        int k = 0;
        {
            const __m256d vSlots = _mm256_set1_pd(slots), half = _mm256_set1_pd(0.5);
            const __m256d zero = _mm256_setzero_pd(),
                          top = _mm256_set1_pd(static_cast<double>(total));
            auto slotsAt = [&](__m256d x)
                               VIG_STEREO_AVX2 { return slotsAt4(x, vSlots, zero, top); };
            int hidden = 0;
            for (; k + 4 < w; k += 4) {
                const __m256d a = _mm256_cvtps_pd(_mm_loadu_ps(posOf + k));
                const __m256d b = _mm256_cvtps_pd(_mm_loadu_ps(posOf + k + 1));
                hidden |= _mm256_movemask_pd(_mm256_cmp_pd(a, b, _CMP_NLT_UQ));
                // std::max(mid, b - 0.5): mid unless it is less.
                const __m256d mid = _mm256_mul_pd(half, _mm256_add_pd(a, b));
                const __m256d left = _mm256_sub_pd(b, half);
                const __m128i e =
                    slotsAt(_mm256_blendv_pd(mid, left, _mm256_cmp_pd(mid, left, _CMP_LT_OQ)));
                const __m128i g = slotsAt(_mm256_add_pd(a, half));
                _mm_storeu_si128(reinterpret_cast<__m128i*>(lo + k + 1), e);
                _mm_storeu_si128(reinterpret_cast<__m128i*>(hi + k), _mm_min_epi32(g, e));
            }
            hiddenRow = hidden != 0;
        }
        for (; k + 1 < w && !hiddenRow; ++k) {
            const double a = posOf[k], b = posOf[k + 1];
            hiddenRow = !(a < b);
            const std::int32_t e = slotAt(std::max(0.5 * (a + b), b - 0.5));
            lo[k + 1] = e;
            hi[k] = std::min(slotAt(a + 0.5), e);
        }
        hi[w - 1] = slotAt(static_cast<double>(posOf[w - 1]) + 0.5);
        if (hiddenRow) {
            // Some reprojection is hidden (on or right of the one right of it): the sweep's
            // order, right to left. A hidden pixel gets an empty footprint where its accepted
            // right neighbour's begins, so that no region lies between them; next_ names each
            // pixel's accepted right neighbour (its partner in a gap).
            int* __restrict__ next = next_.data();
            int accepted = w - 1;  // the left-most accepted so far
            double pp = posOf[accepted];
            next[w - 1] = w;
            for (int i = w - 2; i >= 0; --i) {
                const double a = posOf[i];
                next[i] = accepted;
                if (!(a < pp)) continue;
                const std::int32_t e = slotAt(std::max(0.5 * (a + pp), pp - 0.5));
                lo[accepted] = e;
                hi[i] = std::min(slotAt(a + 0.5), e);
                for (int j = i + 1; j < accepted; ++j)
                    lo[j] = hi[j] = e;
                accepted = i;
                pp = a;
            }
            lo[accepted] = slotAt(pp - 0.5);
            for (int j = 0; j < accepted; ++j)
                lo[j] = hi[j] = lo[accepted];
        }
        for (int i = 0; i < w; ++i)
            packed[i] = packRgb(colorOf[i]);

        Finisher finish(out_, castInColumn_.data(), S, shift);
        // Any pixel: the regions it holds, from the right, as wanRow meets them.
        int kp = 0;  // the last footprint beginning left of the pixel's right end (monotone)
        auto generic = [&](int p) {
            const long p0 = static_cast<long>(p) << shift, p1 = p0 + S;
            while (kp + 1 < w && lo[kp + 1] < p1)
                ++kp;
            PixelAcc a{};
            bool reachedLeft = false;
            for (int j = lo[kp] < p1 ? kp : -1; j >= 0; --j) {
                // The region right of footprint j: the gap to j + 1, or the row's right end.
                const long gLo = std::max<long>(hi[j], p0);
                const long gHi = std::min<long>(j + 1 < w ? lo[j + 1] : total, p1);
                if (gLo < gHi) {
                    const int partner = hiddenRow ? next_[static_cast<std::size_t>(j)] : j + 1;
                    if (partner < w && static_cast<double>(posOf[partner]) - posOf[j] <= gap_) {
                        Interpolation(posOf, depthOf, colorOf, j, partner, slots)
                            .add(gLo, gHi, a.rgb, a.depthSum);
                    } else {
                        a.cast = static_cast<std::uint8_t>(a.cast + (gHi - gLo));
                    }
                }
                const long n = std::min<long>(hi[j], p1) - std::max<long>(lo[j], p0);
                if (n > 0) {
                    a.rgb += static_cast<std::uint64_t>(n) * packed[j];
                    a.depthSum += static_cast<float>(n) * depthOf[j];
                    a.sampled = true;
                }
                if (lo[j] <= p0) {
                    reachedLeft = true;
                    break;
                }
            }
            if (!reachedLeft) {  // the row's left end
                const long n = std::min<long>(lo[0], p1) - p0;
                if (n > 0) a.cast = static_cast<std::uint8_t>(a.cast + n);
            }
            finish.pixel(p, a);
        };

        const __m128i lane = _mm_setr_epi32(0, S, 2 * S, 3 * S), vS = _mm_set1_epi32(S);
        const __m256i roundAll = _mm256_set1_epi64x(static_cast<long long>(finish.roundAll));
        const __m128i shiftCount = _mm_cvtsi32_si128(shift);
        const __m128 inverseAll = _mm_set1_ps(finish.inverseAll), skyMean = _mm_set1_ps(kSkyMean);
        const __m128 skyDepth = _mm_set1_ps(kSkyDepth);
        std::uint32_t reprojected4;
        {
            const RightPixelSource r[4] = {
                RightPixelSource::Reprojected, RightPixelSource::Reprojected,
                RightPixelSource::Reprojected, RightPixelSource::Reprojected};
            std::memcpy(&reprojected4, r, 4);
        }
        int kB = 0;  // the footprint holding the last slot of the group's first pixel
        int p = 0;
        for (; p + 4 <= w; p += 4) {
            const std::int32_t p0 = p << shift, last = p0 + S - 1;
            kB = std::min(kB + 4, w - 1);
            while (kB > 0 && lo[kB] > last)
                --kB;
            while (kB + 1 < w && lo[kB + 1] <= last)
                ++kB;
            if (kB >= 1 && kB + 4 <= w) {
                const __m128i loB = _mm_loadu_si128(reinterpret_cast<const __m128i*>(lo + kB));
                const __m128i hiB = _mm_loadu_si128(reinterpret_cast<const __m128i*>(hi + kB));
                const __m128i loA = _mm_loadu_si128(reinterpret_cast<const __m128i*>(lo + kB - 1));
                const __m128i hiA = _mm_loadu_si128(reinterpret_cast<const __m128i*>(hi + kB - 1));
                const __m128i v0 = _mm_add_epi32(_mm_set1_epi32(p0), lane);
                const __m128i v1 = _mm_add_epi32(v0, vS);
                const __m128i vLast = _mm_sub_epi32(v1, _mm_set1_epi32(1));
                // Each pixel's last slot in footprint kB + i, which abuts kB + i - 1, which
                // holds the pixel's first slot.
                const __m128i bad =
                    _mm_or_si128(_mm_or_si128(_mm_cmpgt_epi32(loB, vLast),
                                              _mm_cmpgt_epi32(hiB, vLast) ^ _mm_set1_epi32(-1)),
                                 _mm_or_si128(_mm_cmpeq_epi32(hiA, loB) ^ _mm_set1_epi32(-1),
                                              _mm_cmpgt_epi32(loA, v0)));
                if (_mm_testz_si128(bad, bad)) {
                    const __m128i nB = _mm_sub_epi32(v1, _mm_max_epi32(loB, v0));
                    const __m128i nA = _mm_sub_epi32(vS, nB);
                    // Colours: each count times a packed colour, lane by 16-bit lane (at most
                    // 8 x 255: nothing carries), then the rounded mean as finish.pixel.
                    const __m256i cB =
                        _mm256_loadu_si256(reinterpret_cast<const __m256i*>(packed + kB));
                    const __m256i cA =
                        _mm256_loadu_si256(reinterpret_cast<const __m256i*>(packed + kB - 1));
                    const __m256i mB = spreadCounts(nB), mA = spreadCounts(nA);
                    const __m256i rgb =
                        _mm256_add_epi64(_mm256_mullo_epi16(cB, mB), _mm256_mullo_epi16(cA, mA));
                    storeColors(_mm256_srl_epi64(_mm256_add_epi64(rgb, roundAll), shiftCount),
                                finish.color + p);
                    // Depths: kB's part, then kB - 1's, as wanRow adds them.
                    const __m128 sum =
                        _mm_add_ps(_mm_mul_ps(_mm_cvtepi32_ps(nB), _mm_loadu_ps(depthOf + kB)),
                                   _mm_mul_ps(_mm_cvtepi32_ps(nA), _mm_loadu_ps(depthOf + kB - 1)));
                    const __m128 mean = _mm_mul_ps(sum, inverseAll);
                    _mm_storeu_ps(finish.depth + p,
                                  _mm_blendv_ps(skyDepth, mean, _mm_cmplt_ps(mean, skyMean)));
                    std::memcpy(finish.source + p, &reprojected4, 4);
                    finish.sampled += 4;
                    continue;
                }
            }
            kp = std::max(kp, kB);  // (kB begins left of the group's first pixel's end)
            for (int i = 0; i < 4; ++i)
                generic(p + i);
        }
        kp = std::max(kp, kB);
        for (; p < w; ++p)
            generic(p);
        finish.count(w, out_.counts);
        return true;
    }
#else
    bool wanRowVector() {
        return false;
    }
#endif

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

    // overwriteRow's result written straight to the right row: each pixel's last reprojection
    // (one slot, so finishing it is a copy) or, marked by its source, empty.
    void overwriteRowDirect() {
        Rgb8* __restrict__ color = out_.color;
        float* __restrict__ depth = out_.depth;
        RightPixelSource* __restrict__ source = out_.source;
        const float* __restrict__ posOf = pos_.data();
        const float* __restrict__ depthOf = depth_.data();
        const Rgb8* __restrict__ colorOf = in_;
        const int w = w_;
        std::fill_n(source, w, RightPixelSource::RayCast);
        long prevP = 0;
        for (int i = 0; i < w; ++i) {
            const long p = floorLong(posOf[i]);
            if (i > 0 && p - prevP > 1) [[unlikely]] {
                for (long q = std::max(0L, prevP + 1); q < std::min<long>(p, w); ++q)
                    source[q] = RightPixelSource::RayCast;
            }
            if (p >= 0 && p < w) {
                color[p] = colorOf[i];
                depth[p] = depthOf[i];
                source[p] = RightPixelSource::Reprojected;
            }
            prevP = p;
        }
        int* __restrict__ castInColumn = castInColumn_.data();
        std::uint64_t cast = 0;
        for (int p = 0; p < w; ++p) {
            if (source[p] == RightPixelSource::RayCast) {
                color[p] = Rgb8{255, 0, 255};  // overwritten by the second pass
                depth[p] = kSkyDepth;
                ++cast;
                ++castInColumn[p];
            } else if (!(depth[p] < kSkyMean)) {
                depth[p] = kSkyDepth;
            }
        }
        out_.counts[0] += static_cast<std::uint64_t>(w) - cast;
        out_.counts[2] += cast;
    }

    const RenderedFrame& left_;
    int w_;
    int slots_, shift_;
    long total_;
    double e_, gap_;
    bool sweep_;
    bool avx2_;  // the processor has AVX2 (base::cpuFeatures): project8 and wanRowVector run
    const Rgb8* in_ = nullptr;  // the row's left colours
    Out out_{};
    std::vector<float> pos_;
    std::vector<float> depth_;
    std::vector<PixelAcc> acc_;
    // wanRowVector's row: left pixel k's footprint is slots [lo_[k], hi_[k]) and packed_[k]
    // its colour.
    std::vector<std::int32_t> lo_, hi_;
    std::vector<std::uint64_t> packed_;
    std::vector<int> next_;
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

// The fast caster's coherence proof (ig/coherence.hpp) per horizontal metre: `upper` stays
// above the terrain wherever `lower` was, because its climb over `lower` outruns the most the
// terrain can rise across the gap between their unit tracks (both leave the eye; tracks less
// than a right angle apart).
bool coherent(const RayGeom& lower, const RayGeom& upper, double maxSlope) {
    return lower.horiz > 1e-9 && upper.horiz > 1e-9 && glm::dot(upper.track, lower.track) > 0.0 &&
           climbsClearOf(upper.slope - lower.slope, maxSlope, 1.0,
                         glm::length(upper.track - lower.track));
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
// Over a nested terrain (docs/design/insets.md) each ray is marched over the global map and
// every inset from the same start, the nearest hit kept: the nested surface is a height field,
// so the coherence holds with the steepest of the maps' slopes; a ray is sky without casting
// only above a rising ray from an eye over every map's top. `part` (nested only) gets each cast
// pixel's map: 0 the global map or sky, k + 1 inset k.
class ColumnCaster {
  public:
    ColumnCaster(const NestedMaps& maps, const Camera& camera, const SkyModel& sky,
                 const std::vector<RightPixelSource>& source, std::uint16_t* part)
        : map_(*maps.global),
          insets_(maps.insets),
          camera_(camera),
          sky_(sky),
          source_(source),
          part_(part) {
        const TerrainMap& map = map_;
        const glm::dvec3& p = camera.pose().position;
        eyeOverMap_ = p.x >= 0.0 && p.y >= 0.0 && p.x <= map.extentX() && p.y <= map.extentY();
        backoff_ = 2.0 * std::max(map.spacingX(), map.spacingY());
        maxSlope_ = map.maxSlope();
        double top = map.maxHeight();
        for (const NestedMaps::Part& in : insets_) {
            maxSlope_ = std::max(maxSlope_, in.map->maxSlope());
            top = std::max(top, in.map->maxHeight());
        }
        eyeOverAll_ = eyeOverMap_ && p.z >= top;
    }

    void column(int x, RenderedFrame& right, CastCounters& counters) const {
        const Intrinsics& in = camera_.intrinsics();
        const int w = in.width, h = in.height;
        const CameraBasis& b = camera_.basis();
        const glm::dvec3 base =
            in.focal * b.forward + (x + 0.5 - in.cx()) * b.right + in.cy() * b.up;
        const glm::dvec3 down = -b.up;
        const glm::dvec3 eye = camera_.pose().position;
        const double maxSlope = maxSlope_;
        const double topExit = map_.maxHeight() - 1e-9 * (1.0 + std::abs(map_.maxHeight()));
        const bool nested = !insets_.empty();

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
                if (part_) part_[idx] = 0;
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
            const bool fromPrev = havePrev && coherent(prev, g, maxSlope);
            double t0, t1, t = -1.0, tEnd = 0.0;
            std::uint16_t hitPart = 0;
            if (clipToMapBox(map_, ray, t0, t1)) {
                double tStart = t0;
                if (fromPrev) {
                    tStart = std::max(t0, prevDist / g.horiz);
                } else {
                    ++counters.restarts;
                }
                t = marchRay(map_, ray, tStart, t1, counters.steps);
                tEnd = t1;
                if (!nested && t < 0.0 && eyeOverMap_ && ray.at(t1).z >= topExit) {
                    haveSkyRef = true;
                    skyRef = g;
                }
            } else if (!nested && eyeOverMap_) {
                // The eye is over the map but outside its box: above it, and this ray never
                // comes down into it.
                haveSkyRef = true;
                skyRef = g;
            }
            if (nested) {
                tEnd = std::max(
                    tEnd, nearestInsetHit(eye, ray.dir, fromPrev ? prevDist / g.horiz : 0.0, t,
                                          hitPart, counters.steps));
            }
            if (nested && t < 0.0 && eyeOverAll_ && ray.dir.z >= 0.0) {
                haveSkyRef = true;
                skyRef = g;
            }
            prevDist = (t >= 0.0 ? t : tEnd) * g.horiz;
            havePrev = true;
            prev = g;
            if (part_) part_[idx] = hitPart;
            if (t >= 0.0) {
                const glm::dvec3 p = ray.at(t);
                right.color[idx] = hitColor(p, t, hitPart);
                right.depth[idx] = static_cast<float>(t);
            } else {
                right.color[idx] = skyColor(sky_, ray.dir.z);
                right.depth[idx] = kSkyDepth;
            }
        }
    }

    // Over a nested terrain, in columns [x0, x1) cast whole by the global map's caster: each
    // marked pixel's ray marched over every inset short of the global map's hit there, the
    // nearest hit kept.
    void insetsOver(int x0, int x1, RenderedFrame& right, CastCounters& counters) const {
        const Intrinsics& in = camera_.intrinsics();
        const CameraBasis& b = camera_.basis();
        const glm::dvec3 eye = camera_.pose().position;
        for (int x = x0; x < x1; ++x) {
            const glm::dvec3 base =
                in.focal * b.forward + (x + 0.5 - in.cx()) * b.right + in.cy() * b.up;
            for (int y = 0; y < in.height; ++y) {
                const std::size_t idx = static_cast<std::size_t>(y) * in.width + x;
                if (source_[idx] != RightPixelSource::RayCast) continue;
                const TerrainRay ray(map_, eye, base - (y + 0.5) * b.up);
                const float depth = right.depth[idx];
                double t = std::isfinite(depth) ? static_cast<double>(depth) : -1.0;
                std::uint16_t hitPart = 0;
                nearestInsetHit(eye, ray.dir, 0.0, t, hitPart, counters.steps);
                part_[idx] = hitPart;
                if (hitPart == 0) continue;
                right.color[idx] = hitColor(ray.at(t), t, hitPart);
                right.depth[idx] = static_cast<float>(t);
            }
        }
    }

  private:
    // Marches the ray from `eye` along unit `dir` over every inset from ray parameter `from`
    // (or the inset's entry) short of the hit `t` so far (-1: none), keeping the nearest: `t`
    // and `hitPart` (k + 1 for inset k) updated. Returns the farthest inset box exit (0: none).
    double nearestInsetHit(const glm::dvec3& eye, const glm::dvec3& dir, double from, double& t,
                           std::uint16_t& hitPart, std::uint64_t& steps) const {
        double exit = 0.0;
        for (std::size_t k = 0; k < insets_.size(); ++k) {
            const TerrainMap& m = *insets_[k].map;
            const TerrainRay local(m, eye - glm::dvec3{insets_[k].placement->origin, 0.0}, dir);
            double a0, a1;
            if (!clipToMapBox(m, local, a0, a1)) continue;
            exit = std::max(exit, a1);
            const double end = t >= 0.0 ? std::min(a1, t) : a1;
            const double start = std::max(a0, from);
            if (start > end) continue;
            const double ti = marchRay(m, local, start, end, steps);
            if (ti >= 0.0 && (t < 0.0 || ti <= t)) {
                t = ti;
                hitPart = static_cast<std::uint16_t>(k + 1);
            }
        }
        return exit;
    }
    // The colour at world point `p` (ray distance t) of the map `hitPart` names.
    Rgb8 hitColor(const glm::dvec3& p, double t, std::uint16_t hitPart) const {
        if (hitPart == 0) return terrainColor(map_, sky_, p.x, p.y, t);
        const NestedMaps::Part& in = insets_[hitPart - 1];
        const glm::dvec2 o = in.placement->origin;
        return terrainColor(*in.map, sky_, p.x - o.x, p.y - o.y, t);
    }

    const TerrainMap& map_;
    const std::vector<NestedMaps::Part>& insets_;
    const Camera& camera_;
    const SkyModel& sky_;
    const std::vector<RightPixelSource>& source_;
    std::uint16_t* part_;
    bool eyeOverMap_ = false, eyeOverAll_ = false;
    double backoff_ = 0.0, maxSlope_ = 0.0;
};

}  // namespace

namespace {

// The right eye's pixels whose surface lies nearer than frame.nearM, redrawn as the casters'
// near pass redraws theirs (clipNearer): the terrain where the ray enters it beyond the plane,
// over the map, or over a nested surface the nearest map's (ties to an inset), by the reference
// caster's shading; each is then a cast pixel (`source`, and `part` its map) for the finishing
// passes. Objects are drawn over both eyes afterwards (drawStereoObjects), which clips them.
void clipRightNearer(const NestedMaps& maps, const std::vector<RenderOptions>& insetOptions,
                     const RenderOptions& options, const Camera& camera, RenderedFrame& frame,
                     RightPixelSource* source, std::uint16_t* part) {
    const double nearM = frame.nearM;
    const Intrinsics& in = camera.intrinsics();
    const int w = in.width, h = in.height;
    const NearerThanPlane nearer(in, nearM);
    const glm::dvec3 eye = camera.pose().position;
    const double none = std::numeric_limits<double>::infinity();
    runWithThreads(options.threads, [&] {
        tbb::parallel_for(tbb::blocked_range<int>(0, h), [&](const tbb::blocked_range<int>& rows) {
            ObjectTraceScratch scratch;
            ObjectShading shading;
            for (int y = rows.begin(); y < rows.end(); ++y) {
                for (int x = 0; x < w; ++x) {
                    const std::size_t i = static_cast<std::size_t>(y) * w + x;
                    if (!nearer(frame.depth[i], x, y)) continue;
                    const TerrainRay global(*maps.global, eye,
                                            camera.rayDirection(x + 0.5, y + 0.5));
                    const double tNear = nearPlaneRange(camera, global.dir, nearM);
                    double best = entryBeyond(*maps.global, global, tNear, none);
                    std::size_t which = 0;  // 0: the global map; k + 1: inset k
                    for (std::size_t k = 0; k < maps.insets.size(); ++k) {
                        const NestedMaps::Part& p = maps.insets[k];
                        const TerrainRay local(*p.map, eye - glm::dvec3{p.placement->origin, 0.0},
                                               global.dir);
                        const double t = entryBeyond(*p.map, local, tNear, none);
                        if (t >= 0.0 && (best < 0.0 || t <= best)) {
                            best = t;
                            which = k + 1;
                        }
                    }
                    if (which == 0) {
                        shadeReferencePixel(*maps.global, options, global, best, tNear, false,
                                            frame, i, scratch, shading);
                    } else {
                        const NestedMaps::Part& p = maps.insets[which - 1];
                        const TerrainRay local(*p.map, eye - glm::dvec3{p.placement->origin, 0.0},
                                               global.dir);
                        shadeReferencePixel(*p.map, insetOptions[which - 1], local, best, tNear,
                                            false, frame, i, scratch, shading);
                    }
                    source[i] = RightPixelSource::RayCast;
                    if (part != nullptr) part[i] = static_cast<std::uint16_t>(which);
                }
            }
        });
    });
}

// reprojectRightEye over the global map alone (maps.insets empty) or a nested terrain, whose
// inset passes take `insetOptions` (insetPassOptions'; one per inset).
RenderedFrame reprojectOver(const NestedMaps& maps, const std::vector<RenderOptions>& insetOptions,
                            const RenderedFrame& left, const StereoOptions& options,
                            const RenderOptions& renderOptions,
                            std::vector<RightPixelSource>& source, StereoStats& stats,
                            const Caster* caster) {
    const TerrainMap& map = *maps.global;
    const bool nested = !maps.insets.empty();
    CHECK(insetOptions.size() == maps.insets.size());
    CHECK(maps.insets.size() < 65535) << "reprojectRightEye: too many insets";
    validateStereoOptions(options);
    if (left.pose.roll != 0.0) {
        throw InputError("pose: stereo reprojection renders roll = 0 (the PRP applies roll)");
    }
    const int w = left.width(), h = left.height();
    const std::size_t n = static_cast<std::size_t>(w) * h;
    CHECK(w > 0 && h > 0 && left.color.size() == n && left.depth.size() == n)
        << "reprojectRightEye: left frame without colour and depth";
    RenderedFrame right;
    right.sequence = left.sequence;
    right.time = left.time;
    right.pose = rightEyePose(left.pose, options.eyeSeparation);
    right.intrinsics = left.intrinsics;
    if (nested) {
        validateNestedView(maps, right.pose, right.intrinsics);
    } else {
        validateView(map, right.pose, right.intrinsics);
    }
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
    // Over a nested terrain: each cast pixel's map, for its own finishing passes.
    std::vector<std::uint16_t> part(nested ? n : 0, 0);
    const ColumnCaster columns(maps, camera, renderOptions.sky, source,
                               nested ? part.data() : nullptr);
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
        // Groups of columns at least a quarter marked are cast whole by the caster (a pixel
        // of a whole column costs it about a third of what one marked pixel on its own costs).
        std::vector<int> wholeUnits;
        std::vector<char> whole(static_cast<std::size_t>(w), 0);
        const int units = caster != nullptr ? caster->workUnits(camera) : 0;
        for (int u = 0; u < units; ++u) {
            const auto [x0, x1] = caster->unitColumns(camera, u);
            if (x1 <= x0) break;  // units of rows
            long count = 0;
            for (int x = x0; x < x1; ++x)
                count += marked[static_cast<std::size_t>(x)];
            if (4 * count < static_cast<long>(x1 - x0) * h) continue;
            wholeUnits.push_back(u);
            std::fill(whole.begin() + x0, whole.begin() + x1, char{1});
            stats.wholeColumns += static_cast<std::uint64_t>(x1 - x0);
        }
        if (!wholeUnits.empty()) {
            tbb::parallel_for(
                tbb::blocked_range<std::size_t>(0, wholeUnits.size(), 1),
                [&](const tbb::blocked_range<std::size_t>& r) {
                    CastCounters& c = castCounters.local();
                    std::vector<Rgb8> keptColor;
                    std::vector<float> keptDepth;
                    for (std::size_t i = r.begin(); i < r.end(); ++i) {
                        const auto [x0, x1] = caster->unitColumns(camera, wholeUnits[i]);
                        // The unit writes every pixel of its columns: keep the reprojected
                        // ones and put them back.
                        const std::size_t cols = static_cast<std::size_t>(x1 - x0);
                        keptColor.resize(cols * static_cast<std::size_t>(h));
                        keptDepth.resize(keptColor.size());
                        for (int y = 0; y < h; ++y) {
                            const std::size_t at = static_cast<std::size_t>(y) * w + x0;
                            std::copy_n(right.color.begin() + at, cols,
                                        keptColor.begin() + y * cols);
                            std::copy_n(right.depth.begin() + at, cols,
                                        keptDepth.begin() + y * cols);
                        }
                        UnitCounters unitCounters;
                        caster->renderUnit(camera, right, wholeUnits[i], unitCounters);
                        c.steps += unitCounters.steps;
                        c.restarts += unitCounters.restarts;
                        if (nested) columns.insetsOver(x0, x1, right, c);
                        for (int y = 0; y < h; ++y) {
                            for (int x = x0; x < x1; ++x) {
                                const std::size_t at = static_cast<std::size_t>(y) * w + x;
                                if (source[at] == RightPixelSource::RayCast) continue;
                                const std::size_t k = y * cols + static_cast<std::size_t>(x - x0);
                                right.color[at] = keptColor[k];
                                right.depth[at] = keptDepth[k];
                            }
                        }
                    }
                },
                tbb::simple_partitioner());
        }
        std::vector<int> queue;
        for (int x = 0; x < w; ++x) {
            if (marked[static_cast<std::size_t>(x)] > 0 && !whole[static_cast<std::size_t>(x)])
                queue.push_back(x);
        }
        std::stable_sort(queue.begin(), queue.end(), [&](int a, int b) {
            return marked[static_cast<std::size_t>(a)] > marked[static_cast<std::size_t>(b)];
        });
        tbb::parallel_for(
            tbb::blocked_range<std::size_t>(0, queue.size(), 1),
            [&](const tbb::blocked_range<std::size_t>& r) {
                CastCounters& c = castCounters.local();
                for (std::size_t i = r.begin(); i < r.end(); ++i)
                    columns.column(queue[i], right, c);
            },
            tbb::simple_partitioner());
    });
    // The near plane (a host's View Definition) is the same plane for both eyes (they are
    // apart across the view axis): what the left eye shows lies beyond it, and so does what is
    // reprojected from it; a cast pixel may not.
    right.nearM = left.nearM;
    if (right.nearM > 0.0) {
        clipRightNearer(maps, insetOptions, renderOptions, camera, right, source.data(),
                        nested ? part.data() : nullptr);
    }
    if (finishPassesOn(renderOptions)) {
        // The reprojected pixels carry the left eye's light (and height-dependent haze); the
        // cast ones get theirs as the caster finishes a frame (its levels), through a copy in
        // which every other pixel is sky, so that the passes (per pixel, sky left as it is)
        // light only them: a few per cent of the eye, not the whole of it again.
        const auto castOnly = [&](std::uint16_t ofMap) {
            RenderedFrame only = right;
            for (std::size_t i = 0; i < n; ++i) {
                if (source[i] != RightPixelSource::RayCast || (nested && part[i] != ofMap))
                    only.depth[i] = kSkyDepth;
            }
            return only;
        };
        RenderedFrame lit = castOnly(0);
        if (caster != nullptr) {
            caster->finishFrame(camera, lit);
        } else {
            finishLighting(renderOptions, LevelBands{}, camera, lit);
        }
        for (std::size_t i = 0; i < n; ++i) {
            if (source[i] == RightPixelSource::RayCast && (!nested || part[i] == 0))
                right.color[i] = lit.color[i];
        }
        // The pixels an inset's surface gives take that inset's passes, in its coordinates
        // (as the nested caster's inset passes run on their own frames).
        for (std::size_t k = 0; k < maps.insets.size(); ++k) {
            const auto id = static_cast<std::uint16_t>(k + 1);
            if (std::find(part.begin(), part.end(), id) == part.end()) continue;
            RenderedFrame own = castOnly(id);
            own.pose.position -= glm::dvec3{maps.insets[k].placement->origin, 0.0};
            finishLighting(insetOptions[k], LevelBands{}, Camera(own.pose, own.intrinsics), own);
            for (std::size_t i = 0; i < n; ++i) {
                if (source[i] == RightPixelSource::RayCast && part[i] == id)
                    right.color[i] = own.color[i];
            }
        }
    }
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
    if (nested) {
        castNestedControlPoints(maps, Camera(right.pose, right.intrinsics), right);
    } else {
        castControlPoints(map, Camera(right.pose, right.intrinsics), right);
    }
    return right;
}

}  // namespace

RenderedFrame reprojectRightEye(const TerrainMap& map, const RenderedFrame& left,
                                const StereoOptions& options, const RenderOptions& renderOptions,
                                std::vector<RightPixelSource>& source, StereoStats& stats,
                                const Caster* caster) {
    NestedMaps alone;
    alone.global = &map;
    return reprojectOver(alone, {}, left, options, renderOptions, source, stats, caster);
}

RenderedFrame reprojectRightEye(const NestedMaps& maps,
                                const std::vector<RenderOptions>& insetOptions,
                                const RenderedFrame& left, const StereoOptions& options,
                                const RenderOptions& renderOptions,
                                std::vector<RightPixelSource>& source, StereoStats& stats,
                                const Caster* globalCaster) {
    return reprojectOver(maps, insetOptions, left, options, renderOptions, source, stats,
                         globalCaster);
}

double drawStereoObjects(const RenderOptions& options, RenderedFrame& left, RenderedFrame& right) {
    const auto draw = [&](RenderedFrame& frame) {
        const auto start = Clock::now();
        const Camera camera(frame.pose, frame.intrinsics);
        // With a near plane, the finished terrain under the objects (see below).
        std::vector<Rgb8> bareColor;
        std::vector<float> bareDepth;
        if (frame.nearM > 0.0) {
            bareColor = frame.color;
            bareDepth = frame.depth;
        }
        runWithThreads(options.threads, [&] {
            drawObjectsOverTerrain(options.objects, options.sky, camera, frame);
        });
        if (frame.nearM > 0.0 && frame.objectId.size() == frame.depth.size()) {
            // The plane cuts the objects as the casters' near pass does: an object pixel nearer
            // than it shows the terrain it covered (already clipped and finished) under the
            // voxels its ray enters beyond the plane (traceObjects from there).
            const Intrinsics& in = frame.intrinsics;
            const glm::dvec3 eye = frame.pose.position;
            const NearerThanPlane nearer(in, frame.nearM);
            runWithThreads(options.threads, [&] {
                tbb::parallel_for(
                    tbb::blocked_range<int>(0, in.height),
                    [&](const tbb::blocked_range<int>& rows) {
                        ObjectTraceScratch scratch;
                        ObjectShading shading;
                        for (int y = rows.begin(); y < rows.end(); ++y) {
                            for (int x = 0; x < in.width; ++x) {
                                const std::size_t i = static_cast<std::size_t>(y) * in.width + x;
                                if (frame.objectId[i] == 0 || !nearer(frame.depth[i], x, y))
                                    continue;
                                const glm::dvec3 dir =
                                    glm::normalize(camera.rayDirection(x + 0.5, y + 0.5));
                                traceObjects(options.objects, eye, dir, bareDepth[i], options.sky,
                                             scratch, shading,
                                             nearPlaneRange(camera, dir, frame.nearM));
                                frame.color[i] = composeOver(shading, bareColor[i]);
                                frame.objectId[i] = shading.id;
                                frame.depth[i] = shading.id != 0 ? static_cast<float>(shading.depth)
                                                                 : bareDepth[i];
                            }
                        }
                    });
            });
        }
        // The terrain is finished (lit, hazed); the casters draw objects before the finishing
        // passes, whose light leaves object pixels as they are but whose height haze does
        // not: the object pixels take theirs through a copy.
        if (deferredHaze(options.sky) && !frame.objectId.empty()) {
            RenderedFrame hazed = frame;
            hazeFrame(options.sky, camera, hazed, options.threads);
            for (std::size_t i = 0; i < frame.color.size(); ++i)
                if (frame.objectId[i] != 0) frame.color[i] = hazed.color[i];
        }
        const double ms = std::chrono::duration<double, std::milli>(Clock::now() - start).count();
        frame.stats.renderMs += ms;
        return ms;
    };
    draw(left);
    return draw(right);
}

namespace {

// renderStereo's steps over any terrain: `eye` renders an eye's frame by the fast caster (with
// the options given), `reproject` the right eye from the left.
template <typename RenderEye, typename Reproject>
StereoFrame stereoPair(const Pose& pose, const StereoOptions& options,
                       const RenderOptions& renderOptions, RenderEye&& eye, Reproject&& reproject) {
    validateStereoOptions(options);
    if (pose.roll != 0.0) {
        throw InputError(
            "pose: stereo renders roll = 0 (the post-rendering processor applies roll)");
    }
    // With voxel objects the reprojection works on the terrain alone: the left eye is cast
    // without them, the right eye reprojected from that, and the objects' footprint pass then
    // draws them over each eye exactly as over a mono frame (docs/design/stereo.md, "Voxel objects
    // in the pair").
    const bool objects =
        !renderOptions.objects.empty() && options.method == RightEyeMethod::Reproject;
    RenderOptions terrainOptions = renderOptions;
    if (objects) terrainOptions.objects.clear();
    StereoFrame out;
    out.left = eye(terrainOptions, pose);
    out.stats.leftMs = out.left.stats.renderMs;
    if (options.method == RightEyeMethod::Raycast) {
        out.right = eye(terrainOptions, rightEyePose(pose, options.eyeSeparation));
        out.right.sequence = out.left.sequence;
        out.stats.rightMs = out.right.stats.renderMs;
        out.stats.castMs = out.stats.rightMs;
        out.stats.rayCast = out.right.color.size();
        out.stats.steps = out.right.stats.steps;
        out.stats.restarts = out.right.stats.restarts;
        return out;
    }
    out.right = reproject(terrainOptions, out.left, out.source, out.stats);
    if (objects) {
        out.stats.objectsMs = drawStereoObjects(renderOptions, out.left, out.right);
        out.stats.leftMs = out.left.stats.renderMs;
        out.stats.rightMs += out.stats.objectsMs;
        out.right.stats.renderMs = out.stats.rightMs;
    }
    return out;
}

}  // namespace

StereoFrame renderStereo(const TerrainMap& map, const Pose& pose, const Intrinsics& intrinsics,
                         const StereoOptions& options, const RenderOptions& renderOptions,
                         double time) {
    std::unique_ptr<Caster> caster;
    return stereoPair(
        pose, options, renderOptions,
        [&](const RenderOptions& o, const Pose& at) {
            if (!caster) caster = makeCaster(CasterKind::Fast, map, o);
            return renderFrame(*caster, map, at, intrinsics, time, 0, options.nearM);
        },
        [&](const RenderOptions& o, const RenderedFrame& left,
            std::vector<RightPixelSource>& source, StereoStats& stats) {
            return reprojectRightEye(map, left, options, o, source, stats, caster.get());
        });
}

StereoFrame renderStereo(const NestedMaps& maps, const std::vector<RenderOptions>& insetOptions,
                         const Pose& pose, const Intrinsics& intrinsics,
                         const StereoOptions& options, const RenderOptions& renderOptions,
                         double time) {
    std::unique_ptr<Caster> caster;
    return stereoPair(
        pose, options, renderOptions,
        [&](const RenderOptions& o, const Pose& at) {
            if (!caster) caster = makeNestedCaster(CasterKind::Fast, maps, o, insetOptions);
            return renderNestedFrame(*caster, maps, at, intrinsics, time, 0, options.nearM);
        },
        [&](const RenderOptions& o, const RenderedFrame& left,
            std::vector<RightPixelSource>& source, StereoStats& stats) {
            return reprojectRightEye(maps, insetPassOptions(maps, insetOptions), left, options, o,
                                     source, stats, nestedGlobalCaster(*caster));
        });
}

StereoFrame renderStereo(const NestedTerrain& terrain, const Pose& pose,
                         const Intrinsics& intrinsics, const StereoOptions& options,
                         const RenderOptions& renderOptions, double time) {
    const NestedMaps& maps = terrain.maps();
    return renderStereo(maps, std::vector<RenderOptions>(maps.insets.size(), renderOptions), pose,
                        intrinsics, options, renderOptions, time);
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
