#include "ig/synthetic.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/partitioner.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <numbers>
#include <string>
#include <vector>

#include "base/check.hpp"
#include "ig/error.hpp"

// The relief is a sum of gradient-noise fields, each a fixed function of world position (metres)
// and the seed. Wavelengths are fixed in metres; only the finest detail octaves depend on the
// spacing (they stop at two samples per wavelength). Components:
//   continent  broad lowlands, hills and sea basins (wavelengths 40..10 km, about +-560 m)
//   mountains  ridged multifractal (9 km .. 1.1 km) under a mask: peaks near 2000 m, hills
//              of a couple of hundred metres where the mask is low
//   detail     fractional Brownian motion from 800 m down to the cell, rougher in the mountains
//   valleys    a domain-warped noise whose zero set carves winding valleys into the land
// Water is flat at sea level; colours come from height, slope, a moisture field and a lambert
// shade, with a small per-sample variation hashed from the sample's world position.
//
// Speed: the broad fields (continent, mountain mask, warped valley noise: 8 noise evaluations)
// change little over a few hundred metres, so they are evaluated on a coarse world-aligned
// lattice (every k samples, k * spacing <= 160 m) and interpolated with Catmull-Rom splines,
// which keep slopes continuous (no faceting in the shading). The lattice depends only on the
// spacing, so every value is still a function of world position alone.

namespace ig {
namespace {

constexpr int kMaxOctaves = 24;
constexpr int kMaxSize = 16384;
constexpr double kMinSpacing = 0.01, kMaxSpacing = 10000.0;  // metres

inline std::uint64_t mix64(std::uint64_t z) {
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
    return z ^ (z >> 31);
}

// Lattice hash: cheap (two multiplies), good enough in its top bits for choosing gradients.
inline std::uint64_t hashLattice(std::int64_t ix, std::int64_t iy, std::uint64_t key) {
    std::uint64_t h = (static_cast<std::uint64_t>(ix) * 0x9E3779B97F4A7C15ULL) ^
                      (static_cast<std::uint64_t>(iy) * 0xC2B2AE3D27D4EB4FULL) ^ key;
    h ^= h >> 29;
    h *= 0xBF58476D1CE4E5B9ULL;
    return h ^ (h >> 32);
}

// Sixteen unit gradient directions.
struct GradientTable {
    double x[16], y[16];
    GradientTable() {
        for (int k = 0; k < 16; ++k) {
            const double a = (k + 0.5) * 2.0 * std::numbers::pi / 16.0;
            x[k] = std::cos(a);
            y[k] = std::sin(a);
        }
    }
};
const GradientTable kGradients;

inline double fade(double t) {
    return t * t * t * (t * (t * 6.0 - 15.0) + 10.0);
}

inline double gradDot(std::uint64_t h, double dx, double dy) {
    const int k = static_cast<int>(h >> 60);
    return kGradients.x[k] * dx + kGradients.y[k] * dy;
}

// 2D gradient noise, roughly in [-1, 1].
inline double gradientNoise(double x, double y, std::uint64_t key) {
    // floor without a library call (the baseline x86-64 target has no rounding instruction).
    std::int64_t ix = static_cast<std::int64_t>(x), iy = static_cast<std::int64_t>(y);
    ix -= x < static_cast<double>(ix);
    iy -= y < static_cast<double>(iy);
    const double dx = x - static_cast<double>(ix), dy = y - static_cast<double>(iy);
    const double u = fade(dx), v = fade(dy);
    const double g00 = gradDot(hashLattice(ix, iy, key), dx, dy);
    const double g10 = gradDot(hashLattice(ix + 1, iy, key), dx - 1.0, dy);
    const double g01 = gradDot(hashLattice(ix, iy + 1, key), dx, dy - 1.0);
    const double g11 = gradDot(hashLattice(ix + 1, iy + 1, key), dx - 1.0, dy - 1.0);
    const double a = g00 + u * (g10 - g00);
    const double b = g01 + u * (g11 - g01);
    return 1.4142135623730951 * (a + v * (b - a));
}

inline double smoothstep(double e0, double e1, double x) {
    const double t = std::clamp((x - e0) / (e1 - e0), 0.0, 1.0);
    return t * t * (3.0 - 2.0 * t);
}

// One octave: frequency (1/m), amplitude, a rotation and offset that decorrelate octaves.
struct Octave {
    double freq = 0, amp = 0, c = 1, s = 0, ox = 0, oy = 0;
    std::uint64_t key = 0;
    double noise(double x, double y) const {
        const double u = (c * x - s * y) * freq + ox;
        const double v = (s * x + c * y) * freq + oy;
        return gradientNoise(u, v, key);
    }
};

struct Field {
    std::array<Octave, kMaxOctaves> octave{};
    int count = 0;
    double norm = 1;  // 1 / sum of amplitudes

