// Per-sensor geometry that the carving method (thesis 3.4.1) computes once
// and shares between body parts: a depth camera placed in the world with a
// table of undistorted rays, the surface (points and normals in the world)
// of one depth image on a decimated pixel grid, and the colour-grid lookup
// that turns an optical-flow match in colour pixels into a depth point.
//
// Frames and units: world metres (+Y up); depth camera OpenCV axes; depth
// images are uint16 millimetres along the depth camera's z, 0 = none.
#pragma once

#include <cstdint>
#include <optional>
#include <vector>

#include <Eigen/Core>

#include "absl/status/statusor.h"
#include "common/base/image.h"
#include "common/geometry/camera.h"
#include "common/geometry/transforms.h"

namespace reenact::recon::carving {

// A pinhole camera with Brown-Conrady distortion (common/geometry/camera.h)
// at a fixed pose in the world, with single-precision projection for the
// inner loops of registration and fusion. Thread-compatible.
class PosedCamera {
 public:
  // InvalidArgument when the intrinsics do not validate or a pixel's ray
  // cannot be undistorted.
  static absl::StatusOr<PosedCamera> Create(const CameraIntrinsics& intrinsics,
                                            const Rigid3d& world_from_camera);

  const CameraIntrinsics& intrinsics() const { return intrinsics_; }
  const Rigid3d& world_from_camera() const { return world_from_camera_; }
  int width() const { return intrinsics_.width; }
  int height() const { return intrinsics_.height; }

  // Undistorted (X/Z, Y/Z) of pixel (x, y).
  const Eigen::Vector2f& Ray(int x, int y) const {
    return rays_[static_cast<size_t>(y) * intrinsics_.width + x];
  }
  // The world point seen at pixel (x, y) with depth z (metres along z).
  Eigen::Vector3f Unproject(int x, int y, float z_m) const {
    const Eigen::Vector2f& ray = Ray(x, y);
    return rotation_ * Eigen::Vector3f(ray.x() * z_m, ray.y() * z_m, z_m) + translation_;
  }
  // A world point in the camera frame.
  Eigen::Vector3f ToCamera(const Eigen::Vector3f& point_in_world_m) const {
    return rotation_t_ * (point_in_world_m - translation_);
  }
  // The pixel (distortion included) of a point in the camera frame; false
  // when it is behind the camera (z <= 1 mm). Inline: fusion calls it per voxel.
  bool ProjectCameraPoint(const Eigen::Vector3f& point_in_camera_m, Eigen::Vector2f* pixel) const {
    if (!(point_in_camera_m.z() > 1e-3f)) return false;
    const float inverse_z = 1.0f / point_in_camera_m.z();
    float x = point_in_camera_m.x() * inverse_z;
    float y = point_in_camera_m.y() * inverse_z;
    if (distorted_) {
      const float r2 = x * x + y * y;
      const float radial = 1.0f + r2 * (k1_ + r2 * (k2_ + r2 * k3_));
      const float xd = x * radial + 2.0f * p1_ * x * y + p2_ * (r2 + 2.0f * x * x);
      const float yd = y * radial + p1_ * (r2 + 2.0f * y * y) + 2.0f * p2_ * x * y;
      x = xd;
      y = yd;
    }
    *pixel = Eigen::Vector2f(fx_ * x + cx_, fy_ * y + cy_);
    return true;
  }

 private:
  CameraIntrinsics intrinsics_;
  Rigid3d world_from_camera_;
  Eigen::Matrix3f rotation_;    // world_from_camera.
  Eigen::Matrix3f rotation_t_;  // camera_from_world.
  Eigen::Vector3f translation_;
  bool distorted_ = false;
  float fx_ = 0, fy_ = 0, cx_ = 0, cy_ = 0, k1_ = 0, k2_ = 0, k3_ = 0, p1_ = 0, p2_ = 0;
  std::vector<Eigen::Vector2f> rays_;
};

// The surface of one depth image on the grid of every `step`-th pixel
// (pixel (x, y) of the map is depth pixel (step x, step y)): points and unit
// normals (facing the camera) in the world frame. A cell without a point has
// a NaN point; a point without a usable normal has a NaN normal.
struct SurfaceMap {
  int step = 1;
  int width = 0;  // ceil(depth width / step).
  int height = 0;
  std::vector<Eigen::Vector3f> points_in_world_m;
  std::vector<Eigen::Vector3f> normals_in_world;
  // Map cell (x, y) -> index; callers check bounds.
  size_t Index(int x, int y) const { return static_cast<size_t>(y) * width + x; }
  bool HasPoint(size_t index) const { return !std::isnan(points_in_world_m[index].x()); }
  bool HasNormal(size_t index) const { return !std::isnan(normals_in_world[index].x()); }
  // The cell nearest to full-resolution depth pixel `pixel`; nullopt outside.
  std::optional<size_t> CellAt(const Eigen::Vector2f& pixel) const;
};

struct SurfaceMapOptions {
  int step = 2;  // Decimation, >= 1.
  // Neighbours whose depth differs by more than this (mm) from the centre
  // pixel are not used for its normal (depth discontinuities).
  int max_depth_step_mm = 40;
  // Depths outside [min, max] mm are treated as no measurement.
  int min_depth_mm = 300;
  int max_depth_mm = 8000;
};

// The surface of `depth_mm` seen by `camera`. When `mask` is given (depth
// size), only pixels with mask > 0 (the actor) get points.
// InvalidArgument when the image sizes disagree with the camera's.
absl::StatusOr<SurfaceMap> BuildSurfaceMap(const PosedCamera& camera, const DepthImageMm& depth_mm,
                                           const MaskImage* mask,
                                           const SurfaceMapOptions& options = {});

// Invalidates (sets to 0) every depth pixel that has a valid 8-neighbour
// more than max_step_mm nearer or farther: time-of-flight pixels that
// straddle a depth discontinuity mix both returns ("flying pixels") and lie
// between the surfaces; this also drops one pixel on each side of every
// silhouette edge. max_step_mm <= 0 leaves the image unchanged.
void RemoveDepthEdges(int max_step_mm, DepthImageMm* depth_mm);

// For every pixel of a (reduced) colour grid, the SurfaceMap cell whose point
// is nearest to the colour camera there (z-buffered splat of the map's
// points), or -1. Used to read the depth point at the end of an optical-flow
// vector, and to test that a point is the one the colour camera sees.
struct ColorLookup {
  int width = 0;
  int height = 0;
  std::vector<int32_t> cell;  // SurfaceMap index, -1 when empty.
  std::vector<float> z_m;     // Depth of that point in the colour camera.
};

// Splats the points of `surface` into the pixel grid of `color_camera` (a
// PosedCamera of the colour camera at the resolution the flow runs at).
ColorLookup BuildColorLookup(const SurfaceMap& surface, const PosedCamera& color_camera);

}  // namespace reenact::recon::carving
