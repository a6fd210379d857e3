// Synthetic terrain: deterministic fractal relief and land-cover colours from a seed.
#pragma once

#include <cstdint>

#include "ig/terrain.hpp"

namespace ig {

// Fixed height quantisation of every synthetic map (independent of its size, so maps of different
// sizes agree sample for sample): z = raw * kSyntheticHeightScale + kSyntheticHeightOffset.
inline constexpr double kSyntheticHeightScale = 0.1;      // metres per raw unit
inline constexpr double kSyntheticHeightOffset = -100.0;  // metres at raw 0
// Water is flat at this height, metres; land is at least one quantum above it, so a sample is
// water exactly when its height equals the sea level.
inline constexpr double kSyntheticSeaLevel = 0.0;

// A size x size map (size a power of two, 2..16384) at `spacing` metres (0.01..10000). Heights and
// colours are functions of world position (x = ix * spacing, y = iy * spacing) and the seed only,
// so a smaller map is exactly the south-west corner of a larger one. Throws InputError for a bad
// size or spacing.
TerrainMap makeSyntheticTerrain(int size, std::uint64_t seed, double spacing = 10.0);

// Largest map generateSyntheticRows streams (a power of two).
inline constexpr int kMaxSyntheticStreamSize = 1 << 20;
// Rows [j0, j1) (south first) of the size x size synthetic map, exactly the samples
// makeSyntheticTerrain gives, into `heights` and `colors` (row j at (j - j0) * size), for
// builders that stream maps larger than memory (size up to kMaxSyntheticStreamSize). Throws
// InputError for a bad size or spacing.
void generateSyntheticRows(int size, std::uint64_t seed, double spacing, int j0, int j1,
                           std::uint16_t* heights, Rgb8* colors);
// Columns [i0, i1) of those rows, (i1 - i0) samples a row: the same samples, for a window
// (an inset) of a map too wide to generate whole rows of.
void generateSyntheticWindow(int size, std::uint64_t seed, double spacing, int i0, int i1, int j0,
                             int j1, std::uint16_t* heights, Rgb8* colors);

}  // namespace ig
