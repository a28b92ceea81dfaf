#include "common/geometry/registration.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <optional>

#include <gtest/gtest.h>

namespace reenact {
namespace {

// A plane {X : normal . X = offset} in some camera frame (metres).
struct Plane {
  Eigen::Vector3d normal;
  double offset_m;
};

// Depth image (mm, rounded) of `plane_in_depth` seen by `intrinsics`.
DepthImageMm RenderPlane(const CameraIntrinsics& intrinsics, const Plane& plane_in_depth) {
  DepthImageMm depth_mm(intrinsics.width, intrinsics.height);
  for (int y = 0; y < intrinsics.height; ++y) {
    for (int x = 0; x < intrinsics.width; ++x) {
      const Eigen::Vector3d ray = *intrinsics.Unproject(Eigen::Vector2d(x, y), 1.0);
      const double z_m = plane_in_depth.offset_m / plane_in_depth.normal.dot(ray);
      depth_mm.at(x, y) = static_cast<uint16_t>(std::lround(z_m * 1000.0));
    }
  }
  return depth_mm;
}

struct PlaneErrors {
  int interior_pixels = 0;  // Colour pixels whose surface point is well inside the depth view.
  int filled_pixels = 0;    // ... of which received a depth.
  double max_error_mm = 0.0;
  double mean_error_mm = 0.0;
};

// Compares a registered image with the plane's exact depth in the colour
// frame, at colour pixels whose surface point projects at least 2 px inside
// the depth image.
PlaneErrors MeasurePlane(const DepthImageMm& registered_mm, const CameraIntrinsics& color,
                         const CameraIntrinsics& depth, const Rigid3d& color_from_depth,
                         const Plane& plane_in_depth) {
  // The plane in the colour frame: n_c = R n_d, offset_c = offset_d + n_c . t.
  const Eigen::Vector3d normal_in_color = color_from_depth.rotation * plane_in_depth.normal;
  const double offset_in_color =
      plane_in_depth.offset_m + normal_in_color.dot(color_from_depth.translation);
  const Rigid3d depth_from_color = color_from_depth.Inverse();
  PlaneErrors errors;
  double sum_error_mm = 0.0;
  for (int y = 0; y < color.height; ++y) {
    for (int x = 0; x < color.width; ++x) {
      const Eigen::Vector3d ray = *color.Unproject(Eigen::Vector2d(x, y), 1.0);
      const double z_m = offset_in_color / normal_in_color.dot(ray);
      const std::optional<Eigen::Vector2d> depth_px = depth.Project(depth_from_color * (ray * z_m));
      if (!depth_px || depth_px->x() < 2 || depth_px->y() < 2 || depth_px->x() > depth.width - 3 ||
          depth_px->y() > depth.height - 3) {
        continue;
      }
      ++errors.interior_pixels;
      const uint16_t value_mm = registered_mm.at(x, y);
      if (value_mm == 0) continue;
      ++errors.filled_pixels;
      const double error_mm = std::abs(value_mm - z_m * 1000.0);
      errors.max_error_mm = std::max(errors.max_error_mm, error_mm);
      sum_error_mm += error_mm;
    }
  }
  if (errors.filled_pixels > 0) errors.mean_error_mm = sum_error_mm / errors.filled_pixels;
  return errors;
}

Rigid3d TiltedColorFromDepth() {
  const Eigen::Quaterniond rotation(Eigen::AngleAxisd(0.14, Eigen::Vector3d::UnitY()) *
                                    Eigen::AngleAxisd(0.05, Eigen::Vector3d::UnitX()));
  return Rigid3d(rotation, Eigen::Vector3d(-0.052, 0.01, 0.005));
}

TEST(RegisterDepthToColor, PlaneMatchesAnalyticDepthWithinOneMillimetre) {
  // The plane z = 2 m in the depth frame has exact integer depth; the rotated
  // colour camera sees it tilted.
  const CameraIntrinsics depth = KinectV2DepthIntrinsics();
  const CameraIntrinsics color = KinectV2ColorIntrinsics();
  const Rigid3d color_from_depth = TiltedColorFromDepth();
  const Plane plane{Eigen::Vector3d::UnitZ(), 2.0};
  const absl::StatusOr<DepthImageMm> registered =
      RegisterDepthToColor(RenderPlane(depth, plane), depth, color, color_from_depth);
  ASSERT_TRUE(registered.ok()) << registered.status();
  ASSERT_EQ(registered->width, 1920);
  const PlaneErrors errors = MeasurePlane(*registered, color, depth, color_from_depth, plane);
  ASSERT_GT(errors.interior_pixels, 1'000'000);
  EXPECT_GE(errors.filled_pixels, 0.999 * errors.interior_pixels);
  EXPECT_LE(errors.max_error_mm, 1.0);   // Millimetres.
  EXPECT_LT(errors.mean_error_mm, 0.3);  // Millimetres.
}

TEST(RegisterDepthToColor, TiltedPlaneAtHalfColourResolution) {
  // A plane slanted in the depth frame: input depth is rounded to 1 mm, so the
  // bound allows the input rounding (0.5 mm) plus the output rounding (0.5 mm).
  const CameraIntrinsics depth = KinectV2DepthIntrinsics();
  const Rigid3d color_from_depth = KinectV2ColorFromDepth();
  const Plane plane{Eigen::Vector3d(0.3, -0.5, -1.0).normalized(),
                    Eigen::Vector3d(0.3, -0.5, -1.0).normalized().dot(Eigen::Vector3d(0, 0, 2.5))};
  RegistrationOptions options;
  options.color_width = 960;
  options.color_height = 540;
  const absl::StatusOr<DepthToColorRegistration> registration =
      DepthToColorRegistration::Create(depth, KinectV2ColorIntrinsics(), color_from_depth, options);
  ASSERT_TRUE(registration.ok()) << registration.status();
  const absl::StatusOr<DepthImageMm> registered = registration->Register(RenderPlane(depth, plane));
  ASSERT_TRUE(registered.ok()) << registered.status();
  ASSERT_EQ(registered->width, 960);
  ASSERT_EQ(registered->height, 540);
  const PlaneErrors errors =
      MeasurePlane(*registered, registration->output_intrinsics(), depth, color_from_depth, plane);
  ASSERT_GT(errors.interior_pixels, 200'000);
  EXPECT_GE(errors.filled_pixels, 0.999 * errors.interior_pixels);
  EXPECT_LE(errors.max_error_mm, 1.1);   // Millimetres.
  EXPECT_LT(errors.mean_error_mm, 0.5);  // Millimetres.
}

TEST(RegisterDepthToColor, NearestSplatLeavesHolesButKeepsDepth) {
  const CameraIntrinsics depth = KinectV2DepthIntrinsics();
  const CameraIntrinsics color = KinectV2ColorIntrinsics();
  const Rigid3d color_from_depth = TiltedColorFromDepth();
  const Plane plane{Eigen::Vector3d::UnitZ(), 2.0};
  RegistrationOptions options;
  options.fill_footprint = false;
  const absl::StatusOr<DepthImageMm> registered =
      RegisterDepthToColor(RenderPlane(depth, plane), depth, color, color_from_depth, options);
  ASSERT_TRUE(registered.ok()) << registered.status();
  const PlaneErrors errors = MeasurePlane(*registered, color, depth, color_from_depth, plane);
  // About one colour pixel in (1081 / 365)^2 ~ 9 receives a depth sample.
  EXPECT_GT(errors.filled_pixels, 0.05 * errors.interior_pixels);
  EXPECT_LT(errors.filled_pixels, 0.25 * errors.interior_pixels);
  // A sample lands within half a pixel of its colour pixel; the tilt changes
  // depth by < 0.5 mm per colour pixel here.
  EXPECT_LE(errors.max_error_mm, 1.0);  // Millimetres.
}

TEST(RegisterDepthToColor, NearerSurfaceWinsAndEdgesAreNotSmeared) {
  const CameraIntrinsics depth = KinectV2DepthIntrinsics();
  const CameraIntrinsics color = KinectV2ColorIntrinsics();
  DepthImageMm depth_mm(depth.width, depth.height, 3000);
  for (int y = 150; y < 270; ++y) {
    for (int x = 200; x < 310; ++x) depth_mm.at(x, y) = 1000;
  }
  const absl::StatusOr<DepthImageMm> registered =
      RegisterDepthToColor(depth_mm, depth, color, KinectV2ColorFromDepth());
  ASSERT_TRUE(registered.ok()) << registered.status();
  int near_pixels = 0;
  int smeared_pixels = 0;
  for (uint16_t value_mm : registered->data) {
    if (value_mm == 0) continue;
    if (std::abs(value_mm - 1000) <= 1) {
      ++near_pixels;
    } else if (std::abs(value_mm - 3000) > 1) {
      ++smeared_pixels;
    }
  }
  // The 110 x 120 depth-pixel square covers about (1081.37 / 365.456)^2 * 13200
  // ~ 115,000 colour pixels at 1 m; every other value is the 3 m wall (no
  // translation along z, no rotation: depths carry over exactly).
  EXPECT_NEAR(near_pixels, 115'600, 3'000);  // Colour pixels.
  EXPECT_EQ(smeared_pixels, 0);
  // The square's centre in colour shows the near surface.
  const Eigen::Vector3d centre_in_depth = *depth.Unproject(Eigen::Vector2d(254.5, 209.5), 1.0);
  const Eigen::Vector2d centre_px = *color.Project(KinectV2ColorFromDepth() * centre_in_depth);
  EXPECT_NEAR(registered->at(static_cast<int>(std::lround(centre_px.x())),
                             static_cast<int>(std::lround(centre_px.y()))),
              1000, 1);  // Millimetres.
}

TEST(MapDepthPixelsToColor, MatchesDirectProjection) {
  const CameraIntrinsics depth = KinectV2DepthIntrinsics();
  const CameraIntrinsics color = KinectV2ColorIntrinsics();
  const Rigid3d color_from_depth = TiltedColorFromDepth();
  DepthImageMm depth_mm(depth.width, depth.height);
  for (int y = 0; y < depth.height; ++y) {
    for (int x = 0; x < depth.width; ++x) {
      depth_mm.at(x, y) = (x % 17 == 0) ? 0 : static_cast<uint16_t>(800 + 5 * x + 3 * y);
    }
  }
  const absl::StatusOr<ColorPixelMap> map =
      MapDepthPixelsToColor(depth_mm, depth, color, color_from_depth);
  ASSERT_TRUE(map.ok()) << map.status();
  double max_error_px = 0.0;
  int mapped = 0;
  int zero_depth_mapped = 0;
  for (int y = 0; y < depth.height; ++y) {
    for (int x = 0; x < depth.width; ++x) {
      const Eigen::Vector2d mapped_px(map->at(x, y, 0), map->at(x, y, 1));
      if (depth_mm.at(x, y) == 0) {
        zero_depth_mapped += std::isnan(mapped_px.x()) ? 0 : 1;
        continue;
      }
      const Eigen::Vector3d point =
          *depth.Unproject(Eigen::Vector2d(x, y), depth_mm.at(x, y) * 1e-3);
      const Eigen::Vector2d expected_px = *color.Project(color_from_depth * point);
      if (!color.IsInside(expected_px)) {
        EXPECT_TRUE(std::isnan(mapped_px.x()));
        continue;
      }
      ++mapped;
      max_error_px = std::max(max_error_px, (mapped_px - expected_px).norm());
    }
  }
  EXPECT_EQ(zero_depth_mapped, 0);
  EXPECT_GT(mapped, 150'000);
  EXPECT_LT(max_error_px, 1e-2);  // Colour pixels (float storage).
}

TEST(RegisterDepthToColor, RejectsSizeMismatchAndBadOptions) {
  const CameraIntrinsics depth = KinectV2DepthIntrinsics();
  const CameraIntrinsics color = KinectV2ColorIntrinsics();
  const DepthImageMm wrong_size(640, 480, 1000);
  EXPECT_EQ(RegisterDepthToColor(wrong_size, depth, color, Rigid3d()).status().code(),
            absl::StatusCode::kInvalidArgument);
  RegistrationOptions options;
  options.color_width = 960;  // Height left at 0.
  EXPECT_EQ(RegisterDepthToColor(DepthImageMm(512, 424, 1000), depth, color, Rigid3d(), options)
                .status()
                .code(),
            absl::StatusCode::kInvalidArgument);
}

}  // namespace
}  // namespace reenact
