// Image error measures used by tests and evaluation tools: mean absolute error and PSNR.
#pragma once

#include "ig/terrain.hpp"

#include <span>
#include <vector>

namespace ig {

// Mean absolute colour difference over all pixels and channels, in percent of full scale (255).
double meanAbsErrorPct(std::span<const Rgb8> a, std::span<const Rgb8> b);
// Peak signal-to-noise ratio in dB over all channels (peak 255); +inf for identical images.
double psnrDb(std::span<const Rgb8> a, std::span<const Rgb8> b);

// Averages each f x f block of an image of (w * f) x (h * f) pixels into a w x h image, rounding
// to nearest: the box filter that turns a supersampled render into a reference.
std::vector<Rgb8> boxDownsample(std::span<const Rgb8> src, int w, int h, int f);

}  // namespace ig
