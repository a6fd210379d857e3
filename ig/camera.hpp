// Pose, pinhole intrinsics (with margins) and the world <-> image transforms of the camera.
#pragma once

#include <glm/vec2.hpp>
#include <glm/vec3.hpp>

#include <optional>

namespace ig {

// Aircraft / camera pose. Metres and radians.
//   position: world x east, y north, z up.
//   yaw:   heading, clockwise from north (+y) toward east (+x).
//   pitch: nose up positive.
//   roll:  right wing down positive.
struct Pose {
    glm::dvec3 position{0.0};
    double yaw = 0.0;
    double pitch = 0.0;
    double roll = 0.0;

    bool isFinite() const;
};

// Pinhole intrinsics of a rendered image. Image x right, y down, pixel (i, j) has its centre at
// (i + 0.5, j + 0.5); the principal point is the image centre; pixels are square. `margin` extra
// pixels surround the output window on every side at the same focal length.
struct Intrinsics {
    int width = 0;   // full rendered width, margins included
    int height = 0;  // full rendered height, margins included
    int margin = 0;
    double focal = 0.0;  // focal length in pixels
    // Level of detail: the multiresolution casters read level 0 out to detail * focal * spacing
    // (where a level-0 voxel shrinks to 1 / detail pixels across) and each coarser level from
    // there on, as if the focal length were detail * focal. 1: a voxel to a pixel (the
    // default); below 1 coarser levels sooner, fewer level-0 tiles for a paged map to place.
    double detail = 1.0;
    double lodFocal() const { return focal * detail; }

    // Window of `windowWidth` x `windowHeight` pixels seen with horizontal field of view `hfov`
    // (radians), plus `margin` pixels on each side.
    static Intrinsics fromFov(int windowWidth, int windowHeight, double hfov, int margin = 0);

    double cx() const { return 0.5 * width; }
    double cy() const { return 0.5 * height; }
    int windowWidth() const { return width - 2 * margin; }
    int windowHeight() const { return height - 2 * margin; }
    double windowHfov() const;
    // The output window alone: the same focal length and centre, no margin.
    Intrinsics window() const {
        Intrinsics w = *this;
        w.width = windowWidth();
        w.height = windowHeight();
        w.margin = 0;
        return w;
    }
};

// Orthonormal camera frame for a pose (roll included).
struct CameraBasis {
    glm::dvec3 forward;
    glm::dvec3 right;
    glm::dvec3 up;

    static CameraBasis fromPose(const Pose& pose);
};

// A camera: pose plus intrinsics, with the projections every module shares.
class Camera {
  public:
    Camera(const Pose& pose, const Intrinsics& intrinsics);

    const Pose& pose() const { return pose_; }
    const Intrinsics& intrinsics() const { return intr_; }
    const CameraBasis& basis() const { return basis_; }

    // Unnormalised world direction of the ray through continuous image point (x, y).
    glm::dvec3 rayDirection(double x, double y) const;
    // Projects a homogeneous world point (w = 1: a point, w = 0: a direction). Empty when the
    // point is on or behind the camera plane (depth along forward <= tiny).
    std::optional<glm::dvec2> project(const glm::dvec3& p, double w = 1.0) const;
    // Depth of a world point along the forward axis (camera z).
    double forwardDepth(const glm::dvec3& p) const;

  private:
    Pose pose_;
    Intrinsics intr_;
    CameraBasis basis_;
};

double degToRad(double deg);
double radToDeg(double rad);

}  // namespace ig
