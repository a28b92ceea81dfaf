#include "common/geometry/camera.h"

#include <cmath>

#include <Eigen/Dense>

#include "absl/strings/str_cat.h"

namespace reenact {
namespace {

constexpr int kMaxUndistortIterations = 30;
constexpr double kUndistortTolerance = 1e-12;  // Normalised units.

}  // namespace

absl::Status CameraIntrinsics::Validate() const {
  if (width <= 0 || height <= 0) {
    return absl::InvalidArgumentError(
        absl::StrCat("CameraIntrinsics: size must be positive, got ", width, "x", height));
  }
  if (!(fx > 0.0) || !(fy > 0.0) || !std::isfinite(fx) || !std::isfinite(fy)) {
    return absl::InvalidArgumentError(
        absl::StrCat("CameraIntrinsics: focal lengths must be positive, got ", fx, ", ", fy));
  }
  for (double value : {cx, cy, k1, k2, k3, p1, p2}) {
    if (!std::isfinite(value)) {
      return absl::InvalidArgumentError(
          "CameraIntrinsics: non-finite principal point or "
          "distortion coefficient");
    }
  }
  return absl::OkStatus();
}

bool CameraIntrinsics::HasDistortion() const {
  return k1 != 0.0 || k2 != 0.0 || k3 != 0.0 || p1 != 0.0 || p2 != 0.0;
}

Eigen::Vector2d CameraIntrinsics::Distort(const Eigen::Vector2d& normalized) const {
  const double x = normalized.x();
  const double y = normalized.y();
  const double r2 = x * x + y * y;
  const double radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3));
  return {x * radial + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x),
          y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y};
}

std::optional<Eigen::Vector2d> CameraIntrinsics::Undistort(const Eigen::Vector2d& distorted) const {
  if (!HasDistortion()) return distorted;
  Eigen::Vector2d estimate = distorted;
  for (int iteration = 0; iteration < kMaxUndistortIterations; ++iteration) {
    const double x = estimate.x();
    const double y = estimate.y();
    const double r2 = x * x + y * y;
    const double radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3));
    // d(radial)/d(r2), then the Jacobian of Distort.
    const double radial_slope = k1 + r2 * (2.0 * k2 + 3.0 * r2 * k3);
    Eigen::Matrix2d jacobian;
    jacobian(0, 0) = radial + 2.0 * x * x * radial_slope + 2.0 * p1 * y + 6.0 * p2 * x;
    jacobian(0, 1) = 2.0 * x * y * radial_slope + 2.0 * p1 * x + 2.0 * p2 * y;
    jacobian(1, 0) = 2.0 * x * y * radial_slope + 2.0 * p1 * x + 2.0 * p2 * y;
    jacobian(1, 1) = radial + 2.0 * y * y * radial_slope + 6.0 * p1 * y + 2.0 * p2 * x;
    const Eigen::Vector2d residual = Distort(estimate) - distorted;
    if (residual.norm() < kUndistortTolerance) return estimate;
    const double determinant = jacobian.determinant();
    if (!(std::abs(determinant) > 1e-12)) return std::nullopt;
    estimate -= jacobian.inverse() * residual;
    if (!estimate.allFinite()) return std::nullopt;
  }
  if ((Distort(estimate) - distorted).norm() < kUndistortTolerance) return estimate;
  return std::nullopt;
}

std::optional<Eigen::Vector2d> CameraIntrinsics::Project(
    const Eigen::Vector3d& point_in_camera) const {
  if (!(point_in_camera.z() > 0.0)) return std::nullopt;
  const Eigen::Vector2d distorted = Distort(point_in_camera.head<2>() / point_in_camera.z());
  return Eigen::Vector2d(fx * distorted.x() + cx, fy * distorted.y() + cy);
}

std::optional<Eigen::Vector3d> CameraIntrinsics::Unproject(const Eigen::Vector2d& pixel,
                                                           double depth_m) const {
  const Eigen::Vector2d distorted((pixel.x() - cx) / fx, (pixel.y() - cy) / fy);
  const std::optional<Eigen::Vector2d> normalized = Undistort(distorted);
  if (!normalized) return std::nullopt;
  return Eigen::Vector3d(normalized->x() * depth_m, normalized->y() * depth_m, depth_m);
}

bool CameraIntrinsics::IsInside(const Eigen::Vector2d& pixel) const {
  return pixel.x() >= -0.5 && pixel.x() < width - 0.5 && pixel.y() >= -0.5 &&
         pixel.y() < height - 0.5;
}

absl::StatusOr<CameraIntrinsics> ScaledIntrinsics(const CameraIntrinsics& intrinsics, int new_width,
                                                  int new_height) {
  if (absl::Status status = intrinsics.Validate(); !status.ok()) return status;
  if (new_width <= 0 || new_height <= 0) {
    return absl::InvalidArgumentError(
        absl::StrCat("ScaledIntrinsics: size must be positive, got ", new_width, "x", new_height));
  }
  const double scale_x = static_cast<double>(new_width) / intrinsics.width;
  const double scale_y = static_cast<double>(new_height) / intrinsics.height;
  CameraIntrinsics scaled = intrinsics;
  scaled.width = new_width;
  scaled.height = new_height;
  scaled.fx = intrinsics.fx * scale_x;
  scaled.fy = intrinsics.fy * scale_y;
  scaled.cx = (intrinsics.cx + 0.5) * scale_x - 0.5;
  scaled.cy = (intrinsics.cy + 0.5) * scale_y - 0.5;
  return scaled;
}

CameraIntrinsics KinectV2DepthIntrinsics() {
  CameraIntrinsics intrinsics;
  intrinsics.width = 512;
  intrinsics.height = 424;
  intrinsics.fx = 365.456;
  intrinsics.fy = 365.456;
  intrinsics.cx = 254.878;
  intrinsics.cy = 205.395;
  intrinsics.k1 = 0.0905474;
  intrinsics.k2 = -0.26819;
  intrinsics.k3 = 0.0950862;
  return intrinsics;
}

CameraIntrinsics KinectV2ColorIntrinsics() {
  CameraIntrinsics intrinsics;
  intrinsics.width = 1920;
  intrinsics.height = 1080;
  intrinsics.fx = 1081.37;
  intrinsics.fy = 1081.37;
  intrinsics.cx = 959.5;
  intrinsics.cy = 539.5;
  return intrinsics;
}

Rigid3d KinectV2ColorFromDepth() {
  return Rigid3d(Eigen::Quaterniond::Identity(), Eigen::Vector3d(-0.052, 0.0, 0.0));
}

}  // namespace reenact
