// The deferred haze pass (docs/design/appearance.md, "Haze"). With a height fall-off the casters
// draw without haze; this pass applies it to the finished frame from each pixel's depth, so no
// kernel needs the eye and hit heights.
#include "ig/haze_pass.hpp"

#include "base/check.hpp"
#include "ig/caster_impl.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <glm/geometric.hpp>

namespace ig {

namespace {

inline bool hazedPixel(float depth) {
    return depth >= 0.0f && depth < kSkyDepth;  // not sky, NaN or negative
}

inline std::uint8_t blendByte(std::uint8_t c, std::uint8_t h, double f) {
    return static_cast<std::uint8_t>(std::clamp(c + (h - c) * f + 0.5, 0.0, 255.0));
}

inline void hazePixel(Rgb8& c, const SkyModel& sky, double f) {
    c = Rgb8{blendByte(c.r, sky.horizon.r, f), blendByte(c.g, sky.horizon.g, f),
             blendByte(c.b, sky.horizon.b, f)};
}

void checkFrame(const Camera& camera, const RenderedFrame& frame) {
    const std::size_t n =
        static_cast<std::size_t>(camera.intrinsics().width) * camera.intrinsics().height;
    CHECK(frame.color.size() == n && frame.depth.size() == n)
        << "hazing a frame whose buffers do not match the camera";
}

}  // namespace

double hazeOpticalDepthNumeric(const SkyModel& sky, double distance, double eyeZ, double rise,
                               int intervals) {
    const int n = intervals + (intervals % 2);
    auto density = [&](double s) {
        return std::exp(-(eyeZ + rise * s) / sky.hazeFalloff) / sky.hazeDistance;
    };
    double sum = density(0.0) + density(1.0);
    for (int i = 1; i < n; ++i)
        sum += (i % 2 == 1 ? 4.0 : 2.0) * density(static_cast<double>(i) / n);
    return distance * sum / (3.0 * n);
}

void hazeFrame(const SkyModel& sky, const Camera& camera, RenderedFrame& frame, int threads) {
    if (!deferredHaze(sky)) return;
    checkFrame(camera, frame);
    const Intrinsics& in = camera.intrinsics();
    const CameraBasis& basis = camera.basis();
    const double eyeDensity = hazeEyeDensity(sky, camera.pose().position.z);
    const double invFalloff = 1.0 / sky.hazeFalloff;
    const int w = in.width;
    auto rows = [&](const tbb::blocked_range<int>& range) {
        for (int y = range.begin(); y < range.end(); ++y) {
            // Pixel (x, y)'s ray: first + x * right (x + 0.5, y + 0.5 its centre).
            const glm::dvec3 first = in.focal * basis.forward + (0.5 - in.cx()) * basis.right -
                                     (y + 0.5 - in.cy()) * basis.up;
            const std::size_t row = static_cast<std::size_t>(y) * w;
            Rgb8* __restrict color = frame.color.data() + row;
            const float* __restrict depth = frame.depth.data() + row;
            for (int x = 0; x < w; ++x) {
                if (!hazedPixel(depth[x])) continue;
                const double dx = first.x + x * basis.right.x, dy = first.y + x * basis.right.y,
                             dz = first.z + x * basis.right.z;
                const double d = depth[x];
                const double rise = d * dz / std::sqrt(dx * dx + dy * dy + dz * dz);
                const double tau = hazeOpticalDepth(eyeDensity, invFalloff, d, rise);
                hazePixel(color[x], sky, -std::expm1(-tau));
            }
        }
    };
    runWithThreads(threads,
                   [&] { tbb::parallel_for(tbb::blocked_range<int>(0, in.height, 8), rows); });
}

void hazeFrameReference(const SkyModel& sky, const Camera& camera, RenderedFrame& frame) {
    if (!deferredHaze(sky)) return;
    checkFrame(camera, frame);
    const Intrinsics& in = camera.intrinsics();
    const double eyeZ = camera.pose().position.z;
    for (int y = 0; y < in.height; ++y) {
        for (int x = 0; x < in.width; ++x) {
            const std::size_t i = static_cast<std::size_t>(y) * in.width + x;
            if (!hazedPixel(frame.depth[i])) continue;
            const glm::dvec3 dir = glm::normalize(camera.rayDirection(x + 0.5, y + 0.5));
            const double d = frame.depth[i];
            const double tau = hazeOpticalDepthNumeric(sky, d, eyeZ, d * dir.z);
            hazePixel(frame.color[i], sky, 1.0 - std::exp(-tau));
        }
    }
}

}  // namespace ig
