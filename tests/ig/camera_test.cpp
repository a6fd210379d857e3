// Pose and image conventions, each a check a reader can follow.
#include "ig/camera.hpp"

#include <gtest/gtest.h>
#include <glm/geometric.hpp>

#include <cmath>
#include <numbers>

namespace {

using ig::Camera;
using ig::CameraBasis;
using ig::degToRad;
using ig::Intrinsics;
using ig::Pose;

Pose poseDeg(double yaw, double pitch, double roll) {
    Pose p;
    p.position = {100.0, 200.0, 300.0};
    p.yaw = degToRad(yaw);
    p.pitch = degToRad(pitch);
    p.roll = degToRad(roll);
    return p;
}

TEST(PoseConvention, YawZeroLooksNorth) {
    const CameraBasis b = CameraBasis::fromPose(poseDeg(0, 0, 0));
    EXPECT_NEAR(b.forward.y, 1.0, 1e-12);
    EXPECT_NEAR(b.right.x, 1.0, 1e-12);
    EXPECT_NEAR(b.up.z, 1.0, 1e-12);
}

TEST(PoseConvention, YawNinetyLooksEastClockwise) {
    const CameraBasis b = CameraBasis::fromPose(poseDeg(90, 0, 0));
    EXPECT_NEAR(b.forward.x, 1.0, 1e-12);  // east
    EXPECT_NEAR(b.right.y, -1.0, 1e-12);   // right of east is south
}

TEST(PoseConvention, PitchUpRaisesForward) {
    const CameraBasis b = CameraBasis::fromPose(poseDeg(0, 30, 0));
    EXPECT_NEAR(b.forward.z, std::sin(degToRad(30)), 1e-12);
    EXPECT_GT(b.forward.y, 0.0);
    EXPECT_LT(b.up.y, 0.0);  // the top of the image tilts back
}

TEST(PoseConvention, RollPositiveIsRightWingDown) {
    const CameraBasis b = CameraBasis::fromPose(poseDeg(0, 0, 20));
    EXPECT_LT(b.right.z, 0.0);
    EXPECT_NEAR(b.right.z, -std::sin(degToRad(20)), 1e-12);
    EXPECT_GT(b.up.x, 0.0);  // the top of the image leans right
}

TEST(PoseConvention, BasisIsOrthonormalRightHandedForAnyPose) {
    for (double yaw = -180; yaw <= 180; yaw += 45) {
        for (double pitch = -90; pitch <= 90; pitch += 30) {
            for (double roll = -180; roll <= 180; roll += 60) {
                const CameraBasis b = CameraBasis::fromPose(poseDeg(yaw, pitch, roll));
                EXPECT_NEAR(glm::dot(b.forward, b.right), 0.0, 1e-12);
                EXPECT_NEAR(glm::dot(b.forward, b.up), 0.0, 1e-12);
                // Image x right, y down, z forward is right-handed: right x down = forward.
                EXPECT_NEAR(glm::length(glm::cross(b.right, -b.up) - b.forward), 0.0, 1e-12);
            }
        }
    }
}

TEST(ImageConvention, PixelCentresAndPrincipalPoint) {
    const Intrinsics in = Intrinsics::fromFov(640, 480, degToRad(90), 0);
    EXPECT_DOUBLE_EQ(in.cx(), 320.0);
    EXPECT_DOUBLE_EQ(in.cy(), 240.0);
    EXPECT_NEAR(in.focal, 320.0, 1e-9);  // tan(45 deg) = 1
    const Camera cam(poseDeg(0, 0, 0), in);
    // The principal point looks straight ahead; x grows to the right, y grows downward.
    const glm::dvec3 centre = cam.rayDirection(320.0, 240.0);
    EXPECT_NEAR(centre.x, 0.0, 1e-12);
    EXPECT_NEAR(centre.z, 0.0, 1e-12);
    EXPECT_GT(cam.rayDirection(639.5, 240.0).x, 0.0);  // right column looks east of north
    EXPECT_LT(cam.rayDirection(320.0, 479.5).z, 0.0);  // bottom row looks down
}

TEST(ImageConvention, MarginsKeepFocalAndWindow) {
    const Intrinsics in = Intrinsics::fromFov(720, 486, degToRad(60), 32);
    EXPECT_EQ(in.width, 784);
    EXPECT_EQ(in.height, 550);
    EXPECT_EQ(in.windowWidth(), 720);
    EXPECT_NEAR(in.windowHfov(), degToRad(60), 1e-12);
    EXPECT_NEAR(in.focal, 360.0 / std::tan(degToRad(30)), 1e-9);
}

TEST(Projection, RoundTripsEveryPixelForRolledPitchedPoses) {
    const Intrinsics in = Intrinsics::fromFov(160, 120, degToRad(70), 8);
    for (double roll : {0.0, 15.0, -40.0}) {
        const Camera cam(poseDeg(33, -25, roll), in);
        for (double y = 0.5; y < in.height; y += 13) {
            for (double x = 0.5; x < in.width; x += 17) {
                const glm::dvec3 p = cam.pose().position + 57.0 * cam.rayDirection(x, y);
                const auto q = cam.project(p);
                ASSERT_TRUE(q.has_value());
                EXPECT_NEAR(q->x, x, 1e-9);
                EXPECT_NEAR(q->y, y, 1e-9);
                // A direction (w = 0) projects to the same pixel.
                const auto qd = cam.project(cam.rayDirection(x, y), 0.0);
                ASSERT_TRUE(qd.has_value());
                EXPECT_NEAR(qd->x, x, 1e-9);
            }
        }
    }
}

TEST(Projection, BehindTheCameraHasNoImage) {
    const Camera cam(poseDeg(0, 0, 0), Intrinsics::fromFov(64, 48, degToRad(60)));
    EXPECT_FALSE(cam.project(cam.pose().position - glm::dvec3{0, 10, 0}).has_value());
    EXPECT_FALSE(cam.project(cam.pose().position).has_value());
}

}  // namespace