    // Octaves from `wavelength` metres, halving each time, amplitude times `gain` per octave;
    // stops after `maxCount` octaves or below `minWavelength`.
    Field(std::uint64_t seed, std::uint64_t component, double wavelength, double gain, int maxCount,
          double minWavelength = 0) {
        double amp = 1, sum = 0;
        for (int k = 0; k < maxCount && k < kMaxOctaves && wavelength >= minWavelength; ++k) {
            const std::uint64_t key = mix64(seed ^ mix64(component * 1000 + k + 1));
            const double angle = (key >> 11) * 0x1.0p-53 * 2.0 * std::numbers::pi;
            Octave& o = octave[count++];
            o.freq = 1.0 / wavelength;
            o.amp = amp;
            o.c = std::cos(angle);
            o.s = std::sin(angle);
            o.ox = static_cast<double>(mix64(key) >> 40) * 0x1.0p-24 * 256.0;
            o.oy = static_cast<double>(mix64(key + 1) >> 40) * 0x1.0p-24 * 256.0;
            o.key = key;
            sum += amp;
            amp *= gain;
            wavelength *= 0.5;
        }
        norm = sum > 0 ? 1.0 / sum : 0.0;
    }

    // Fractional Brownian motion, roughly in [-1, 1].
    double fbm(double x, double y) const {
        double v = 0;
        for (int k = 0; k < count; ++k)
            v += octave[k].amp * octave[k].noise(x, y);
        return v * norm;
    }
    // The same, also returning the (unnormalised) sum of the first `n` octaves in `partial`.
    double fbm(double x, double y, int n, double* partial) const {
        double v = 0;
        for (int k = 0; k < count; ++k) {
            if (k == n) *partial = v;
            v += octave[k].amp * octave[k].noise(x, y);
        }
        if (n >= count) *partial = v;
        return v * norm;
    }

    // Ridged multifractal in [0, 1]: sharp crests where the noise crosses zero, each octave
    // weighted by the one above so detail gathers on the ridges.
    double ridged(double x, double y) const {
        double v = 0, weight = 1;
        for (int k = 0; k < count; ++k) {
            double r = 1.0 - std::abs(octave[k].noise(x, y));
            r = r * r * weight;
            weight = std::clamp(2.0 * r, 0.0, 1.0);
            v += octave[k].amp * r;
        }
        return v * norm;
    }
};

// Broad fields, evaluated on the coarse lattice.
struct Broad {
    double continent;  // about -1 .. 1
    double mask;       // mountain mask field before its smoothstep, about -1 .. 1
    double valley;     // warped valley noise; valleys where it is near zero
};
constexpr int kBroadFields = 3;

// The terrain's fields at one world position.
struct Sample {
    double height;    // metres, below sea level where water
    float moisture;   // 0 dry .. 1 wet
    float variation;  // about -1 .. 1, a broad field that shifts the snow and tree lines
};

class Generator {
  public:
    Generator(std::uint64_t seed, double spacing)
        : continent_(seed, 1, 40000, 0.5, 3),
          mask_(seed, 2, 24000, 0.5, 2),
          warpX_(seed, 3, 14000, 0.5, 1),
          warpY_(seed, 4, 14000, 0.5, 1),
          valley_(seed, 5, 7000, 0.5, 1),
          ridge_(seed, 6, 9000, 0.5, 4),
          detail_(seed, 7, 800, 0.55, kMaxOctaves, 2.0 * spacing) {
        // Detail in metres: the first octave swings about +-55 m.
        // (At spacings over 400 m there are no detail octaves.)
        detailMetres_ = detail_.count > 0 ? 55.0 / detail_.norm : 0.0;
    }

    Broad broad(double x, double y) const {
        const double wx = x + 3000.0 * warpX_.fbm(x, y);
        const double wy = y + 3000.0 * warpY_.fbm(x, y);
        return Broad{continent_.fbm(x, y), mask_.fbm(x, y), valley_.fbm(wx, wy)};
    }

