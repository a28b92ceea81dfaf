#include "clients/viewer/viewer_camera.h"

#include <cmath>

#include <gtest/gtest.h>

namespace reenact::viewer {
namespace {

// Pixel position of a world point seen by `camera`.
Eigen::Vector2d Project(const render::RenderCamera& camera, const Eigen::Vector3d& point_in_world) {
  const Eigen::Vector3d p = camera.world_from_camera.inverse() * point_in_world;
  return {camera.fx * p.x() / p.z() + camera.cx, camera.fy * p.y() / p.z() + camera.cy};
}

TEST(LookAtCamera, TargetAtCentreUpIsUpRightIsRight) {
  auto camera = LookAtCamera({0, 1.5, 3}, {0, 1, 0}, 60.0, 640, 480);
  ASSERT_TRUE(camera.ok()) << camera.status();
  EXPECT_NEAR((Project(*camera, {0, 1, 0}) - Eigen::Vector2d(320, 240)).norm(), 0.0, 1e-9);
  EXPECT_LT(Project(*camera, {0, 2, 0}).y(), 240.0);  // Higher in the world: up in the image.
  EXPECT_GT(Project(*camera, {1, 1, 0}).x(), 320.0);  // +X seen from +Z: to the right.
  // 60 degrees across 640 pixels.
  EXPECT_NEAR(camera->fx, 320.0 / std::tan(M_PI / 6), 1e-9);
  EXPECT_NEAR(camera->world_from_camera.linear().determinant(), 1.0, 1e-12);
}

TEST(LookAtCamera, RejectsDegenerateViews) {
  EXPECT_FALSE(LookAtCamera({0, 1, 0}, {0, 1, 0}, 60, 640, 480).ok());
  EXPECT_FALSE(LookAtCamera({0, 3, 0}, {0, 1, 0}, 60, 640, 480).ok());  // Along up.
  EXPECT_FALSE(LookAtCamera({0, 1, 3}, {0, 1, 0}, 0.5, 640, 480).ok());
  EXPECT_FALSE(LookAtCamera({0, NAN, 3}, {0, 1, 0}, 60, 640, 480).ok());
  EXPECT_FALSE(LookAtCamera({0, 1, 3}, {0, 1, 0}, 60, 8, 480).ok());
}

TEST(ParseCameraPath, InterpolatesBetweenKeys) {
  const std::string text = R"({"fov_deg": 40, "keys": [
      {"step": 0, "frame": 0, "eye": [0, 1, 3], "target": [0, 1, 0]},
      {"step": 10, "frame": 20, "eye": [3, 1, 0], "target": [0, 1, 0], "fov_deg": 60}]})";
  auto shots = ParseCameraPath(text, 30, 320, 240, Eigen::Vector3d::Zero());
  ASSERT_TRUE(shots.ok()) << shots.status();
  ASSERT_EQ(shots->size(), 11u);
  EXPECT_EQ((*shots)[0].frame, 0);
  EXPECT_EQ((*shots)[5].frame, 10);
  EXPECT_EQ((*shots)[10].frame, 20);
  EXPECT_NEAR(
      ((*shots)[5].camera.world_from_camera.translation() - Eigen::Vector3d(1.5, 1, 1.5)).norm(),
      0.0, 1e-9);
  EXPECT_NEAR((*shots)[0].camera.fx, 160.0 / std::tan(20.0 * M_PI / 180), 1e-9);
  EXPECT_NEAR((*shots)[10].camera.fx, 160.0 / std::tan(30.0 * M_PI / 180), 1e-9);
}

TEST(ParseCameraPath, ActorOriginAndPlayAlongFrames) {
  const std::string text = R"({"origin": "actor", "keys": [
      {"frame": 4, "eye": [0, 0.5, 2], "target": [0, 0, 0]},
      {"step": 3, "eye": [2, 0.5, 0], "target": [0, 0, 0]}]})";
  auto shots = ParseCameraPath(text, 30, 320, 240, Eigen::Vector3d(1, 1, 1));
  ASSERT_TRUE(shots.ok()) << shots.status();
  ASSERT_EQ(shots->size(), 4u);
  EXPECT_EQ(shots->back().frame, 7);  // 4 + 3 steps.
  EXPECT_NEAR(
      (shots->front().camera.world_from_camera.translation() - Eigen::Vector3d(1, 1.5, 3)).norm(),
      0.0, 1e-9);
}

TEST(ParseCameraPath, RejectsBadFiles) {
  const Eigen::Vector3d o = Eigen::Vector3d::Zero();
  EXPECT_FALSE(ParseCameraPath("not json", 10, 320, 240, o).ok());
  EXPECT_FALSE(ParseCameraPath(R"({"keys": []})", 10, 320, 240, o).ok());
  EXPECT_FALSE(
      ParseCameraPath(R"({"keys": [{"eye": [0, 1], "target": [0, 0, 0]}]})", 10, 320, 240, o).ok());
  EXPECT_FALSE(
      ParseCameraPath(R"({"keys": [{"frame": 10, "eye": [0, 1, 2], "target": [0, 0, 0]}]})", 10,
                      320, 240, o)
          .ok());
  EXPECT_FALSE(ParseCameraPath(R"({"keys": [{"step": 3, "eye": [0, 1, 2], "target": [0, 0, 0]},
      {"step": 3, "eye": [0, 1, 2], "target": [0, 0, 0]}]})",
                               10, 320, 240, o)
                   .ok());
  EXPECT_FALSE(
      ParseCameraPath(R"({"keys": [{"eye": [0, 1, 2], "target": "x"}]})", 10, 320, 240, o).ok());
  EXPECT_FALSE(ParseCameraPath(R"({"origin": "moon", "keys": [{"eye": [0, 1, 2], "target": [0, 0,
      0]}]})",
                               10, 320, 240, o)
                   .ok());
  EXPECT_FALSE(ParseCameraPath(R"({"keys": [{"frame": "x", "eye": [0, 1, 2], "target": [0, 0,
      0]}]})",
                               10, 320, 240, o)
                   .ok());
}

TEST(OrbitController, StartsAtTheCameraAndTurns) {
  auto camera = LookAtCamera({0, 1.5, 3}, {0, 1, 0}, 60.0, 640, 480);
  ASSERT_TRUE(camera.ok());
  OrbitController orbit = OrbitController::FromCamera(*camera, {0, 1, 0});
  auto same = orbit.Camera(640, 480);
  ASSERT_TRUE(same.ok());
  EXPECT_NEAR((same->world_from_camera.translation() - Eigen::Vector3d(0, 1.5, 3)).norm(), 0.0,
              1e-9);
  EXPECT_NEAR(same->fx, camera->fx, 1e-9);
  orbit.Rotate(-300, 0, 0.3);  // 90 degrees about +Y: from +Z to +X.
  auto turned = orbit.Camera(640, 480);
  ASSERT_TRUE(turned.ok());
  const Eigen::Vector3d eye = turned->world_from_camera.translation();
  EXPECT_NEAR(eye.x(), std::sqrt(9.25) * std::cos(std::atan2(0.5, 3.0)), 1e-6);
  EXPECT_NEAR(eye.z(), 0.0, 1e-6);
  orbit.Zoom(1);
  EXPECT_NEAR(orbit.distance_m(), 0.9 * std::sqrt(9.25), 1e-9);
  orbit.Rotate(0, 1e6);
  EXPECT_DOUBLE_EQ(orbit.pitch_deg(), 85.0);
  orbit.Reset();
  EXPECT_NEAR(orbit.yaw_deg(), 0.0, 1e-9);
}

}  // namespace
}  // namespace reenact::viewer
