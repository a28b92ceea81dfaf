// The render camera of a calibrated pinhole camera.
#pragma once

#include <Eigen/Geometry>

#include "common/geometry/camera.h"
#include "common/render/render_types.h"

namespace reenact::render {

// The renderer's camera for `intrinsics` (pixel centres on integers, the
// OpenCV convention) posed at `world_from_camera`: the principal point moves
// by +0.5 to the renderer's convention (render_types.h); the lens
// distortion is not rendered. Clipping planes in metres.
RenderCamera RenderCameraFromIntrinsics(const CameraIntrinsics& intrinsics,
                                        const Eigen::Isometry3d& world_from_camera,
                                        double near_m = 0.05, double far_m = 30.0);

}  // namespace reenact::render
