// Depth-to-colour registration: re-expresses a depth image in the pixel grid
// of the colour camera (so colour pixel (u, v) gets the depth of the surface
// it sees), or maps each depth pixel to the colour pixel it falls on.
//
// Each valid depth pixel is unprojected with the depth camera's intrinsics
// (undistorted ray times depth), moved into the colour frame with
// colour_from_depth and projected with the colour intrinsics (distortion
// included). Depth in the output is the z of the point in the colour frame.
#pragma once

#include <vector>

#include <Eigen/Core>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "common/base/image.h"
#include "common/geometry/camera.h"
#include "common/geometry/transforms.h"

namespace reenact {

// Per depth pixel, the colour pixel coordinate (x, y) it projects to; both
// NaN where the depth is 0 or the point falls outside the colour image.
using ColorPixelMap = Image<float, 2>;

struct RegistrationOptions {
  // Size of the output colour grid in pixels; 0 keeps the colour intrinsics'
  // size. Other sizes rescale the colour intrinsics (ScaledIntrinsics), e.g.
  // 960x540 for a half-resolution colour stream. Both 0 or both positive.
  int color_width = 0;
  int color_height = 0;
  // When true, the depth image is treated as a surface: each 2x2 block of
  // valid depth pixels is split into two triangles that are rasterised into
  // the colour grid, interpolating 1/z (exact for planar patches seen by an
  // undistorted colour camera). When false, each depth pixel is only splatted
  // to the nearest colour pixel, which leaves holes where colour pixels are
  // denser than depth pixels. Both are z-buffered (nearest surface wins).
  bool fill_footprint = true;
  // Triangles whose corner depths differ by more than this (mm) span a depth
  // discontinuity and are not filled. Must be positive.
  int max_depth_step_mm = 50;
  // Triangles covering more than this many colour pixels along x or y are
  // skipped as degenerate (grazing surfaces). Must be positive.
  int max_triangle_extent_px = 64;

  absl::Status Validate() const;
};

// Precomputes the undistorted depth rays once so that many frames of one
// sensor register cheaply. Thread-compatible: const methods may run
// concurrently.
class DepthToColorRegistration {
 public:
  // InvalidArgument when either intrinsics or the options are invalid, or a
  // depth pixel's ray cannot be undistorted.
  static absl::StatusOr<DepthToColorRegistration> Create(const CameraIntrinsics& depth_intrinsics,
                                                         const CameraIntrinsics& color_intrinsics,
                                                         const Rigid3d& color_from_depth,
                                                         const RegistrationOptions& options = {});

  // The depth image in the colour grid, millimetres along the colour camera's
  // z, 0 where no depth pixel lands. InvalidArgument when `depth_mm` does not
  // match the depth intrinsics' size.
  absl::StatusOr<DepthImageMm> Register(const DepthImageMm& depth_mm) const;

  // For every depth pixel, the colour pixel it projects to (in the output
  // grid). InvalidArgument on a size mismatch.
  absl::StatusOr<ColorPixelMap> MapDepthPixels(const DepthImageMm& depth_mm) const;

  // Intrinsics of the output colour grid (rescaled when the options ask).
  const CameraIntrinsics& output_intrinsics() const { return color_intrinsics_; }

 private:
  DepthToColorRegistration() = default;

  // Fills `pixels` (u, v) and `z_m` (depth in the colour frame) for every
  // depth pixel; NaN where invalid.
  void ProjectAll(const DepthImageMm& depth_mm, std::vector<Eigen::Vector2f>* pixels,
                  std::vector<float>* z_m) const;
  absl::Status CheckSize(const DepthImageMm& depth_mm) const;

  CameraIntrinsics depth_intrinsics_;
  CameraIntrinsics color_intrinsics_;
  Rigid3d color_from_depth_;
  RegistrationOptions options_;
  std::vector<Eigen::Vector2f> rays_;  // Undistorted (X/Z, Y/Z) per depth pixel.
};

// One-shot helpers over DepthToColorRegistration (they rebuild the ray table
// on every call; keep a DepthToColorRegistration for streams).
absl::StatusOr<DepthImageMm> RegisterDepthToColor(const DepthImageMm& depth_mm,
                                                  const CameraIntrinsics& depth_intrinsics,
                                                  const CameraIntrinsics& color_intrinsics,
                                                  const Rigid3d& color_from_depth,
                                                  const RegistrationOptions& options = {});
absl::StatusOr<ColorPixelMap> MapDepthPixelsToColor(const DepthImageMm& depth_mm,
                                                    const CameraIntrinsics& depth_intrinsics,
                                                    const CameraIntrinsics& color_intrinsics,
                                                    const Rigid3d& color_from_depth,
                                                    const RegistrationOptions& options = {});

}  // namespace reenact
