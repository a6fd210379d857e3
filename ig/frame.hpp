// RenderedFrame: the contract between the image generator and the post-rendering processor.
#pragma once

#include "ig/camera.hpp"
#include "ig/terrain.hpp"

#include <glm/vec4.hpp>

#include <array>
#include <cstdint>
#include <limits>
#include <memory>
#include <string_view>
#include <vector>

namespace ig {

// One registered control point: a fixed pixel of the rendered image and the world point seen
// through its centre, homogeneous (w = 1: a terrain point; w = 0: a unit direction into the sky).
struct ControlPoint {
    glm::dvec2 pixel{0.0};
    glm::dvec4 world{0.0};
};

inline constexpr int kControlPointCount = 9;
inline constexpr float kSkyDepth = std::numeric_limits<float>::infinity();

// What a caster did, accumulated per frame.
struct RenderStats {
    double renderMs = 0.0;
    std::uint64_t steps = 0;             // grid-line steps over all rays
    std::uint64_t rays = 0;              // rays cast (may exceed pixels with supersampling)
    std::uint64_t restarts = 0;          // coherence starts abandoned for a fresh march
    std::string_view kernel = "scalar";  // the caster's kernel (Caster::kernelName)
    // The span caster's path for this frame: "span" (vertical plane) or "fast" (steep view
    // handed to the fast caster); empty for the other casters.
    std::string_view path;
};

// A rendered image with margins, per-pixel depth and nine control points. Immutable once
// published. The fast path renders with pose.roll == 0; the PRP applies roll as a 2D rotation.
struct RenderedFrame {
    std::uint64_t sequence = 0;
    double time = 0.0;  // simulation time of `pose`, seconds
    Pose pose;
    Intrinsics intrinsics;
    std::vector<Rgb8> color;   // width * height, row-major from the top row
    std::vector<float> depth;  // Euclidean distance from the eye in metres; +inf for sky
    // Object id per pixel (0: terrain or sky), width * height, when the frame was rendered with
    // voxel objects; empty otherwise. Depth is then the distance to the first voxel of non-zero
    // opacity where an object covers the pixel.
    std::vector<std::uint16_t> objectId;
    std::array<ControlPoint, kControlPointCount> controlPoints{};
    // The near clipping plane it was drawn with (metres ahead along the view axis; 0: none):
    // nothing nearer shows, in its pixels or its control points (ig/near_clip.hpp).
    double nearM = 0.0;
    RenderStats stats;
    // Stereo: the right eye of the pair this frame is the left eye of (its own pose, depth and
    // control points; same sequence, time and intrinsics), or null.
    std::shared_ptr<const RenderedFrame> right;

    int width() const { return intrinsics.width; }
    int height() const { return intrinsics.height; }
};

}  // namespace ig
