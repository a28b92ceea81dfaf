#include "common/body/makehuman_importer.h"

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>

#include <gtest/gtest.h>

#include "common/testing/test_data.h"

namespace reenact::body {
namespace {

// Vertices in base.obj (all groups, helper geometry included).
constexpr int kBaseMeshVertices = 19158;

std::string MakeHumanDir() { return reenact::testing::TestDataPath("body/makehuman"); }

// The import is slow enough (a few MB of text and JSON) to do once.
const MakeHumanImport& Imported() {
  static const MakeHumanImport* imported = [] {
    absl::StatusOr<MakeHumanImport> result = ImportMakeHumanDetailed(MakeHumanDir());
    EXPECT_TRUE(result.ok()) << result.status();
    return result.ok() ? new MakeHumanImport(std::move(*result)) : nullptr;
  }();
  return *imported;
}

TEST(ImportMakeHuman, KeepsOnlyTheBodyGroup) {
  REENACT_REQUIRE_TEST_FILE(MakeHumanDir() + "/3dobjs/base.obj");
  const BodyModel& model = Imported().model;
  std::printf("MakeHuman body: %d vertices, %zu triangles, %zu uvs\n", model.num_vertices(),
              model.triangles.size(), model.uvs.size());
  EXPECT_GT(model.num_vertices(), 10000);
  EXPECT_LT(model.num_vertices(), kBaseMeshVertices);
  ASSERT_EQ(Imported().original_vertex_index.size(), static_cast<size_t>(model.num_vertices()));
  for (int original : Imported().original_vertex_index) {
    ASSERT_GE(original, 0);
    ASSERT_LT(original, kBaseMeshVertices);
  }
  for (const Eigen::Vector3i& tri : model.triangles) {
    ASSERT_TRUE((tri.array() >= 0).all() && (tri.array() < model.num_vertices()).all());
    ASSERT_TRUE(tri[0] != tri[1] && tri[1] != tri[2] && tri[0] != tri[2]);
  }
  ASSERT_EQ(model.uv_triangles.size(), model.triangles.size());
  for (const Eigen::Vector2f& uv : model.uvs) {
    ASSERT_TRUE(uv.x() >= 0.f && uv.x() <= 1.f && uv.y() >= 0.f && uv.y() <= 1.f);
  }
}

TEST(ImportMakeHuman, StandsOnTheFloorWithAdultStature) {
  REENACT_REQUIRE_TEST_FILE(MakeHumanDir() + "/3dobjs/base.obj");
  const Eigen::Matrix3Xd& v = Imported().model.template_vertices_m;
  const double min_y_mm = 1e3 * v.row(1).minCoeff();
  const double stature_m = v.row(1).maxCoeff() - v.row(1).minCoeff();
  std::printf("MakeHuman stature %.3f m, floor offset %.4f m\n", stature_m,
              Imported().floor_offset_m);
  EXPECT_NEAR(min_y_mm, 0.0, 1e-6);
  EXPECT_GT(stature_m, 1.5);
  EXPECT_LT(stature_m, 1.9);
  // Facing +Z: the nose tip (front of the head) is ahead of the back of the head.
  const Eigen::Vector3d head_m = Imported().skeleton_joints_m[Index(KinectV2Joint::kHead)];
  double front_z_m = -1e9, back_z_m = 1e9;
  for (Eigen::Index i = 0; i < v.cols(); ++i) {
    if (std::abs(v(1, i) - head_m.y()) < 0.05 && std::abs(v(0, i)) < 0.02) {
      front_z_m = std::max(front_z_m, v(2, i));
      back_z_m = std::min(back_z_m, v(2, i));
    }
  }
  EXPECT_GT(front_z_m - head_m.z(), head_m.z() - back_z_m);
}

TEST(ImportMakeHuman, RegressedJointsMatchSkeletonJoints) {
  REENACT_REQUIRE_TEST_FILE(MakeHumanDir() + "/rigs/default.mhskel");
  const BodyModel& model = Imported().model;
  const absl::StatusOr<std::array<Eigen::Vector3d, kNumKinectV2Joints>> joints =
      RestJointPositions(model, Eigen::VectorXd());
  ASSERT_TRUE(joints.ok()) << joints.status();
  double max_error_mm = 0.0, min_weight = 1.0, max_weight = 0.0;
  for (int j = 0; j < kNumKinectV2Joints; ++j) {
    const double error_mm = 1e3 * ((*joints)[j] - Imported().skeleton_joints_m[j]).norm();
    max_error_mm = std::max(max_error_mm, error_mm);
    EXPECT_LT(error_mm, 5.0) << KinectV2JointName(static_cast<KinectV2Joint>(j));
    double row_sum = 0.0;
    for (Eigen::SparseMatrix<double, Eigen::RowMajor>::InnerIterator it(model.joint_regressor, j);
         it; ++it) {
      row_sum += it.value();
      min_weight = std::min(min_weight, it.value());
      max_weight = std::max(max_weight, it.value());
    }
    EXPECT_NEAR(row_sum, 1.0, 1e-9);
  }
  std::printf("max regressed-joint error %.4f mm, regressor weights in [%.3f, %.3f]\n",
              max_error_mm, min_weight, max_weight);
  // Rows stay close to averages of nearby vertices (no wild extrapolation).
  EXPECT_GT(min_weight, -0.5);
  EXPECT_LT(max_weight, 1.0);
  // The skeleton is plausible: left joints on +X (the person's left, facing +Z).
  EXPECT_GT(Imported().skeleton_joints_m[Index(KinectV2Joint::kShoulderLeft)].x(), 0.1);
  EXPECT_GT(Imported().skeleton_joints_m[Index(KinectV2Joint::kHead)].y(), 1.4);
}

TEST(ImportMakeHuman, SkinWeightsAreNormalisedWithFourInfluences) {
  REENACT_REQUIRE_TEST_FILE(MakeHumanDir() + "/rigs/default_weights.mhw");
  const BodyModel& model = Imported().model;
  ASSERT_EQ(model.skin_weights.size(), static_cast<size_t>(model.num_vertices()));
  double max_sum_error = 0.0;
  std::array<int, kNumKinectV2Joints> dominant_count{};
  for (int v = 0; v < model.num_vertices(); ++v) {
    double sum = 0.0;
    int influences = 0;
    for (int k = 0; k < kMaxInfluences; ++k) {
      ASSERT_GE(model.skin_weights[v][k], 0.f);
      sum += model.skin_weights[v][k];
      influences += model.skin_weights[v][k] > 0.f;
    }
    max_sum_error = std::max(max_sum_error, std::abs(sum - 1.0));
    ASSERT_LE(influences, kMaxInfluences);
    ++dominant_count[model.skin_joints[v][0]];
  }
  EXPECT_LT(max_sum_error, 1e-6);
  // Every limb joint drives some part of the body.
  for (KinectV2Joint j : {KinectV2Joint::kShoulderLeft, KinectV2Joint::kElbowRight,
                          KinectV2Joint::kKneeLeft, KinectV2Joint::kHipRight}) {
    EXPECT_GT(dominant_count[Index(j)], 100) << KinectV2JointName(j);
  }
}

TEST(ImportMakeHuman, ReadsMacroTargetsAsShapeDirections) {
  REENACT_REQUIRE_TEST_FILE(MakeHumanDir() + "/targets/macrodetails");
  const BodyModel& model = Imported().model;
  std::printf("MakeHuman shape directions: %d\n", model.num_shape_components());
  EXPECT_GE(model.num_shape_components(), 18);
  ASSERT_EQ(model.shape_names.size(), model.shape_directions_m.size());
  // The max-height target at full weight makes the body taller by a plausible
  // amount (MakeHuman blends it by gender, so about half of it in practice).
  int max_height = -1;
  for (size_t k = 0; k < model.shape_names.size(); ++k) {
    if (model.shape_names[k] == "male-young-averagemuscle-averageweight-maxheight") {
      max_height = static_cast<int>(k);
    }
    EXPECT_GT(model.shape_directions_m[k].colwise().norm().maxCoeff(), 1e-3)
        << model.shape_names[k];
  }
  ASSERT_GE(max_height, 0);
  Eigen::VectorXd shape = Eigen::VectorXd::Zero(max_height + 1);
  shape[max_height] = 1.0;
  const absl::StatusOr<Eigen::Matrix3Xd> tall = ShapedRestVertices(model, shape);
  ASSERT_TRUE(tall.ok());
  const double gain_mm =
      1e3 *
      ((tall->row(1).maxCoeff() - tall->row(1).minCoeff()) -
       (model.template_vertices_m.row(1).maxCoeff() - model.template_vertices_m.row(1).minCoeff()));
  std::printf("max-height target adds %.1f mm of stature\n", gain_mm);
  EXPECT_GT(gain_mm, 100.0);
  EXPECT_LT(gain_mm, 1000.0);
}

TEST(ImportMakeHuman, MissingFolderIsAnErrorNamingIt) {
  const std::string dir = reenact::testing::MakeTempDir("mh_missing") + "/nothing_here";
  const absl::StatusOr<BodyModel> model = ImportMakeHuman(dir);
  ASSERT_FALSE(model.ok());
  EXPECT_NE(model.status().message().find(dir), std::string::npos) << model.status();
}

TEST(ImportMakeHuman, CorruptObjIsAnErrorNamingTheFile) {
  const std::string dir = reenact::testing::MakeTempDir("mh_corrupt");
  std::filesystem::create_directories(dir + "/3dobjs");
  const std::string obj = dir + "/3dobjs/base.obj";
  std::ofstream(obj) << "v 0 0 0\nv 1 0 0\nv 0 1 zero\ng body\nf 1 2 3\n";
  const absl::StatusOr<BodyModel> model = ImportMakeHuman(dir);
  ASSERT_FALSE(model.ok());
  EXPECT_NE(model.status().message().find(obj), std::string::npos) << model.status();
  EXPECT_NE(model.status().message().find(":3:"), std::string::npos) << model.status();
  // A face that indexes a vertex the file never declared.
  std::ofstream(obj) << "v 0 0 0\nv 1 0 0\nv 0 1 0\ng body\nf 1 2 7\n";
  const absl::StatusOr<BodyModel> bad_index = ImportMakeHuman(dir);
  ASSERT_FALSE(bad_index.ok());
  EXPECT_NE(bad_index.status().message().find(obj), std::string::npos) << bad_index.status();
}

}  // namespace
}  // namespace reenact::body
