#include "ig/synthetic.hpp"

#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

#include "ig/error.hpp"

namespace {

using ig::makeSyntheticTerrain;
using ig::TerrainMap;

bool sameMaps(const TerrainMap& a, const TerrainMap& b) {
    return a.width() == b.width() && a.height() == b.height() && a.rawHeights() == b.rawHeights() &&
           a.colors() == b.colors();
}

TEST(SyntheticTerrain, DeterministicPerSeed) {
    const TerrainMap a = makeSyntheticTerrain(64, 7, 20.0);
    const TerrainMap b = makeSyntheticTerrain(64, 7, 20.0);
    EXPECT_TRUE(sameMaps(a, b));
    const TerrainMap c = makeSyntheticTerrain(64, 8, 20.0);
    EXPECT_NE(a.rawHeights(), c.rawHeights());
    EXPECT_NE(a.colors(), c.colors());
}

TEST(SyntheticTerrain, SmallerMapIsTheSouthWestCornerOfALargerOne) {
    for (std::uint64_t seed : {1u, 99u}) {
        const TerrainMap small = makeSyntheticTerrain(256, seed);
        const TerrainMap large = makeSyntheticTerrain(512, seed);
        int rawMismatches = 0, colorMismatches = 0;
        for (int iy = 0; iy < 256; ++iy) {
            for (int ix = 0; ix < 256; ++ix) {
                rawMismatches += small.raw(ix, iy) != large.raw(ix, iy);
                colorMismatches += !(small.colorAt(ix, iy) == large.colorAt(ix, iy));
            }
        }
        EXPECT_EQ(rawMismatches, 0) << "seed " << seed;
        EXPECT_EQ(colorMismatches, 0) << "seed " << seed;
    }
    // The same holds at another spacing, down to the smallest map.
    const TerrainMap tiny = makeSyntheticTerrain(2, 5, 37.5);
    const TerrainMap big = makeSyntheticTerrain(32, 5, 37.5);
    for (int iy = 0; iy < 2; ++iy) {
        for (int ix = 0; ix < 2; ++ix) {
            EXPECT_EQ(tiny.raw(ix, iy), big.raw(ix, iy));
            EXPECT_EQ(tiny.colorAt(ix, iy), big.colorAt(ix, iy));
        }
    }
}

TEST(SyntheticTerrain, AWindowIsThoseSamplesOfTheWholeMap) {
    // Windows of every alignment to the coarse lattice (every k samples), at two spacings,
    // against the whole map: the same samples.
    for (const double spacing : {10.0, 2.5}) {
        const TerrainMap whole = makeSyntheticTerrain(256, 11, spacing);
        for (const auto& [i0, i1, j0, j1] : {std::array<int, 4>{0, 256, 0, 256},
                                             {1, 2, 255, 256},
                                             {37, 101, 5, 70},
                                             {128, 256, 0, 9},
                                             {3, 200, 190, 256}}) {
            std::vector<std::uint16_t> h(static_cast<std::size_t>(i1 - i0) * (j1 - j0));
            std::vector<ig::Rgb8> c(h.size());
            ig::generateSyntheticWindow(256, 11, spacing, i0, i1, j0, j1, h.data(), c.data());
            int mismatches = 0;
            for (int j = j0; j < j1; ++j) {
                for (int i = i0; i < i1; ++i) {
                    const std::size_t k = static_cast<std::size_t>(j - j0) * (i1 - i0) + (i - i0);
                    mismatches += h[k] != whole.raw(i, j) || !(c[k] == whole.colorAt(i, j));
                }
            }
            EXPECT_EQ(mismatches, 0) << "window " << i0 << ".." << i1 << " x " << j0 << ".." << j1
                                     << " at " << spacing << " m";
        }
    }
}

TEST(SyntheticTerrain, IndependentOfThreadCount) {
    TerrainMap one;
    {
        tbb::global_control single(tbb::global_control::max_allowed_parallelism, 1);
        one = makeSyntheticTerrain(128, 3, 25.0);
    }
    const TerrainMap many = makeSyntheticTerrain(128, 3, 25.0);
    EXPECT_TRUE(sameMaps(one, many));
}

TEST(SyntheticTerrain, SizeMustBeAPowerOfTwoUpTo16384) {
    for (int bad : {-4, 0, 1, 3, 6, 100, 1000, 32768, 1 << 30}) {
        EXPECT_THROW(makeSyntheticTerrain(bad, 1), ig::InputError) << bad;
    }
    for (int good : {2, 4, 8, 64}) {
        const TerrainMap m = makeSyntheticTerrain(good, 1);
        EXPECT_EQ(m.width(), good);
        EXPECT_EQ(m.height(), good);
    }
    const double nan = std::numeric_limits<double>::quiet_NaN();
    for (double bad :
         {0.0, -10.0, 1e-6, 2e4, 1e300, nan, std::numeric_limits<double>::infinity()}) {
        EXPECT_THROW(makeSyntheticTerrain(8, 1, bad), ig::InputError) << bad;
    }
}

TEST(SyntheticTerrain, FixedQuantisationAndSpacing) {
    const TerrainMap m = makeSyntheticTerrain(16, 2, 12.5);
    EXPECT_EQ(m.spacingX(), 12.5);
    EXPECT_EQ(m.spacingY(), 12.5);
    EXPECT_EQ(m.heightScale(), ig::kSyntheticHeightScale);
    EXPECT_EQ(m.heightOffset(), ig::kSyntheticHeightOffset);
}

TEST(SyntheticTerrain, PlausibleReliefAndFlatWater) {
    // 256 samples at 80 m: 20 km squares.
    const std::uint16_t seaRaw = static_cast<std::uint16_t>(std::lround(
        (ig::kSyntheticSeaLevel - ig::kSyntheticHeightOffset) / ig::kSyntheticHeightScale));
    std::size_t water = 0, total = 0;
    double highest = 0;
    for (std::uint64_t seed = 1; seed <= 6; ++seed) {
        const TerrainMap m = makeSyntheticTerrain(256, seed, 80.0);
        EXPECT_GE(m.minHeight(), ig::kSyntheticSeaLevel - 1e-9) << seed;  // water is flat
        EXPECT_GT(m.maxHeight() - m.minHeight(), 300.0) << seed;
        EXPECT_LT(m.maxHeight(), 3500.0) << seed;
        highest = std::max(highest, m.maxHeight());
        for (int iy = 0; iy < m.height(); ++iy) {
            for (int ix = 0; ix < m.width(); ++ix) {
                ++total;
                if (m.raw(ix, iy) != seaRaw) continue;
                ++water;
                const ig::Rgb8 c = m.colorAt(ix, iy);
                EXPECT_GT(c.b, c.r) << "water should be blue at " << ix << "," << iy;
            }
        }
    }
    EXPECT_GT(highest, 1000.0);
    // Some water, mostly land.
    EXPECT_GT(water, total / 200);
    EXPECT_LT(water, total / 2);
}

TEST(SyntheticTerrain, DetailDownToTheCell) {
    // At 10 m spacing neighbouring land samples differ: relief has detail at the cell scale.
    const TerrainMap m = makeSyntheticTerrain(128, 4, 10.0);
    int land = 0, flat = 0;
    double sumDiff = 0;
    for (int iy = 0; iy < m.height(); ++iy) {
        for (int ix = 1; ix < m.width(); ++ix) {
            if (m.heightAt(ix, iy) <= ig::kSyntheticSeaLevel ||
                m.heightAt(ix - 1, iy) <= ig::kSyntheticSeaLevel) {
                continue;
            }
            ++land;
            flat += m.raw(ix, iy) == m.raw(ix - 1, iy);
            sumDiff += std::abs(m.heightAt(ix, iy) - m.heightAt(ix - 1, iy));
        }
    }
    ASSERT_GT(land, 1000);
    EXPECT_LT(flat, land / 10);
    // Mean slope between 1% and 100%: neither flat nor a wall.
    EXPECT_GT(sumDiff / land, 0.1);
    EXPECT_LT(sumDiff / land, 10.0);
}

TEST(SyntheticTerrain, ExtremeSpacingsStayFinite) {
    for (double spacing : {0.01, 0.5, 399.0, 401.0, 1000.0, 10000.0}) {
        const TerrainMap m = makeSyntheticTerrain(16, 21, spacing);
        EXPECT_TRUE(std::isfinite(m.minHeight()) && std::isfinite(m.maxHeight())) << spacing;
        EXPECT_GE(m.minHeight(), ig::kSyntheticSeaLevel) << spacing;
        EXPECT_LT(m.maxHeight(), 4000.0) << spacing;
    }
    // Coarse spacing: 16 samples over 160 km still show relief.
    const TerrainMap coarse = makeSyntheticTerrain(16, 21, 10000.0);
    EXPECT_GT(coarse.maxHeight() - coarse.minHeight(), 50.0);
}

TEST(SyntheticTerrain, ColoursVaryWithTerrain) {
    const TerrainMap m = makeSyntheticTerrain(128, 11, 40.0);
    int distinct = 0;
    for (int ix = 1; ix < m.width(); ++ix)
        distinct += !(m.colorAt(ix, 64) == m.colorAt(ix - 1, 64));
    EXPECT_GT(distinct, m.width() / 2);
}

}  // namespace
