#include "common/geometry/transforms.h"

#include <cmath>

#include <gtest/gtest.h>

namespace reenact {
namespace {

Eigen::Quaterniond AxisAngle(double angle_rad, const Eigen::Vector3d& axis) {
  return Eigen::Quaterniond(Eigen::AngleAxisd(angle_rad, axis.normalized()));
}

TEST(Rigid3d, InverseComposesToIdentity) {
  const Rigid3d world_from_sensor(AxisAngle(0.7, {1, 2, 3}), Eigen::Vector3d(0.5, 1.2, -2.0));
  const Rigid3d identity = world_from_sensor * world_from_sensor.Inverse();
  // Tolerances: 1e-12 rad and 1e-12 m.
  EXPECT_LT(RotationAngleRad(identity.rotation, Eigen::Quaterniond::Identity()), 1e-12);
  EXPECT_LT(identity.translation.norm(), 1e-12);
  const Eigen::Vector3d point_in_sensor(0.3, -0.2, 2.5);
  const Eigen::Vector3d round_trip =
      world_from_sensor.Inverse() * (world_from_sensor * point_in_sensor);
  EXPECT_LT((round_trip - point_in_sensor).norm(), 1e-12);  // Metres.
}

TEST(Rigid3d, CompositionMatchesMatrixProduct) {
  const Rigid3d a_from_b(AxisAngle(0.3, {0, 1, 0}), Eigen::Vector3d(1.0, 0.0, 0.5));
  const Rigid3d b_from_c(AxisAngle(-1.1, {1, 0, 1}), Eigen::Vector3d(-0.2, 0.4, 0.0));
  const Eigen::Matrix4d expected = a_from_b.ToMatrix4() * b_from_c.ToMatrix4();
  EXPECT_LT(((a_from_b * b_from_c).ToMatrix4() - expected).cwiseAbs().maxCoeff(), 1e-12);
  const Eigen::Vector3d point_in_c(0.1, 0.2, 0.3);
  const Eigen::Vector4d expected_point = expected * point_in_c.homogeneous();
  EXPECT_LT(((a_from_b * (b_from_c * point_in_c)) - expected_point.head<3>()).norm(), 1e-12);
}

TEST(Rigid3d, FromMatrixRecoversTransform) {
  const Rigid3d original(AxisAngle(2.0, {0.2, -1, 0.4}), Eigen::Vector3d(3.0, -1.0, 0.25));
  const Rigid3d rebuilt = Rigid3d::FromMatrix(original.ToMatrix4().topRows<3>());
  EXPECT_LT(RotationAngleRad(original.rotation, rebuilt.rotation), 1e-12);  // Radians.
  EXPECT_LT((original.translation - rebuilt.translation).norm(), 1e-12);    // Metres.
}

TEST(Sim3d, InverseAndCompositionMatchMatrices) {
  const Sim3d a_from_b(1.7, AxisAngle(0.9, {1, 1, 0}), Eigen::Vector3d(0.1, -0.3, 2.0));
  const Sim3d b_from_c(0.4, AxisAngle(-0.2, {0, 0, 1}), Eigen::Vector3d(1.0, 2.0, 3.0));
  const Eigen::Matrix4d expected = a_from_b.ToMatrix4() * b_from_c.ToMatrix4();
  EXPECT_LT(((a_from_b * b_from_c).ToMatrix4() - expected).cwiseAbs().maxCoeff(), 1e-12);
  const Eigen::Matrix4d inverse = a_from_b.Inverse().ToMatrix4();
  EXPECT_LT((inverse * a_from_b.ToMatrix4() - Eigen::Matrix4d::Identity()).cwiseAbs().maxCoeff(),
            1e-12);
  EXPECT_NEAR(a_from_b.Inverse().scale, 1.0 / 1.7, 1e-15);
}

TEST(RotationAngleRad, MeasuresSmallAndLargeAngles) {
  const Eigen::Vector3d axis(0.3, 0.4, 0.5);
  EXPECT_NEAR(RotationAngleRad(Eigen::Quaterniond::Identity(), AxisAngle(1e-7, axis)), 1e-7, 1e-15);
  EXPECT_NEAR(RotationAngleRad(AxisAngle(0.5, axis), AxisAngle(2.5, axis)), 2.0, 1e-12);
  // q and -q are the same rotation.
  const Eigen::Quaterniond q = AxisAngle(1.0, axis);
  EXPECT_NEAR(RotationAngleRad(q, Eigen::Quaterniond(-q.coeffs())), 0.0, 1e-12);
}

}  // namespace
}  // namespace reenact
