// Haze with a height fall-off, applied over a finished frame from each pixel's depth and ray
// (deferred, as the sun lighting): the optical depth of an exponential atmosphere along the
// straight ray from the eye to the hit, in closed form (docs/design/appearance.md, "Haze").
#pragma once

#include "ig/caster.hpp"
#include "ig/frame.hpp"

#include <algorithm>
#include <cmath>

namespace ig {

// Whether the haze has a height fall-off, applied over the finished frame by hazeFrame instead
// of by the casters (applyHaze does nothing then).
inline bool deferredHaze(const SkyModel& sky) {
    return sky.hazeDistance > 0.0 && sky.hazeFalloff > 0.0;
}

// (1 - exp(-u)) / u, 1 at u = 0: the mean of exp(-s u) over s in [0, 1]. Near 0 its series, so
// a (nearly) level ray never divides by (nearly) 0.
inline double hazeRiseFactor(double u) {
    if (std::abs(u) < 1e-4) return 1.0 - u * (0.5 - u * (1.0 / 6.0));
    return -std::expm1(-u) / u;
}

// Optical depth of the haze along a straight ray of `distance` metres from height eyeZ rising
// by `rise` metres (negative: down) at its end: the integral of exp(-z / H) / D along it,
// (distance / D) exp(-eyeZ / H) (1 - exp(-rise / H)) / (rise / H). H = sky.hazeFalloff > 0,
// D = sky.hazeDistance > 0. Exponents are clamped to +-600: an absurd height gives an absurd
// but finite (or +inf) depth, never NaN.
// The per-frame part: exp(-eyeZ / H) / D (the density at the eye).
inline double hazeEyeDensity(const SkyModel& sky, double eyeZ) {
    return std::exp(-std::clamp(eyeZ / sky.hazeFalloff, -600.0, 600.0)) / sky.hazeDistance;
}
// The per-pixel part, given the eye's density and 1 / H.
inline double hazeOpticalDepth(double eyeDensity, double invFalloff, double distance, double rise) {
    return distance * eyeDensity * hazeRiseFactor(std::clamp(rise * invFalloff, -1200.0, 1200.0));
}
inline double hazeOpticalDepth(const SkyModel& sky, double distance, double eyeZ, double rise) {
    return hazeOpticalDepth(hazeEyeDensity(sky, eyeZ), 1.0 / sky.hazeFalloff, distance, rise);
}

// The blend toward the horizon colour: 1 - exp(-optical depth); without a fall-off the plain
// distance haze 1 - exp(-distance / D); 0 with haze off.
inline double hazeFraction(const SkyModel& sky, double distance, double eyeZ, double rise) {
    if (!(sky.hazeDistance > 0.0)) return 0.0;
    if (!(sky.hazeFalloff > 0.0)) return -std::expm1(-distance / sky.hazeDistance);
    return -std::expm1(-hazeOpticalDepth(sky, distance, eyeZ, rise));
}

// Hazes a finished frame in place when the haze has a fall-off (deferredHaze(sky); otherwise
// nothing): every pixel with a finite, non-negative depth (terrain and voxel objects) blends
// toward the horizon colour by hazeFraction along its pixel-centre ray at that depth. Sky and
// NaN / negative / infinite depths are left as they are. Rows go to the library's workers
// (`threads` as RenderOptions::threads); the image does not depend on them.
void hazeFrame(const SkyModel& sky, const Camera& camera, RenderedFrame& frame, int threads = 0);
// The slow twin, for tests: the camera's ray per pixel and the optical depth by Simpson's rule
// over 256 intervals of the density along it.
void hazeFrameReference(const SkyModel& sky, const Camera& camera, RenderedFrame& frame);
// Simpson's rule for the optical depth (what hazeFrameReference uses).
double hazeOpticalDepthNumeric(const SkyModel& sky, double distance, double eyeZ, double rise,
                               int intervals = 256);

}  // namespace ig
