#include "common/body/procedural_body.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <map>
#include <numeric>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

#include "common/body/body_model.h"
#include "common/body/joint_set.h"
#include "common/body/shape_space.h"

namespace reenact::body {
namespace {

// One default build shared by the tests (building takes about a second).
const ProceduralBody& DefaultBody() {
  static const ProceduralBody* body = [] {
    absl::StatusOr<ProceduralBody> built = BuildProceduralBodyDetailed();
    EXPECT_TRUE(built.ok()) << built.status();
    return new ProceduralBody(built.ok() ? std::move(*built) : ProceduralBody{});
  }();
  return *body;
}

double Stature(const Eigen::Matrix3Xd& vertices_m) {
  return vertices_m.row(1).maxCoeff() - vertices_m.row(1).minCoeff();
}

// Signed volume of a closed mesh (divergence theorem), m^3.
double SignedVolume(const Eigen::Matrix3Xd& v, const std::vector<Eigen::Vector3i>& triangles) {
  double volume = 0.0;
  for (const auto& t : triangles) {
    volume += v.col(t[0]).dot(v.col(t[1]).cross(v.col(t[2]))) / 6.0;
  }
  return volume;
}

uint64_t Key(int a, int b) { return (static_cast<uint64_t>(a) << 32) | static_cast<uint32_t>(b); }

TEST(BuildProceduralBody, HasEnoughVerticesAndTriangles) {
  const BodyModel& model = DefaultBody().model;
  std::printf("procedural body: %d vertices, %zu triangles, %zu uvs\n", model.num_vertices(),
              model.triangles.size(), model.uvs.size());
  EXPECT_GE(model.num_vertices(), 6000);
  EXPECT_LE(model.num_vertices(), 30000);
  EXPECT_EQ(model.triangles.size(), model.uv_triangles.size());
  EXPECT_EQ(DefaultBody().triangle_region.size(), model.triangles.size());
}

TEST(BuildProceduralBody, IsOneClosedConsistentlyOrientedManifold) {
  const BodyModel& model = DefaultBody().model;
  const int num_vertices = model.num_vertices();
  std::map<uint64_t, int> directed;
  for (const auto& t : model.triangles) {
    for (int e = 0; e < 3; ++e) {
      ASSERT_NE(t[e], t[(e + 1) % 3]);
      ++directed[Key(t[e], t[(e + 1) % 3])];
    }
  }
  int bad_directed = 0, unpaired = 0;
  for (const auto& [key, count] : directed) {
    bad_directed += count != 1;
    // Each directed edge a->b must meet exactly one b->a: two triangles per
    // edge, opposite orientations.
    const int a = static_cast<int>(key >> 32), b = static_cast<int>(key & 0xffffffffu);
    unpaired += directed.count(Key(b, a)) != 1;
  }
  const int64_t num_edges = static_cast<int64_t>(directed.size()) / 2;
  const int64_t euler = num_vertices - num_edges + static_cast<int64_t>(model.triangles.size());
  // Connected components by union-find.
  std::vector<int> parent(num_vertices);
  std::iota(parent.begin(), parent.end(), 0);
  auto root = [&](int v) {
    while (parent[v] != v) v = parent[v] = parent[parent[v]];
    return v;
  };
  for (const auto& t : model.triangles) {
    parent[root(t[0])] = root(t[1]);
    parent[root(t[1])] = root(t[2]);
  }
  int components = 0;
  for (int v = 0; v < num_vertices; ++v) components += root(v) == v;
  double min_area_m2 = 1e9;
  for (const auto& t : model.triangles) {
    const auto& v = model.template_vertices_m;
    min_area_m2 = std::min(
        min_area_m2, 0.5 * (v.col(t[1]) - v.col(t[0])).cross(v.col(t[2]) - v.col(t[0])).norm());
  }
  std::printf(
      "manifold: %d repeated directed edges, %d unpaired, V-E+F = %lld (genus %lld), "
      "%d components, smallest triangle %.3g mm^2\n",
      bad_directed, unpaired, static_cast<long long>(euler),
      static_cast<long long>((2 - euler) / 2), components, min_area_m2 * 1e6);
  EXPECT_EQ(bad_directed, 0);
  EXPECT_EQ(unpaired, 0);
  EXPECT_EQ(euler, 2);
  EXPECT_EQ(components, 1);
  EXPECT_GT(min_area_m2, 1e-10);  // 1e-4 mm^2.
}

TEST(BuildProceduralBody, FacesOutwardWithHumanVolume) {
  const BodyModel& model = DefaultBody().model;
  const double volume_m3 = SignedVolume(model.template_vertices_m, model.triangles);
  std::printf("template volume %.4f m^3\n", volume_m3);
  EXPECT_GT(volume_m3, 0.05);
  EXPECT_LT(volume_m3, 0.11);
}

TEST(BuildProceduralBody, MeanStatureMatchesOption) {
  const double stature_m = Stature(DefaultBody().model.template_vertices_m);
  std::printf("template stature %.4f m (option 1.75)\n", stature_m);
  EXPECT_NEAR(stature_m, 1.75, 0.02);
  EXPECT_NEAR(DefaultBody().model.template_vertices_m.row(1).minCoeff(), 0.0, 1e-9);

  ProceduralBodyOptions options;
  options.stature_m = 1.60;
  options.population_size = 40;
  options.num_held_out = 0;
  options.num_shape_components = 8;
  absl::StatusOr<BodyModel> small = BuildProceduralBody(options);
  ASSERT_TRUE(small.ok()) << small.status();
  std::printf("stature option 1.60 m -> template %.4f m\n", Stature(small->template_vertices_m));
  EXPECT_NEAR(Stature(small->template_vertices_m), 1.60, 0.02);
}

TEST(BuildProceduralBody, RegressorReproducesRestJoints) {
  const ProceduralBody& body = DefaultBody();
  const Eigen::MatrixXd joints =
      body.model.joint_regressor * body.model.template_vertices_m.transpose();
  ASSERT_EQ(joints.rows(), kNumKinectV2Joints);
  double worst_m = 0.0, worst_row_sum = 0.0;
  for (int j = 0; j < kNumKinectV2Joints; ++j) {
    worst_m = std::max(worst_m, (joints.row(j).transpose() - body.rest_joints_m[j]).norm());
    worst_row_sum = std::max(worst_row_sum, std::abs(body.model.joint_regressor.row(j).sum() - 1));
  }
  std::printf("regressor: worst joint error %.3g mm, worst row-sum error %.3g\n", worst_m * 1e3,
              worst_row_sum);
  EXPECT_LT(worst_m, 1e-3);
  EXPECT_LT(worst_row_sum, 1e-9);
}

TEST(BuildProceduralBody, JointsAreAnatomical) {
  const auto& jt = DefaultBody().rest_joints_m;
  const auto at = [&](KinectV2Joint j) { return jt[Index(j)]; };
  // Winter (Fig. 4.1) heights, with 3 cm of slack for the population mean.
  EXPECT_NEAR(at(KinectV2Joint::kShoulderLeft).y(), 0.818 * 1.75, 0.03);
  EXPECT_NEAR(at(KinectV2Joint::kHipRight).y(), 0.530 * 1.75, 0.03);
  EXPECT_NEAR(at(KinectV2Joint::kKneeLeft).y(), 0.285 * 1.75, 0.03);
  EXPECT_NEAR(at(KinectV2Joint::kAnkleRight).y(), 0.039 * 1.75, 0.02);
  // Person's left at +X, facing +Z.
  EXPECT_GT(at(KinectV2Joint::kHandTipLeft).x(), 0.5);
  EXPECT_LT(at(KinectV2Joint::kHandTipRight).x(), -0.5);
  EXPECT_GT(at(KinectV2Joint::kFootLeft).z(), at(KinectV2Joint::kAnkleLeft).z() + 0.1);
  EXPECT_GT(at(KinectV2Joint::kThumbRight).z(), at(KinectV2Joint::kWristRight).z() + 0.03);
  // A-pose: the upper arm points about 40 degrees below horizontal.
  const Eigen::Vector3d arm = at(KinectV2Joint::kElbowLeft) - at(KinectV2Joint::kShoulderLeft);
  const double angle_deg = std::atan2(-arm.y(), arm.x()) * 180.0 / 3.14159265358979;
  EXPECT_NEAR(angle_deg, 40.0, 2.0);
}

TEST(BuildProceduralBody, SkinningWeightsAreNormalised) {
  const BodyModel& model = DefaultBody().model;
  ASSERT_EQ(static_cast<int>(model.skin_weights.size()), model.num_vertices());
  double worst_sum = 0.0;
  float min_weight = 1.f;
  for (int v = 0; v < model.num_vertices(); ++v) {
    double sum = 0.0;
    for (int i = 0; i < kMaxInfluences; ++i) {
      sum += model.skin_weights[v][i];
      min_weight = std::min(min_weight, model.skin_weights[v][i]);
      ASSERT_GE(model.skin_joints[v][i], 0);
      ASSERT_LT(model.skin_joints[v][i], kNumKinectV2Joints);
    }
    worst_sum = std::max(worst_sum, std::abs(sum - 1.0));
  }
  EXPECT_LT(worst_sum, 1e-5);
  EXPECT_GE(min_weight, 0.f);
}

TEST(BuildProceduralBody, HandVerticesFollowTheArm) {
  // A vertex at the left fingertips must be driven by left-hand joints.
  const ProceduralBody& body = DefaultBody();
  const Eigen::Vector3d tip = body.rest_joints_m[Index(KinectV2Joint::kHandTipLeft)];
  Eigen::Index nearest = 0;
  (body.model.template_vertices_m.colwise() - tip).colwise().squaredNorm().minCoeff(&nearest);
  const int main_joint = body.model.skin_joints[nearest][0];
  EXPECT_TRUE(main_joint == Index(KinectV2Joint::kHandLeft) ||
              main_joint == Index(KinectV2Joint::kWristLeft))
      << main_joint;
  EXPECT_GT(body.model.skin_weights[nearest][0], 0.5f);
}

TEST(BuildProceduralBody, UvAtlasIsInUnitSquareAndCoversEveryRegion) {
  const ProceduralBody& body = DefaultBody();
  const BodyModel& model = body.model;
  for (const auto& uv : model.uvs) {
    ASSERT_GE(uv.minCoeff(), 0.f);
    ASSERT_LE(uv.maxCoeff(), 1.f);
  }
  double uv_area = 0.0;
  for (const auto& t : model.uv_triangles) {
    for (int c = 0; c < 3; ++c) {
      ASSERT_GE(t[c], 0);
      ASSERT_LT(t[c], static_cast<int>(model.uvs.size()));
    }
    const Eigen::Vector2f e1 = model.uvs[t[1]] - model.uvs[t[0]];
    const Eigen::Vector2f e2 = model.uvs[t[2]] - model.uvs[t[0]];
    uv_area += 0.5 * std::abs(e1.x() * e2.y() - e1.y() * e2.x());
  }
  std::array<int, kNumBodyRegions> count{};
  for (BodyRegion r : body.triangle_region) ++count[static_cast<int>(r)];
  for (int r = 0; r < kNumBodyRegions; ++r) {
    std::printf("region %-9s %6d triangles\n",
                std::string(BodyRegionName(static_cast<BodyRegion>(r))).c_str(), count[r]);
    EXPECT_GT(count[r], 50);
  }
  std::printf("uv area covered %.3f of the unit square\n", uv_area);
  // Non-overlapping charts cannot cover more than the square.
  EXPECT_LT(uv_area, 1.0);
  EXPECT_GT(uv_area, 0.2);
}

TEST(BuildProceduralBody, ShapeSpaceExplainsThePopulation) {
  const ProceduralBody& body = DefaultBody();
  const auto& ratio = body.explained_variance_ratio;
  ASSERT_GE(body.model.num_shape_components(), 8);
  ASSERT_EQ(static_cast<int>(ratio.size()), body.model.num_shape_components());
  double cumulative = 0.0;
  for (size_t k = 0; k < ratio.size(); ++k) {
    cumulative += ratio[k];
    std::printf("pc%zu explains %.4f (cumulative %.4f)\n", k, ratio[k], cumulative);
    if (k > 0) {
      EXPECT_LE(ratio[k], ratio[k - 1]);
    }
  }
  EXPECT_GT(ratio[0] + ratio[1] + ratio[2], 0.6);
  EXPECT_GT(cumulative, 0.95);
}

TEST(BuildProceduralBody, FirstComponentChangesStature) {
  const BodyModel& model = DefaultBody().model;
  const Eigen::Matrix3Xd tall = model.template_vertices_m + 2.0 * model.shape_directions_m[0];
  const Eigen::Matrix3Xd short_body = model.template_vertices_m - 2.0 * model.shape_directions_m[0];
  const double change_m = std::abs(Stature(tall) - Stature(short_body));
  std::printf("pc0 at +-2 sigma changes stature by %.1f cm\n", change_m * 100);
  EXPECT_GT(change_m, 0.03);
}

TEST(BuildProceduralBody, ShapedBodiesStayFinite) {
  const BodyModel& model = DefaultBody().model;
  uint64_t state = 12345;
  for (int trial = 0; trial < 20; ++trial) {
    Eigen::Matrix3Xd shaped = model.template_vertices_m;
    for (int k = 0; k < model.num_shape_components(); ++k) {
      state = state * 6364136223846793005ull + 1442695040888963407ull;
      const double beta = 6.0 * static_cast<double>(state >> 11) * 0x1.0p-53 - 3.0;  // [-3, 3].
      shaped += beta * model.shape_directions_m[k];
    }
    ASSERT_TRUE(shaped.allFinite());
    const double stature_m = Stature(shaped);
    EXPECT_GT(stature_m, 1.2);
    EXPECT_LT(stature_m, 2.3);
  }
}

TEST(BuildProceduralBody, ReconstructsHeldOutMembers) {
  const ProceduralBody& body = DefaultBody();
  ASSERT_FALSE(body.held_out_members_m.empty());
  ShapeSpace space;
  space.mean_m = body.model.template_vertices_m;
  space.directions_m = body.model.shape_directions_m;
  double sum_squared = 0.0, mean_only_squared = 0.0;
  int64_t count = 0;
  for (const Eigen::Matrix3Xd& member : body.held_out_members_m) {
    absl::StatusOr<Eigen::VectorXd> beta = ProjectOntoShapeSpace(space, member);
    ASSERT_TRUE(beta.ok()) << beta.status();
    absl::StatusOr<Eigen::Matrix3Xd> fit = ShapeFromCoefficients(space, *beta);
    ASSERT_TRUE(fit.ok());
    sum_squared += (*fit - member).colwise().squaredNorm().sum();
    mean_only_squared += (space.mean_m - member).colwise().squaredNorm().sum();
    count += member.cols();
  }
  const double rms_m = std::sqrt(sum_squared / count);
  const double mean_rms_m = std::sqrt(mean_only_squared / count);
  std::printf("held-out members: %.2f mm RMS with %d components (%.2f mm from the mean alone)\n",
              rms_m * 1e3, body.model.num_shape_components(), mean_rms_m * 1e3);
  EXPECT_LT(rms_m, 0.005);
  EXPECT_LT(rms_m, 0.25 * mean_rms_m);
}

TEST(BuildProceduralBody, PassesModelValidationAndPoses) {
  const BodyModel& model = DefaultBody().model;
  EXPECT_TRUE(ValidateBodyModel(model).ok()) << ValidateBodyModel(model);
  BodyPose pose;
  pose.local_rotation[Index(KinectV2Joint::kElbowLeft)] =
      Eigen::Quaterniond(Eigen::AngleAxisd(1.2, Eigen::Vector3d::UnitZ()));
  absl::StatusOr<PosedBody> posed = PoseBody(model, pose, Eigen::VectorXd::Zero(2));
  ASSERT_TRUE(posed.ok()) << posed.status();
  EXPECT_TRUE(posed->vertices_m.allFinite());
  // Feet do not move when only the elbow bends.
  const auto foot = Index(KinectV2Joint::kFootRight);
  EXPECT_LT((posed->joints_m[foot] - DefaultBody().rest_joints_m[foot]).norm(), 1e-6);
}

TEST(BuildProceduralBody, IsDeterministicForASeed) {
  ProceduralBodyOptions options;
  options.population_size = 30;
  options.num_held_out = 0;
  options.num_shape_components = 8;
  absl::StatusOr<BodyModel> a = BuildProceduralBody(options);
  absl::StatusOr<BodyModel> b = BuildProceduralBody(options);
  options.seed += 1;
  absl::StatusOr<BodyModel> c = BuildProceduralBody(options);
  ASSERT_TRUE(a.ok() && b.ok() && c.ok());
  EXPECT_EQ((a->template_vertices_m - b->template_vertices_m).cwiseAbs().maxCoeff(), 0.0);
  EXPECT_GT((a->template_vertices_m - c->template_vertices_m).cwiseAbs().maxCoeff(), 1e-5);
}

TEST(ProceduralBodyOptions, RejectsBadValues) {
  ProceduralBodyOptions options;
  EXPECT_TRUE(options.Validate().ok());
  options.num_shape_components = 5;
  EXPECT_FALSE(options.Validate().ok());
  options = {};
  options.stature_m = 0.3;
  EXPECT_FALSE(BuildProceduralBody(options).ok());
  options = {};
  options.population_size = 9;
  EXPECT_FALSE(options.Validate().ok());
}

// A population with planted orthogonal directions of known spread.
TEST(LearnShapeSpace, RecoversPlantedVariances) {
  const int num_vertices = 50, n = 400;
  Eigen::Matrix3Xd mean = Eigen::Matrix3Xd::Random(3, num_vertices);
  Eigen::Matrix3Xd d0 = Eigen::Matrix3Xd::Zero(3, num_vertices);
  Eigen::Matrix3Xd d1 = Eigen::Matrix3Xd::Zero(3, num_vertices);
  d0.row(1).setConstant(0.03 / std::sqrt(num_vertices));  // Unit-free: 3 cm total norm.
  d1.row(0).setConstant(0.01 / std::sqrt(num_vertices));
  std::vector<Eigen::Matrix3Xd> population;
  uint64_t state = 7;
  auto uniform = [&] {
    state = state * 6364136223846793005ull + 1442695040888963407ull;
    return static_cast<double>(state >> 11) * 0x1.0p-53;
  };
  for (int i = 0; i < n; ++i) {
    // Standard normal coefficients (Box-Muller).
    const double r = std::sqrt(-2 * std::log(uniform() + 1e-300));
    const double a = 2 * 3.14159265358979 * uniform();
    population.push_back(mean + r * std::cos(a) * d0 + r * std::sin(a) * d1);
  }
  absl::StatusOr<ShapeSpace> space = LearnShapeSpace(population, 2);
  ASSERT_TRUE(space.ok()) << space.status();
  // Expected ratio 0.03^2 / (0.03^2 + 0.01^2) = 0.9; sampling error ~5%.
  EXPECT_NEAR(space->explained_variance_ratio[0], 0.9, 0.03);
  EXPECT_NEAR(space->directions_m[0].norm(), 0.03, 0.003);  // Metres, one sigma.
  EXPECT_NEAR(space->directions_m[1].norm(), 0.01, 0.001);
  absl::StatusOr<Eigen::VectorXd> beta = ProjectOntoShapeSpace(*space, population[3]);
  ASSERT_TRUE(beta.ok());
  absl::StatusOr<Eigen::Matrix3Xd> fit = ShapeFromCoefficients(*space, *beta);
  ASSERT_TRUE(fit.ok());
  EXPECT_LT((*fit - population[3]).cwiseAbs().maxCoeff(), 1e-9);  // Metres.
}

TEST(LearnShapeSpace, RejectsBadInput) {
  EXPECT_FALSE(LearnShapeSpace({}, 1).ok());
  std::vector<Eigen::Matrix3Xd> population = {Eigen::Matrix3Xd::Zero(3, 4),
                                              Eigen::Matrix3Xd::Ones(3, 4)};
  EXPECT_FALSE(LearnShapeSpace(population, 2).ok());  // At most N - 1 = 1.
  population.push_back(Eigen::Matrix3Xd::Zero(3, 5));
  EXPECT_FALSE(LearnShapeSpace(population, 1).ok());
  population.back() = Eigen::Matrix3Xd::Constant(3, 4, std::nan(""));
  EXPECT_FALSE(LearnShapeSpace(population, 1).ok());
}

}  // namespace
}  // namespace reenact::body
