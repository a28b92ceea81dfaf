#include "common/geometry/camera.h"

#include <algorithm>
#include <optional>

#include <gtest/gtest.h>

namespace reenact {
namespace {

// Kinect v2 depth intrinsics with tangential terms added, so that every
// distortion coefficient takes part.
CameraIntrinsics StronglyDistorted() {
  CameraIntrinsics intrinsics = KinectV2DepthIntrinsics();
  intrinsics.p1 = 0.002;
  intrinsics.p2 = -0.0015;
  return intrinsics;
}

double MaxRoundTripErrorPx(const CameraIntrinsics& intrinsics, double depth_m) {
  double max_error_px = 0.0;
  for (int y = 0; y < intrinsics.height; y += 7) {
    for (int x = 0; x < intrinsics.width; x += 7) {
      const Eigen::Vector2d pixel(x, y);
      const std::optional<Eigen::Vector3d> point = intrinsics.Unproject(pixel, depth_m);
      if (!point) return 1e9;
      const std::optional<Eigen::Vector2d> back = intrinsics.Project(*point);
      if (!back) return 1e9;
      max_error_px = std::max(max_error_px, (*back - pixel).norm());
    }
  }
  return max_error_px;
}

TEST(CameraIntrinsics, ProjectUnprojectRoundTripWithDistortion) {
  EXPECT_LT(MaxRoundTripErrorPx(KinectV2DepthIntrinsics(), 2.0), 1e-3);  // Pixels.
  EXPECT_LT(MaxRoundTripErrorPx(StronglyDistorted(), 0.7), 1e-3);        // Pixels.
  EXPECT_LT(MaxRoundTripErrorPx(KinectV2ColorIntrinsics(), 3.5), 1e-3);  // Pixels.
}

TEST(CameraIntrinsics, UnprojectKeepsDepthAndProjectMatchesPinhole) {
  const CameraIntrinsics intrinsics = KinectV2ColorIntrinsics();  // No distortion.
  const std::optional<Eigen::Vector3d> point = intrinsics.Unproject({100.0, 900.0}, 2.5);
  ASSERT_TRUE(point.has_value());
  EXPECT_NEAR(point->z(), 2.5, 1e-12);                              // Metres.
  EXPECT_NEAR(point->x(), (100.0 - 959.5) / 1081.37 * 2.5, 1e-12);  // Metres.
  const std::optional<Eigen::Vector2d> pixel = intrinsics.Project({0.5, -0.25, 2.0});
  ASSERT_TRUE(pixel.has_value());
  EXPECT_NEAR(pixel->x(), 1081.37 * 0.25 + 959.5, 1e-9);    // Pixels.
  EXPECT_NEAR(pixel->y(), -1081.37 * 0.125 + 539.5, 1e-9);  // Pixels.
  EXPECT_FALSE(intrinsics.Project({0.0, 0.0, -1.0}).has_value());
}

TEST(CameraIntrinsics, UndistortInvertsDistort) {
  const CameraIntrinsics intrinsics = StronglyDistorted();
  double max_error = 0.0;
  for (double y = -0.6; y <= 0.6; y += 0.05) {
    for (double x = -0.7; x <= 0.7; x += 0.05) {
      const Eigen::Vector2d normalized(x, y);
      const std::optional<Eigen::Vector2d> back =
          intrinsics.Undistort(intrinsics.Distort(normalized));
      ASSERT_TRUE(back.has_value()) << x << ", " << y;
      max_error = std::max(max_error, (*back - normalized).norm());
    }
  }
  EXPECT_LT(max_error, 1e-10);  // Normalised units.
  // Distortion is not the identity (the test would pass trivially otherwise):
  // at the corner of the Kinect v2 depth image it moves points by > 5 px.
  const Eigen::Vector2d corner(0.7, 0.56);
  EXPECT_GT((intrinsics.Distort(corner) - corner).norm() * intrinsics.fx, 5.0);
}

TEST(ScaledIntrinsics, HalfResolutionKeepsPixelCentresConsistent) {
  const CameraIntrinsics full = KinectV2ColorIntrinsics();
  const absl::StatusOr<CameraIntrinsics> half = ScaledIntrinsics(full, 960, 540);
  ASSERT_TRUE(half.ok()) << half.status();
  EXPECT_NEAR(half->fx, full.fx / 2.0, 1e-12);  // Pixels.
  EXPECT_NEAR(half->cx, 479.5, 1e-12);          // Pixels: centre stays centred.
  // A point lands at the same place in both, measured in image fractions.
  const Eigen::Vector3d point(0.4, 0.3, 2.0);
  const Eigen::Vector2d full_px = *full.Project(point);
  const Eigen::Vector2d half_px = *half->Project(point);
  EXPECT_NEAR((half_px.x() + 0.5) * 2.0, full_px.x() + 0.5, 1e-9);  // Full-res pixels.
  EXPECT_NEAR((half_px.y() + 0.5) * 2.0, full_px.y() + 0.5, 1e-9);  // Full-res pixels.
  EXPECT_FALSE(ScaledIntrinsics(full, 0, 540).ok());
}

TEST(CameraIntrinsics, ValidateRejectsBadValues) {
  CameraIntrinsics intrinsics = KinectV2DepthIntrinsics();
  EXPECT_TRUE(intrinsics.Validate().ok());
  intrinsics.fx = 0.0;
  EXPECT_FALSE(intrinsics.Validate().ok());
  intrinsics = KinectV2DepthIntrinsics();
  intrinsics.width = -1;
  EXPECT_FALSE(intrinsics.Validate().ok());
}

TEST(KinectV2ColorFromDepth, BaselineIsAboutFiftyTwoMillimetres) {
  const Rigid3d color_from_depth = KinectV2ColorFromDepth();
  EXPECT_NEAR(color_from_depth.translation.norm(), 0.052, 0.001);  // Metres.
  EXPECT_NEAR(color_from_depth.translation.x(), -0.052, 0.001);    // Metres, along x.
}

}  // namespace
}  // namespace reenact
