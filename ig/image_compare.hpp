// Image error measures used by tests and evaluation tools: mean absolute error and PSNR.
#pragma once

#include "ig/terrain.hpp"

#include <span>

namespace ig {

// Mean absolute colour difference over all pixels and channels, in percent of full scale (255).
double meanAbsErrorPct(std::span<const Rgb8> a, std::span<const Rgb8> b);
// Peak signal-to-noise ratio in dB over all channels (peak 255); +inf for identical images.
double psnrDb(std::span<const Rgb8> a, std::span<const Rgb8> b);

}  // namespace ig
