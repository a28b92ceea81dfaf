#include "common/geometry/transforms.h"

#include <cmath>

namespace reenact {

Rigid3d::Rigid3d(const Eigen::Quaterniond& rotation, const Eigen::Vector3d& translation)
    : rotation(rotation.normalized()), translation(translation) {}

Rigid3d Rigid3d::FromMatrix(const Eigen::Matrix<double, 3, 4>& target_from_source) {
  const Eigen::Matrix3d rotation_matrix = target_from_source.leftCols<3>();
  return Rigid3d(Eigen::Quaterniond(rotation_matrix), target_from_source.col(3));
}

Eigen::Matrix4d Rigid3d::ToMatrix4() const {
  Eigen::Matrix4d matrix = Eigen::Matrix4d::Identity();
  matrix.topLeftCorner<3, 3>() = rotation.toRotationMatrix();
  matrix.topRightCorner<3, 1>() = translation;
  return matrix;
}

Rigid3d Rigid3d::Inverse() const {
  const Eigen::Quaterniond inverse_rotation = rotation.conjugate();
  return Rigid3d(inverse_rotation, -(inverse_rotation * translation));
}

Rigid3d operator*(const Rigid3d& a_from_b, const Rigid3d& b_from_c) {
  return Rigid3d(a_from_b.rotation * b_from_c.rotation,
                 a_from_b.rotation * b_from_c.translation + a_from_b.translation);
}

Sim3d::Sim3d(double scale, const Eigen::Quaterniond& rotation, const Eigen::Vector3d& translation)
    : scale(scale), rotation(rotation.normalized()), translation(translation) {}

Sim3d::Sim3d(const Rigid3d& rigid) : Sim3d(1.0, rigid.rotation, rigid.translation) {}

Eigen::Matrix4d Sim3d::ToMatrix4() const {
  Eigen::Matrix4d matrix = Eigen::Matrix4d::Identity();
  matrix.topLeftCorner<3, 3>() = scale * rotation.toRotationMatrix();
  matrix.topRightCorner<3, 1>() = translation;
  return matrix;
}

Sim3d Sim3d::Inverse() const {
  // x = s R y + t  <=>  y = (1/s) R^T x - (1/s) R^T t.
  const Eigen::Quaterniond inverse_rotation = rotation.conjugate();
  const double inverse_scale = 1.0 / scale;
  return Sim3d(inverse_scale, inverse_rotation, -inverse_scale * (inverse_rotation * translation));
}

Sim3d operator*(const Sim3d& a_from_b, const Sim3d& b_from_c) {
  // s1 R1 (s2 R2 x + t2) + t1 = (s1 s2)(R1 R2) x + (s1 R1 t2 + t1).
  return Sim3d(a_from_b.scale * b_from_c.scale, a_from_b.rotation * b_from_c.rotation,
               a_from_b.scale * (a_from_b.rotation * b_from_c.translation) + a_from_b.translation);
}

double RotationAngleRad(const Eigen::Quaterniond& a, const Eigen::Quaterniond& b) {
  // The relative rotation a^-1 b has w = cos(theta / 2) and |xyz| = sin(theta / 2);
  // atan2 keeps precision at small angles, |w| folds q and -q together.
  const Eigen::Quaterniond relative = a.normalized().conjugate() * b.normalized();
  return 2.0 * std::atan2(relative.vec().norm(), std::abs(relative.w()));
}

}  // namespace reenact