    Sample eval(double x, double y, const Broad& b) const {
        const double mask = smoothstep(-0.2, 0.4, b.mask);
        const double ridge = ridge_.ridged(x, y);
        double patch = 0;  // the two broadest detail octaves, reused for vegetation patches
        const double detail = detail_.fbm(x, y, 2, &patch) * detailMetres_ * (0.35 + 0.65 * mask);
        double h = 560.0 * b.continent + 110.0 + (1900.0 * mask + 220.0) * ridge * ridge + detail;
        // Valleys: near the zero set of the warped noise the land sinks towards 30% of its height.
        const double v = std::abs(b.valley);
        // Wider valleys in the mountains keep their walls from turning into cliffs.
        if (h > 0) h *= 0.3 + 0.7 * smoothstep(0.0, 0.12 + 0.22 * mask, v);
        const double moisture = 0.65 * (1.0 - smoothstep(0.0, 0.3, v)) + 0.4 * (0.2 - b.continent) +
                                1.2 * patch * detail_.norm;
        return Sample{h, static_cast<float>(std::clamp(moisture, 0.0, 1.0)),
                      static_cast<float>(b.continent + 0.5 * b.mask)};
    }

  private:
    Field continent_, mask_, warpX_, warpY_, valley_, ridge_, detail_;
    double detailMetres_ = 0;
};

struct Color {
    double r, g, b;
};

inline Color mixColor(Color a, Color b, double t) {
    return Color{a.r + (b.r - a.r) * t, a.g + (b.g - a.g) * t, a.b + (b.b - a.b) * t};
}

// Land cover by height (m), slope (rise over run), moisture and variation; returns an albedo.
inline Color landColor(double h, double slope, double moisture, double variation) {
    constexpr Color kSand{196, 182, 136}, kGrass{104, 138, 62}, kDryGrass{146, 146, 90};
    constexpr Color kForest{46, 82, 42}, kRock{122, 112, 100}, kSnow{240, 242, 248};
    Color c = mixColor(kDryGrass, kGrass, smoothstep(0.05, 0.45, moisture));
    // Forest on moist ground below the tree line.
    const double treeLine = 1150.0 + 250.0 * variation;
    const double forest =
        smoothstep(0.45, 0.65, moisture) * (1.0 - smoothstep(treeLine - 150, treeLine, h));
    c = mixColor(c, kForest, forest);
    // Beach just above the water.
    c = mixColor(c, kSand, 1.0 - smoothstep(1.5, 4.0, h));
    // Bare rock on steep slopes and high ground.
    const double rock = std::max(smoothstep(0.55, 0.85, slope), smoothstep(1600.0, 2000.0, h));
    c = mixColor(c, kRock, rock);
    // Snow above the snow line where it can lie.
    const double snowLine = 1500.0 + 300.0 * variation;
    const double snow =
        smoothstep(snowLine, snowLine + 200.0, h) * (1.0 - smoothstep(0.8, 1.1, slope));
    return mixColor(c, kSnow, snow);
}

inline Color waterColor(double depth) {
    constexpr Color kShallow{58, 120, 140}, kDeep{18, 46, 88};
    return mixColor(kShallow, kDeep, smoothstep(0.0, 40.0, depth));
}

inline std::uint8_t toByte(double v) {
    return static_cast<std::uint8_t>(std::clamp(v, 0.0, 255.0) + 0.5);
}

inline int floorDiv(int a, int b) {
    return a >= 0 ? a / b : -((-a + b - 1) / b);
}

// Catmull-Rom weights for taps at -1, 0, 1, 2 and fraction t.
struct CubicWeights {
    double w[4];
};

CubicWeights catmullRom(double t) {
    const double t2 = t * t, t3 = t2 * t;
    return CubicWeights{{0.5 * (-t3 + 2 * t2 - t), 0.5 * (3 * t3 - 5 * t2 + 2),
                         0.5 * (-3 * t3 + 4 * t2 + t), 0.5 * (t3 - t2)}};
}

// Evaluates and shades columns [i0, i1) of rows [j0, j1) of the map; sample (i, j) is written
// at row j - outRow0, column i - i0 of `heights` and `colors` (i1 - i0 samples a row).
void generateRows(const Generator& gen, int i0, int i1, double spacing, std::uint64_t seed, int j0,
                  int j1, int outRow0, std::uint16_t* heights, Rgb8* colors) {
    // Coarse lattice step in samples: at most 160 m, at most 8 samples.
    const int k = static_cast<int>(std::clamp(160.0 / spacing, 1.0, 8.0));
    std::vector<CubicWeights> weights(k);
    for (int r = 0; r < k; ++r)
        weights[r] = catmullRom(static_cast<double>(r) / k);

    // The block holds rows j0-1 .. j1 and columns i0-1 .. i1 (a one-sample border for slopes).
    const int width = i1 - i0;
    const int bw = width + 2, bh = j1 - j0 + 2;
    // Lattice nodes covering the block with the spline's extra taps.
    const int nx0 = floorDiv(i0 - 1, k) - 1, nx1 = floorDiv(i1, k) + 2;
    const int ny0 = floorDiv(j0 - 1, k) - 1, ny1 = floorDiv(j1, k) + 2;
    const int nw = nx1 - nx0 + 1, nh = ny1 - ny0 + 1;
    std::vector<double> nodes(static_cast<std::size_t>(nw) * nh * kBroadFields);
    for (int ny = 0; ny < nh; ++ny) {
        for (int nx = 0; nx < nw; ++nx) {
            const Broad b = gen.broad((nx0 + nx) * k * spacing, (ny0 + ny) * k * spacing);
            double* n = &nodes[(static_cast<std::size_t>(ny) * nw + nx) * kBroadFields];
            n[0] = b.continent;
            n[1] = b.mask;
            n[2] = b.valley;
        }
    }

    std::vector<double> hb(static_cast<std::size_t>(bw) * bh);
    std::vector<float> moist(hb.size()), vary(hb.size());
    std::vector<double> rowNodes(static_cast<std::size_t>(nw) * kBroadFields);
    for (int bj = 0; bj < bh; ++bj) {
        const int j = j0 - 1 + bj;
        const double y = j * spacing;
        // Interpolate the lattice along y for this row.
        const int my = floorDiv(j, k);
        const CubicWeights& wy = weights[j - my * k];
        for (int nx = 0; nx < nw; ++nx) {
            for (int f = 0; f < kBroadFields; ++f) {
                double v = 0;
                for (int t = 0; t < 4; ++t) {
                    const std::size_t row = static_cast<std::size_t>(my - 1 + t - ny0);
                    v += wy.w[t] * nodes[(row * nw + nx) * kBroadFields + f];
                }
                rowNodes[static_cast<std::size_t>(nx) * kBroadFields + f] = v;
            }
        }
        for (int bi = 0; bi < bw; ++bi) {
            const int i = i0 + bi - 1;
            const int mx = floorDiv(i, k);
            const CubicWeights& wx = weights[i - mx * k];
            const double* n = &rowNodes[static_cast<std::size_t>(mx - 1 - nx0) * kBroadFields];
            double f[kBroadFields] = {};
            for (int t = 0; t < 4; ++t) {
                for (int q = 0; q < kBroadFields; ++q)
                    f[q] += wx.w[t] * n[t * kBroadFields + q];
            }
            const Sample s = gen.eval(i * spacing, y, Broad{f[0], f[1], f[2]});
            const std::size_t idx = static_cast<std::size_t>(bj) * bw + bi;
            hb[idx] = s.height;
            moist[idx] = s.moisture;
            vary[idx] = s.variation;
        }
    }

    // Sun from the north-west, 45 degrees up.
    const double sunAz = 315.0 * std::numbers::pi / 180.0, sunEl = std::numbers::pi / 4;
    const double lx = std::sin(sunAz) * std::cos(sunEl), ly = std::cos(sunAz) * std::cos(sunEl);
    const double lz = std::sin(sunEl);
    const double inv2s = 0.5 / spacing;
    for (int j = j0; j < j1; ++j) {
        const std::size_t row = static_cast<std::size_t>(j - j0 + 1) * bw;
        for (int i = i0; i < i1; ++i) {
            const std::size_t q = row + (i - i0) + 1;
            const double h = hb[q];
            // Land stays at least one height quantum above the water, so a sample is water
            // exactly when its height is the sea level.
            const double surface = h < kSyntheticSeaLevel
                                       ? kSyntheticSeaLevel
                                       : std::max(h, kSyntheticSeaLevel + kSyntheticHeightScale);
            // Slope of the surface (water flat) by central differences.
            const double dzdx = (std::max(hb[q + 1], kSyntheticSeaLevel) -
                                 std::max(hb[q - 1], kSyntheticSeaLevel)) *
                                inv2s;
            const double dzdy = (std::max(hb[q + bw], kSyntheticSeaLevel) -
                                 std::max(hb[q - bw], kSyntheticSeaLevel)) *
                                inv2s;
            const double slope = std::sqrt(dzdx * dzdx + dzdy * dzdy);
            const Color c = h < kSyntheticSeaLevel ? waterColor(kSyntheticSeaLevel - h)
                                                   : landColor(surface, slope, moist[q], vary[q]);
            const double lambert =
                std::max(0.0, (-dzdx * lx - dzdy * ly + lz) / std::sqrt(slope * slope + 1));
            // Small per-sample variation, hashed from the sample's grid position.
            const double jitter =
                static_cast<double>(hashLattice(i, j, seed ^ 0x5EEDULL) >> 11) * 0x1.0p-53;
            const double light = (0.3 + 0.7 * lambert / lz) * (0.95 + 0.1 * jitter);
            const std::size_t out = static_cast<std::size_t>(j - outRow0) * width + (i - i0);
            colors[out] = Rgb8{toByte(c.r * light), toByte(c.g * light), toByte(c.b * light)};
            const double raw =
                std::round((surface - kSyntheticHeightOffset) / kSyntheticHeightScale);
            heights[out] = static_cast<std::uint16_t>(std::clamp(raw, 0.0, 65535.0));
        }
    }
}

void checkSynthetic(int size, int maxSize, double spacing) {
    if (size < 2 || size > maxSize || (size & (size - 1)) != 0) {
        throw InputError("synthetic terrain size: must be a power of two from 2 to " +
                         std::to_string(maxSize) + " (got " + std::to_string(size) + ")");
    }
    if (!(spacing >= kMinSpacing && spacing <= kMaxSpacing)) {
        throw InputError("synthetic terrain spacing: must be " + std::to_string(kMinSpacing) +
                         " to " + std::to_string(kMaxSpacing) + " metres (got " +
                         std::to_string(spacing) + ")");
    }
}

}  // namespace

void generateSyntheticRows(int size, std::uint64_t seed, double spacing, int j0, int j1,
                           std::uint16_t* heights, Rgb8* colors) {
    checkSynthetic(size, kMaxSyntheticStreamSize, spacing);
    CHECK(0 <= j0 && j0 <= j1 && j1 <= size);
    const Generator gen(seed, spacing);
    tbb::parallel_for(
        tbb::blocked_range<int>(j0, j1, 32),
        [&](const tbb::blocked_range<int>& rows) {
            generateRows(gen, 0, size, spacing, seed, rows.begin(), rows.end(), j0, heights,
                         colors);
        },
        tbb::simple_partitioner());
}

void generateSyntheticWindow(int size, std::uint64_t seed, double spacing, int i0, int i1, int j0,
                             int j1, std::uint16_t* heights, Rgb8* colors) {
    checkSynthetic(size, kMaxSyntheticStreamSize, spacing);
    CHECK(0 <= i0 && i0 <= i1 && i1 <= size && 0 <= j0 && j0 <= j1 && j1 <= size);
    const Generator gen(seed, spacing);
    tbb::parallel_for(
        tbb::blocked_range<int>(j0, j1, 32),
        [&](const tbb::blocked_range<int>& rows) {
            generateRows(gen, i0, i1, spacing, seed, rows.begin(), rows.end(), j0, heights, colors);
        },
        tbb::simple_partitioner());
}

TerrainMap makeSyntheticTerrain(int size, std::uint64_t seed, double spacing) {
    checkSynthetic(size, kMaxSize, spacing);
    const Generator gen(seed, spacing);
    TerrainMap map(size, size, spacing, spacing, kSyntheticHeightScale, kSyntheticHeightOffset);
    std::uint16_t* heights = map.rawHeights().data();
    Rgb8* colors = map.colors().data();
    // Blocks of rows; every value depends only on its world position, so the result does not
    // depend on the blocking or the thread count.
    tbb::parallel_for(
        tbb::blocked_range<int>(0, size, 32),
        [&](const tbb::blocked_range<int>& rows) {
            generateRows(gen, 0, size, spacing, seed, rows.begin(), rows.end(), 0, heights, colors);
        },
        tbb::simple_partitioner());
    map.updateRange();
    return map;
}

}  // namespace ig
