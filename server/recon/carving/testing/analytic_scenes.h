// Test helpers of the carving tests: cameras looking at a point, and depth
// images of analytic shapes (boxes, spheres) ray-cast exactly, so that
// registration and fusion can be checked against known geometry.
#pragma once

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <optional>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "common/base/image.h"
#include "common/geometry/camera.h"
#include "common/geometry/transforms.h"
#include "server/recon/carving/sensor_frame.h"

namespace reenact::recon::carving::testing {

// A Kinect v2-like depth camera (512x424, radial distortion) at `eye_m`
// looking at `target_m`, image "down" toward world -Y.
inline PosedCamera LookAtCamera(const Eigen::Vector3d& eye_m, const Eigen::Vector3d& target_m) {
  CameraIntrinsics intrinsics;
  intrinsics.width = 512;
  intrinsics.height = 424;
  intrinsics.fx = intrinsics.fy = 365.0;
  intrinsics.cx = 255.5;
  intrinsics.cy = 211.5;
  intrinsics.k1 = 0.09;
  intrinsics.k2 = -0.27;
  intrinsics.k3 = 0.095;
  const Eigen::Vector3d forward = (target_m - eye_m).normalized();
  const Eigen::Vector3d down(0.0, -1.0, 0.0);
  const Eigen::Vector3d right = down.cross(forward).normalized();
  const Eigen::Vector3d true_down = forward.cross(right);
  Eigen::Matrix3d world_from_camera;
  world_from_camera.col(0) = right;
  world_from_camera.col(1) = true_down;
  world_from_camera.col(2) = forward;
  return *PosedCamera::Create(intrinsics, Rigid3d(Eigen::Quaterniond(world_from_camera), eye_m));
}

// Distance along a unit ray (origin, direction in the world) to a shape, or
// nullopt when it misses.
using RayCaster = std::function<std::optional<double>(const Eigen::Vector3d& origin,
                                                      const Eigen::Vector3d& direction)>;

// A box of half extents `half_m` placed by world_from_box.
inline RayCaster Box(const Eigen::Vector3d& half_m, const Rigid3d& world_from_box) {
  return [=](const Eigen::Vector3d& origin,
             const Eigen::Vector3d& direction) -> std::optional<double> {
    const Rigid3d box_from_world = world_from_box.Inverse();
    const Eigen::Vector3d o = box_from_world * origin;
    const Eigen::Vector3d d = box_from_world.rotation * direction;
    double t_near = -std::numeric_limits<double>::infinity();
    double t_far = std::numeric_limits<double>::infinity();
    for (int axis = 0; axis < 3; ++axis) {
      if (std::abs(d[axis]) < 1e-12) {
        if (std::abs(o[axis]) > half_m[axis]) return std::nullopt;
        continue;
      }
      double t0 = (-half_m[axis] - o[axis]) / d[axis];
      double t1 = (half_m[axis] - o[axis]) / d[axis];
      if (t0 > t1) std::swap(t0, t1);
      t_near = std::max(t_near, t0);
      t_far = std::min(t_far, t1);
    }
    if (t_near > t_far || t_near <= 0.0) return std::nullopt;
    return t_near;
  };
}

inline RayCaster Sphere(const Eigen::Vector3d& centre_m, double radius_m) {
  return [=](const Eigen::Vector3d& origin,
             const Eigen::Vector3d& direction) -> std::optional<double> {
    const Eigen::Vector3d oc = origin - centre_m;
    const double b = oc.dot(direction);
    const double c = oc.squaredNorm() - radius_m * radius_m;
    const double discriminant = b * b - c;
    if (discriminant < 0.0) return std::nullopt;
    const double t = -b - std::sqrt(discriminant);
    if (t <= 0.0) return std::nullopt;
    return t;
  };
}

// The nearest hit over several shapes.
inline RayCaster Union(std::vector<RayCaster> shapes) {
  return [shapes = std::move(shapes)](const Eigen::Vector3d& origin,
                                      const Eigen::Vector3d& direction) {
    std::optional<double> best;
    for (const RayCaster& shape : shapes) {
      const std::optional<double> t = shape(origin, direction);
      if (t && (!best || *t < *best)) best = t;
    }
    return best;
  };
}

// The depth image (mm along the optical axis, rounded) of `scene` seen by
// `camera`; 0 where the ray misses.
inline DepthImageMm RenderDepth(const PosedCamera& camera, const RayCaster& scene) {
  DepthImageMm depth(camera.width(), camera.height(), 0);
  const Eigen::Matrix3d rotation = camera.world_from_camera().rotation.toRotationMatrix();
  const Eigen::Vector3d eye = camera.world_from_camera().translation;
  for (int y = 0; y < camera.height(); ++y) {
    for (int x = 0; x < camera.width(); ++x) {
      const Eigen::Vector2f& ray = camera.Ray(x, y);
      const Eigen::Vector3d ray_in_camera(ray.x(), ray.y(), 1.0);
      const Eigen::Vector3d direction = (rotation * ray_in_camera).normalized();
      const std::optional<double> t = scene(eye, direction);
      if (!t) continue;
      const double z_m = *t / ray_in_camera.norm();
      depth.at(x, y) = static_cast<uint16_t>(std::lround(z_m * 1000.0));
    }
  }
  return depth;
}

}  // namespace reenact::recon::carving::testing
