// Rigid and similarity transforms between coordinate frames.
//
// Naming follows the "target_from_source" convention: `world_from_sensor`
// maps a point expressed in the sensor frame into the world frame, so that
// `point_in_world = world_from_sensor * point_in_sensor` and transforms chain
// as `world_from_color = world_from_depth * depth_from_color`. Translations are
// in metres unless a name says otherwise.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace reenact {

// A rotation followed by a translation: x -> R x + t.
//
// `rotation` is a unit quaternion (Eigen order: w, x, y, z) and `translation`
// is in the target frame, in metres. Constructors normalise the quaternion;
// code that writes `rotation` directly must keep it unit length.
struct Rigid3d {
  Eigen::Quaterniond rotation = Eigen::Quaterniond::Identity();
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();

  Rigid3d() = default;
  Rigid3d(const Eigen::Quaterniond& rotation, const Eigen::Vector3d& translation);

  // Builds the transform from the top-left 3x3 rotation and the last column
  // of a 4x4 (or 3x4) matrix. The rotation block must be orthonormal; this is
  // not checked.
  static Rigid3d FromMatrix(const Eigen::Matrix<double, 3, 4>& target_from_source);

  // The homogeneous 4x4 matrix [R t; 0 1].
  Eigen::Matrix4d ToMatrix4() const;

  // The transform that maps the target frame back to the source frame.
  Rigid3d Inverse() const;

  // Applies the transform to a point given in the source frame.
  Eigen::Vector3d operator*(const Eigen::Vector3d& point_in_source) const {
    return rotation * point_in_source + translation;
  }
};

// Composition: (a_from_b * b_from_c) maps frame c into frame a.
Rigid3d operator*(const Rigid3d& a_from_b, const Rigid3d& b_from_c);

// A scaled rigid transform: x -> s R x + t (Umeyama 1991 notation).
//
// `scale` is dimensionless and positive; `rotation` is a unit quaternion and
// `translation` is in the target frame's units.
struct Sim3d {
  double scale = 1.0;
  Eigen::Quaterniond rotation = Eigen::Quaterniond::Identity();
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();

  Sim3d() = default;
  Sim3d(double scale, const Eigen::Quaterniond& rotation, const Eigen::Vector3d& translation);
  // A similarity with unit scale.
  explicit Sim3d(const Rigid3d& rigid);

  // The homogeneous 4x4 matrix [sR t; 0 1].
  Eigen::Matrix4d ToMatrix4() const;

  // The inverse similarity (scale 1/s). Requires scale != 0.
  Sim3d Inverse() const;

  // Applies the transform to a point given in the source frame.
  Eigen::Vector3d operator*(const Eigen::Vector3d& point_in_source) const {
    return scale * (rotation * point_in_source) + translation;
  }
};

// Composition: (a_from_b * b_from_c) maps frame c into frame a.
Sim3d operator*(const Sim3d& a_from_b, const Sim3d& b_from_c);

// Angle in radians of the rotation that takes `a` to `b`, in [0, pi].
double RotationAngleRad(const Eigen::Quaterniond& a, const Eigen::Quaterniond& b);

}  // namespace reenact
