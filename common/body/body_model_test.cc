#include "common/body/body_model.h"

#include <cmath>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "common/testing/test_data.h"

namespace reenact::body {
namespace {

using J = KinectV2Joint;

// A stick figure: one vertex on every joint (the regressor picks it out) plus
// one vertex halfway along the left forearm. Every joint vertex is skinned to
// its own joint, the forearm vertex to the left elbow, so the left arm is a
// two-bone chain (shoulder -> elbow -> wrist) whose posing can be worked out
// by hand. One shape direction moves every vertex by a small fixed field.
BodyModel MakeStickModel() {
  std::array<Eigen::Vector3d, kNumKinectV2Joints> joints_m;
  auto set = [&](J joint, double x, double y, double z) { joints_m[Index(joint)] = {x, y, z}; };
  set(J::kSpineBase, 0, 1.0, 0);
  set(J::kSpineMid, 0, 1.2, 0);
  set(J::kSpineShoulder, 0, 1.4, 0);
  set(J::kNeck, 0, 1.5, 0);
  set(J::kHead, 0, 1.65, 0);
  for (double side : {1.0, -1.0}) {
    const bool left = side > 0;
    set(left ? J::kShoulderLeft : J::kShoulderRight, 0.2 * side, 1.4, 0);
    set(left ? J::kElbowLeft : J::kElbowRight, 0.5 * side, 1.4, 0);
    set(left ? J::kWristLeft : J::kWristRight, 0.75 * side, 1.4, 0);
    set(left ? J::kHandLeft : J::kHandRight, 0.8 * side, 1.4, 0);
    set(left ? J::kHandTipLeft : J::kHandTipRight, 0.9 * side, 1.4, 0);
    set(left ? J::kThumbLeft : J::kThumbRight, 0.8 * side, 1.4, 0.05);
    set(left ? J::kHipLeft : J::kHipRight, 0.1 * side, 1.0, 0);
    set(left ? J::kKneeLeft : J::kKneeRight, 0.1 * side, 0.55, 0);
    set(left ? J::kAnkleLeft : J::kAnkleRight, 0.1 * side, 0.1, 0);
    set(left ? J::kFootLeft : J::kFootRight, 0.1 * side, 0.05, 0.1);
  }
  BodyModel model;
  model.name = "stick";
  const int num_vertices = kNumKinectV2Joints + 1;
  model.template_vertices_m.resize(3, num_vertices);
  for (int j = 0; j < kNumKinectV2Joints; ++j) model.template_vertices_m.col(j) = joints_m[j];
  model.template_vertices_m.col(kNumKinectV2Joints) =
      0.5 * (joints_m[Index(J::kElbowLeft)] + joints_m[Index(J::kWristLeft)]);
  model.triangles = {{0, 1, 2}, {4, 5, 6}, {5, 6, kNumKinectV2Joints}};
  model.uvs = {{0.f, 0.f}, {1.f, 0.f}, {0.f, 1.f}};
  model.uv_triangles = {{0, 1, 2}, {0, 1, 2}, {2, 1, 0}};
  std::vector<Eigen::Triplet<double>> triplets;
  for (int j = 0; j < kNumKinectV2Joints; ++j) triplets.emplace_back(j, j, 1.0);
  model.joint_regressor.resize(kNumKinectV2Joints, num_vertices);
  model.joint_regressor.setFromTriplets(triplets.begin(), triplets.end());
  model.skin_joints.resize(num_vertices);
  model.skin_weights.resize(num_vertices);
  for (int v = 0; v < num_vertices; ++v) {
    model.skin_joints[v] = {v < kNumKinectV2Joints ? v : Index(J::kElbowLeft), 0, 0, 0};
    model.skin_weights[v] = {1.f, 0.f, 0.f, 0.f};
  }
  Eigen::Matrix3Xd direction(3, num_vertices);
  for (int v = 0; v < num_vertices; ++v) {
    direction.col(v) =
        0.01 * Eigen::Vector3d(std::sin(v), std::cos(2.0 * v), 0.5 * std::sin(3.0 * v));
  }
  model.shape_directions_m = {direction};
  model.shape_names = {"wiggle"};
  return model;
}

Eigen::Quaterniond AxisAngleDeg(double degrees, const Eigen::Vector3d& axis) {
  return Eigen::Quaterniond(Eigen::AngleAxisd(degrees * std::numbers::pi / 180.0, axis));
}

TEST(ValidateBodyModel, AcceptsStickModel) {
  EXPECT_TRUE(ValidateBodyModel(MakeStickModel()).ok());
}

TEST(ValidateBodyModel, RejectsNaNVertex) {
  BodyModel model = MakeStickModel();
  model.template_vertices_m(1, 3) = std::nan("");
  const absl::Status status = ValidateBodyModel(model);
  EXPECT_EQ(status.code(), absl::StatusCode::kInvalidArgument) << status;
}

TEST(ValidateBodyModel, RejectsNaNShapeDirectionAndBadWeights) {
  BodyModel model = MakeStickModel();
  model.shape_directions_m[0](2, 5) = std::nan("");
  EXPECT_EQ(ValidateBodyModel(model).code(), absl::StatusCode::kInvalidArgument);
  model = MakeStickModel();
  model.skin_weights[3][0] = 0.5f;
  EXPECT_EQ(ValidateBodyModel(model).code(), absl::StatusCode::kInvalidArgument);
}

TEST(PoseBody, IdentityPoseReproducesShapedRestVertices) {
  const BodyModel model = MakeStickModel();
  Eigen::VectorXd shape(1);
  shape << 0.7;
  const absl::StatusOr<Eigen::Matrix3Xd> rest = ShapedRestVertices(model, shape);
  ASSERT_TRUE(rest.ok()) << rest.status();
  const absl::StatusOr<PosedBody> posed = PoseBody(model, BodyPose(), shape);
  ASSERT_TRUE(posed.ok()) << posed.status();
  const double max_error_m = (posed->vertices_m - *rest).colwise().norm().maxCoeff();
  EXPECT_LT(max_error_m, 1e-9);
  // The shape really moved the vertices (so the comparison is not vacuous).
  EXPECT_GT((*rest - model.template_vertices_m).colwise().norm().maxCoeff(), 1e-3);
}

TEST(PoseBody, ElbowRotationMovesWristToExpectedSpot) {
  const BodyModel model = MakeStickModel();
  BodyPose pose;
  // Elbow bent 90 degrees forward: the forearm (+X at rest) turns to +Z.
  pose.local_rotation[Index(J::kElbowLeft)] = AxisAngleDeg(-90.0, Eigen::Vector3d::UnitY());
  const absl::StatusOr<PosedBody> posed = PoseBody(model, pose, Eigen::VectorXd());
  ASSERT_TRUE(posed.ok()) << posed.status();
  // Elbow (0.5, 1.4, 0) + forearm length 0.25 m along +Z.
  const Eigen::Vector3d expected_wrist_m(0.5, 1.4, 0.25);
  const double joint_error_mm =
      1e3 * (posed->joints_m[Index(J::kWristLeft)] - expected_wrist_m).norm();
  const double vertex_error_mm =
      1e3 * (posed->vertices_m.col(Index(J::kWristLeft)) - expected_wrist_m).norm();
  const double mid_error_mm =
      1e3 * (posed->vertices_m.col(kNumKinectV2Joints) - Eigen::Vector3d(0.5, 1.4, 0.125)).norm();
  EXPECT_LT(joint_error_mm, 1.0);
  EXPECT_LT(vertex_error_mm, 1.0);
  EXPECT_LT(mid_error_mm, 1.0);
}

TEST(PoseBody, ShoulderAndElbowComposeAlongTheChain) {
  const BodyModel model = MakeStickModel();
  BodyPose pose;
  // Upper arm raised straight up (+X -> +Y), then the elbow bent so the
  // forearm points forward (+Z), with the root moved by (1, 0, 2) m.
  pose.local_rotation[Index(J::kShoulderLeft)] = AxisAngleDeg(90.0, Eigen::Vector3d::UnitZ());
  pose.local_rotation[Index(J::kElbowLeft)] = AxisAngleDeg(-90.0, Eigen::Vector3d::UnitY());
  pose.root_translation_m = {1.0, 0.0, 2.0};
  const absl::StatusOr<PosedBody> posed = PoseBody(model, pose, Eigen::VectorXd());
  ASSERT_TRUE(posed.ok()) << posed.status();
  // Shoulder (0.2, 1.4, 0) + 0.3 m up + Rz(90) * (0, 0, 0.25) forward.
  const Eigen::Vector3d expected_wrist_m =
      Eigen::Vector3d(0.2, 1.7, 0.25) + pose.root_translation_m;
  const double error_mm = 1e3 * (posed->joints_m[Index(J::kWristLeft)] - expected_wrist_m).norm();
  EXPECT_LT(error_mm, 1.0);
  const double root_error_mm =
      1e3 * (posed->joints_m[Index(J::kSpineBase)] - Eigen::Vector3d(1.0, 1.0, 2.0)).norm();
  EXPECT_LT(root_error_mm, 1e-6);
}

TEST(PoseBody, RejectsTooManyShapeCoefficients) {
  EXPECT_EQ(PoseBody(MakeStickModel(), BodyPose(), Eigen::VectorXd::Zero(3)).status().code(),
            absl::StatusCode::kInvalidArgument);
}

TEST(SaveBodyModel, RoundTripIsExact) {
  const BodyModel model = MakeStickModel();
  const std::string path = reenact::testing::MakeTempDir("rbm_round_trip") + "/stick.rbm";
  ASSERT_TRUE(SaveBodyModel(model, path).ok());
  const absl::StatusOr<BodyModel> loaded = LoadBodyModel(path);
  ASSERT_TRUE(loaded.ok()) << loaded.status();
  EXPECT_EQ(loaded->name, model.name);
  EXPECT_EQ((loaded->template_vertices_m - model.template_vertices_m).cwiseAbs().maxCoeff(), 0.0);
  EXPECT_EQ(loaded->triangles, model.triangles);
  EXPECT_EQ(loaded->uvs, model.uvs);
  EXPECT_EQ(loaded->uv_triangles, model.uv_triangles);
  EXPECT_EQ(Eigen::MatrixXd(loaded->joint_regressor - model.joint_regressor).cwiseAbs().maxCoeff(),
            0.0);
  EXPECT_EQ(loaded->skin_joints, model.skin_joints);
  EXPECT_EQ(loaded->skin_weights, model.skin_weights);
  ASSERT_EQ(loaded->shape_directions_m.size(), 1u);
  EXPECT_EQ((loaded->shape_directions_m[0] - model.shape_directions_m[0]).cwiseAbs().maxCoeff(),
            0.0);
  EXPECT_EQ(loaded->shape_names, model.shape_names);
  EXPECT_TRUE(loaded->pose_correctives_m.empty());
}

TEST(LoadBodyModel, TruncatedFileIsDataLossNamingTheFile) {
  const std::string dir = reenact::testing::MakeTempDir("rbm_truncated");
  const std::string path = dir + "/stick.rbm";
  ASSERT_TRUE(SaveBodyModel(MakeStickModel(), path).ok());
  const auto full_size = std::filesystem::file_size(path);
  for (auto size :
       {full_size - 1, full_size / 2, decltype(full_size){10}, decltype(full_size){0}}) {
    std::filesystem::resize_file(path, size);
    const absl::StatusOr<BodyModel> loaded = LoadBodyModel(path);
    EXPECT_EQ(loaded.status().code(), absl::StatusCode::kDataLoss) << size << " bytes";
    EXPECT_NE(loaded.status().message().find(path), std::string::npos) << loaded.status();
  }
}

TEST(LoadBodyModel, CorruptHeaderIsDataLoss) {
  const std::string dir = reenact::testing::MakeTempDir("rbm_corrupt");
  const std::string path = dir + "/stick.rbm";
  ASSERT_TRUE(SaveBodyModel(MakeStickModel(), path).ok());
  {
    // Claim a huge vertex count (bytes 8..11).
    std::fstream file(path, std::ios::in | std::ios::out | std::ios::binary);
    file.seekp(8);
    const char huge[4] = {'\xff', '\xff', '\xff', '\x0f'};
    file.write(huge, 4);
  }
  const absl::StatusOr<BodyModel> loaded = LoadBodyModel(path);
  EXPECT_EQ(loaded.status().code(), absl::StatusCode::kDataLoss) << loaded.status();
  EXPECT_FALSE(LoadBodyModel(dir + "/absent.rbm").ok());
}

}  // namespace
}  // namespace reenact::body
