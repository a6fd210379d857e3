// Test helper: analytic frames of a textured ground plane z = 0 under a sky (no caster needed).
#pragma once

#include "ig/caster.hpp"
#include "ig/frame.hpp"

#include <glm/geometric.hpp>

#include <algorithm>
#include <cmath>
#include <limits>

namespace prp::test {

// Smooth colour of a ground point: a few sine patterns, all channels in 20..235.
inline ig::Rgb8 groundColor(double x, double y) {
    const double r = 127.5 + 100.0 * std::sin(x * 0.031) * std::cos(y * 0.017);
    const double g = 127.5 + 100.0 * std::sin((x + y) * 0.023 + 1.0);
    const double b = 127.5 + 100.0 * std::cos(x * 0.011 - y * 0.029);
    return {static_cast<std::uint8_t>(std::lround(r)), static_cast<std::uint8_t>(std::lround(g)),
            static_cast<std::uint8_t>(std::lround(b))};
}

inline ig::Rgb8 skyColor(const glm::dvec3& dir) {
    const double up = std::clamp(dir.z, 0.0, 1.0);
    return {static_cast<std::uint8_t>(180 - 100 * up), static_cast<std::uint8_t>(200 - 80 * up),
            230};
}

// Ray from the camera through image point (x, y) against z = 0: distance along the unit ray,
// or +inf for sky.
inline double groundDistance(const ig::Camera& cam, double x, double y, glm::dvec3& dir) {
    dir = glm::normalize(cam.rayDirection(x, y));
    if (dir.z >= -1e-9) return std::numeric_limits<double>::infinity();
    return -cam.pose().position.z / dir.z;
}

// A horizontal square hovering at height z over [x0, x1] x [y0, y1] (seen from above), with a
// colour pattern of its own: a near surface in front of the ground for occlusion tests.
struct Slab {
    double x0 = 0, y0 = 0, x1 = 0, y1 = 0, z = 0;
};

inline ig::Rgb8 slabColor(double x, double y) {
    const ig::Rgb8 c = groundColor(1.7 * y + 500.0, 1.3 * x - 300.0);
    return {static_cast<std::uint8_t>(255 - c.g), c.b, static_cast<std::uint8_t>(255 - c.r)};
}

// The ray through image point (x, y) against the slab (when given) and then the ground:
// distance along the unit ray (+inf: sky); `onSlab` says which it met.
inline double sceneDistance(const ig::Camera& cam, double x, double y, const Slab* slab,
                            glm::dvec3& dir, bool& onSlab) {
    const double t = groundDistance(cam, x, y, dir);
    onSlab = false;
    const glm::dvec3 o = cam.pose().position;
    if (slab != nullptr && dir.z < -1e-9 && o.z > slab->z) {
        const double s = (slab->z - o.z) / dir.z;
        const glm::dvec3 p = o + s * dir;
        if (p.x >= slab->x0 && p.x <= slab->x1 && p.y >= slab->y0 && p.y <= slab->y1) {
            onSlab = true;
            return s;
        }
    }
    return t;
}

// Renders colour (sampled at pixel centres), depth and the nine control points analytically:
// the ground, and `slab` over it when given.
inline ig::RenderedFrame renderPlane(const ig::Pose& pose, const ig::Intrinsics& in,
                                     double time = 0.0, std::uint64_t sequence = 0,
                                     const Slab* slab = nullptr) {
    ig::RenderedFrame f;
    f.sequence = sequence;
    f.time = time;
    f.pose = pose;
    f.intrinsics = in;
    const ig::Camera cam(pose, in);
    f.color.resize(static_cast<std::size_t>(in.width) * in.height);
    f.depth.resize(f.color.size());
    for (int y = 0; y < in.height; ++y) {
        for (int x = 0; x < in.width; ++x) {
            glm::dvec3 dir;
            bool onSlab = false;
            const double t = sceneDistance(cam, x + 0.5, y + 0.5, slab, dir, onSlab);
            const std::size_t i = static_cast<std::size_t>(y) * in.width + x;
            if (std::isfinite(t)) {
                const glm::dvec3 p = pose.position + t * dir;
                f.color[i] = onSlab ? slabColor(p.x, p.y) : groundColor(p.x, p.y);
                f.depth[i] = static_cast<float>(t);
            } else {
                f.color[i] = skyColor(dir);
                f.depth[i] = ig::kSkyDepth;
            }
        }
    }
    const auto pixels = ig::controlPointPixels(in);
    for (int k = 0; k < ig::kControlPointCount; ++k) {
        glm::dvec3 dir;
        bool onSlab = false;
        const double t = sceneDistance(cam, pixels[k].x, pixels[k].y, slab, dir, onSlab);
        f.controlPoints[k].pixel = pixels[k];
        f.controlPoints[k].world =
            std::isfinite(t) ? glm::dvec4(pose.position + t * dir, 1.0) : glm::dvec4(dir, 0.0);
    }
    return f;
}

// A frame of a flat colour function of the pixel only (no geometry needed), control points
// on the ground plane as seen from `pose`.
inline ig::Pose lookingDown(double pitchDeg = -35.0, double height = 400.0) {
    ig::Pose p;
    p.position = {1000.0, 2000.0, height};
    p.yaw = 0.3;
    p.pitch = pitchDeg * 3.14159265358979323846 / 180.0;
    return p;
}

}  // namespace prp::test
