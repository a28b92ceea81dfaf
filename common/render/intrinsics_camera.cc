#include "common/render/intrinsics_camera.h"

namespace reenact::render {

RenderCamera RenderCameraFromIntrinsics(const CameraIntrinsics& intrinsics,
                                        const Eigen::Isometry3d& world_from_camera, double near_m,
                                        double far_m) {
  RenderCamera camera;
  camera.width = intrinsics.width;
  camera.height = intrinsics.height;
  camera.fx = intrinsics.fx;
  camera.fy = intrinsics.fy;
  camera.cx = intrinsics.cx + 0.5;
  camera.cy = intrinsics.cy + 0.5;
  camera.world_from_camera = world_from_camera;
  camera.near_m = near_m;
  camera.far_m = far_m;
  return camera;
}

}  // namespace reenact::render
