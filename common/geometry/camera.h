// Pinhole camera with Brown-Conrady lens distortion, in the OpenCV camera
// frame (x right, y down, z forward) and pixel convention (pixel centres at
// integer coordinates, origin at the centre of the top-left pixel).
//
// Distortion (D. C. Brown, "Decentering Distortion of Lenses", 1966; the
// five-coefficient form used by OpenCV) maps normalised coordinates
// (x, y) = (X/Z, Y/Z) with r^2 = x^2 + y^2 to
//   x_d = x (1 + k1 r^2 + k2 r^4 + k3 r^6) + 2 p1 x y + p2 (r^2 + 2 x^2)
//   y_d = y (1 + k1 r^2 + k2 r^4 + k3 r^6) + p1 (r^2 + 2 y^2) + 2 p2 x y
// and then to pixels u = fx x_d + cx, v = fy y_d + cy.
#pragma once

#include <optional>

#include <Eigen/Core>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "common/geometry/transforms.h"

namespace reenact {

struct CameraIntrinsics {
  int width = 0;    // Image width, pixels.
  int height = 0;   // Image height, pixels.
  double fx = 0.0;  // Focal lengths, pixels.
  double fy = 0.0;
  double cx = 0.0;  // Principal point, pixels.
  double cy = 0.0;
  double k1 = 0.0;  // Radial distortion coefficients (dimensionless).
  double k2 = 0.0;
  double k3 = 0.0;
  double p1 = 0.0;  // Tangential distortion coefficients (dimensionless).
  double p2 = 0.0;

  // InvalidArgument unless the size and focal lengths are positive and every
  // value is finite.
  absl::Status Validate() const;

  bool HasDistortion() const;

  // Applies the lens distortion to normalised coordinates (the equations in
  // the file comment).
  Eigen::Vector2d Distort(const Eigen::Vector2d& normalized) const;

  // Inverts Distort by Newton iterations on the 2x2 system, starting from the
  // distorted point. nullopt when the iterations do not converge to 1e-12
  // (far outside the calibrated field of view).
  std::optional<Eigen::Vector2d> Undistort(const Eigen::Vector2d& distorted) const;

  // Projects a point in the camera frame (any length unit) to a pixel,
  // distortion included. nullopt when the point is not in front of the camera
  // (z <= 0). The pixel may fall outside the image; see IsInside.
  std::optional<Eigen::Vector2d> Project(const Eigen::Vector3d& point_in_camera) const;

  // The point in the camera frame, metres, seen at `pixel` with z = depth_m
  // (depth along the optical axis, as depth cameras report it). nullopt when
  // Undistort fails.
  std::optional<Eigen::Vector3d> Unproject(const Eigen::Vector2d& pixel, double depth_m) const;

  // True when `pixel` lies within the image, i.e. in [-0.5, width - 0.5) x
  // [-0.5, height - 0.5).
  bool IsInside(const Eigen::Vector2d& pixel) const;
};

// The same camera resampled to new_width x new_height pixels (e.g. colour
// captured at a reduced resolution). Focal lengths scale with the size ratio;
// the principal point scales about the image corner, (c + 0.5) s - 0.5, so
// pixel centres stay consistent. Distortion is in normalised coordinates and
// stays unchanged. InvalidArgument for non-positive sizes or invalid input.
absl::StatusOr<CameraIntrinsics> ScaledIntrinsics(const CameraIntrinsics& intrinsics, int new_width,
                                                  int new_height);

// Nominal Kinect v2 depth (IR) camera, 512x424. Values as read from a
// device's factory calibration through libfreenect2 and widely republished
// (e.g. the OpenKinect-for-Processing Kinect v2 examples): fx = fy = 365.456,
// cx = 254.878, cy = 205.395, k1 = 0.0905474, k2 = -0.26819, k3 = 0.0950862,
// p1 = p2 = 0. Each device differs by a few pixels; prefer a device's own
// calibration when one is available.
CameraIntrinsics KinectV2DepthIntrinsics();

// Nominal Kinect v2 colour camera, 1920x1080: fx = fy = 1081.37,
// cx = 959.5, cy = 539.5, no distortion (libfreenect2's default colour
// parameters).
CameraIntrinsics KinectV2ColorIntrinsics();

// Nominal pose of the Kinect v2 depth camera in its colour camera's frame:
// no rotation and the commonly reported ~52 mm baseline along x. The colour
// lens sits on the depth camera's +x side (to the left as seen when facing the
// sensor), so a point's x in the colour frame is 0.052 m smaller:
// translation = (-0.052, 0, 0) m.
Rigid3d KinectV2ColorFromDepth();

}  // namespace reenact
