#include "common/bodyfit/body_fit.h"

#include <cmath>
#include <cstdio>
#include <limits>
#include <memory>
#include <random>
#include <vector>

#include <ceres/gradient_checker.h>
#include <gtest/gtest.h>

#include "common/body/procedural_body.h"
#include "common/bodyfit/body_terms.h"

namespace reenact::bodyfit {
namespace {

using body::KinectV2Joint;

const body::BodyModel& Model() {
  static const body::BodyModel* model = [] {
    body::ProceduralBodyOptions options;
    options.grid_spacing_m = 0.025;
    options.population_size = 60;
    options.num_held_out = 0;
    auto built = body::BuildProceduralBody(options);
    EXPECT_TRUE(built.ok()) << built.status();
    return new body::BodyModel(std::move(*built));
  }();
  return *model;
}

const ModelData& Data() {
  static const ModelData* data = new ModelData(Model());
  return *data;
}

// A pose with every active joint turned (random, up to `max_rad`).
PoseParameters RandomPose(std::mt19937* rng, double max_rad) {
  std::uniform_real_distribution<double> u(-max_rad, max_rad);
  PoseParameters p;
  for (auto& a : p.angle_axis) a = Eigen::Vector3d(u(*rng), u(*rng), u(*rng));
  p.translation_m = Eigen::Vector3d(0.1, 0.05, -0.2);
  return p;
}

// Probes `cost` at `pose` (and `shape` when it has a shape block) and
// returns the largest difference between the analytic Jacobian and central
// differences, relative to the largest Jacobian entry (entries of 1e-11
// next to entries of 1 make per-entry relative errors meaningless).
double MaxJacobianError(const ceres::CostFunction& cost, const PoseParameters& pose,
                        Eigen::VectorXd* shape) {
  std::vector<std::array<double, 3>> blocks(kJoints + 1);
  for (int j = 0; j < kJoints; ++j) {
    for (int c = 0; c < 3; ++c) blocks[j][c] = pose.angle_axis[j][c];
  }
  for (int c = 0; c < 3; ++c) blocks[kJoints][c] = pose.translation_m[c];
  std::vector<const double*> pointers;
  for (const auto& b : blocks) pointers.push_back(b.data());
  if (cost.parameter_block_sizes().size() == kJoints + 2) pointers.push_back(shape->data());
  const ceres::GradientChecker checker(
      &cost, static_cast<const std::vector<const ceres::Manifold*>*>(nullptr),
      ceres::NumericDiffOptions());
  ceres::GradientChecker::ProbeResults results;
  checker.Probe(pointers.data(), 1e-5, &results);
  double scale = 0.0, error = 0.0;
  for (size_t b = 0; b < results.jacobians.size(); ++b) {
    scale = std::max(scale, results.jacobians[b].cwiseAbs().maxCoeff());
    error = std::max(error,
                     (results.jacobians[b] - results.numeric_jacobians[b]).cwiseAbs().maxCoeff());
  }
  return error / scale;
}

TEST(BodyTerms, PointTermJacobiansMatchNumericDifferences) {
  std::mt19937 rng(3);
  const PoseParameters pose = RandomPose(&rng, 0.5);
  Eigen::VectorXd shape = Eigen::VectorXd::LinSpaced(Model().num_shape_components(), -1.0, 1.0);
  std::vector<Correspondence> matches;
  std::uniform_int_distribution<int> vertex(0, Model().num_vertices() - 1);
  std::normal_distribution<double> g(0.0, 1.0);
  for (int i = 0; i < 60; ++i) {
    const Eigen::Vector3d n = Eigen::Vector3d(g(rng), g(rng), g(rng)).normalized();
    matches.push_back({vertex(rng), Eigen::Vector3d(g(rng), 1.0 + g(rng), g(rng)), n});
  }
  const std::unique_ptr<ceres::CostFunction> with_shape(
      NewPointTerm(Data(), matches, 2.0, /*fixed=*/nullptr));
  const double error_shape = MaxJacobianError(*with_shape, pose, &shape);
  EXPECT_LT(error_shape, 1e-5);
  ShapedRest rest;
  Data().Shaped(shape, &rest.vertices_m, &rest.joints_m);
  const std::unique_ptr<ceres::CostFunction> fixed(NewPointTerm(Data(), matches, 2.0, &rest));
  EXPECT_LT(MaxJacobianError(*fixed, pose, &shape), 1e-5);
  std::printf("point term: max relative Jacobian error %.2e\n", error_shape);
}

TEST(BodyTerms, SkeletonAndSmoothnessJacobiansMatchNumericDifferences) {
  std::mt19937 rng(5);
  const PoseParameters pose = RandomPose(&rng, 0.6);
  Eigen::VectorXd shape = Eigen::VectorXd::Constant(Model().num_shape_components(), 0.7);
  SkeletonJoints targets = NoSkeletonJoints();
  for (int j = 0; j < kJoints; j += 2) targets[j] = Eigen::Vector3d(0.1 * j, 1.0, 0.0);
  const std::unique_ptr<ceres::CostFunction> skeleton(
      NewSkeletonTerm(Data(), targets, 3.0, /*fixed=*/nullptr));
  EXPECT_EQ(skeleton->num_residuals(), 3 * 13);
  EXPECT_LT(MaxJacobianError(*skeleton, pose, &shape), 1e-5);

  const std::unique_ptr<ceres::CostFunction> smooth(
      NewSmoothnessTerm(Eigen::AngleAxisd(0.4, Eigen::Vector3d::UnitY()).toRotationMatrix(), 0.05));
  const double a[3] = {0.2, -0.3, 0.1};
  const double* pointers[1] = {a};
  const ceres::GradientChecker checker(
      smooth.get(), static_cast<const std::vector<const ceres::Manifold*>*>(nullptr), {});
  ceres::GradientChecker::ProbeResults results;
  EXPECT_TRUE(checker.Probe(pointers, 1e-6, &results)) << results.error_log;
}

// Posing by the terms' kinematics equals body::PoseBody.
TEST(BodyTerms, KinematicsMatchPoseBody) {
  std::mt19937 rng(9);
  const PoseParameters pose = RandomPose(&rng, 0.8);
  const Eigen::VectorXd shape = Eigen::VectorXd::Constant(Model().num_shape_components(), -0.5);
  Eigen::Matrix3Xd rest;
  std::array<Eigen::Vector3d, kJoints> rest_joints;
  Data().Shaped(shape, &rest, &rest_joints);
  std::array<const double*, kJoints> aa;
  for (int j = 0; j < kJoints; ++j) aa[j] = pose.angle_axis[j].data();
  Kinematics kin;
  ComputeKinematics(Data(), aa.data(), pose.translation_m.data(), nullptr, &rest_joints, false,
                    &kin);
  Eigen::Matrix3Xd posed;
  PoseAllVertices(Data(), kin, rest, &posed);
  auto expected = body::PoseBody(Model(), pose.ToPose(), shape);
  ASSERT_TRUE(expected.ok());
  EXPECT_LT(1000.0 * (posed - expected->vertices_m).colwise().norm().maxCoeff(), 1e-6);
  for (int j = 0; j < kJoints; ++j) {
    EXPECT_LT(1000.0 * (kin.position_m[j] - expected->joints_m[j]).norm(), 1e-6);
  }
}

// The cloud a pair of facing sensors would see of a posed body: the posed
// vertices whose normals face +Z or -Z (front or back), with 2 mm noise.
PointCloud CloudOf(const body::PosedBody& posed, std::mt19937* rng) {
  Eigen::Matrix3Xd normals = Eigen::Matrix3Xd::Zero(3, posed.vertices_m.cols());
  for (const Eigen::Vector3i& t : Model().triangles) {
    const Eigen::Vector3d n = (posed.vertices_m.col(t[1]) - posed.vertices_m.col(t[0]))
                                  .cross(posed.vertices_m.col(t[2]) - posed.vertices_m.col(t[0]));
    for (int c = 0; c < 3; ++c) normals.col(t[c]) += n;
  }
  std::normal_distribution<double> noise(0.0, 0.002);
  PointCloud cloud;
  for (Eigen::Index v = 0; v < normals.cols(); ++v) {
    const Eigen::Vector3d n = normals.col(v).normalized();
    if (std::abs(n.z()) < 0.2) continue;
    const Eigen::Vector3d p =
        posed.vertices_m.col(v) + Eigen::Vector3d(noise(*rng), noise(*rng), noise(*rng));
    cloud.points_m.push_back(p.cast<float>());
    cloud.normals.push_back(n.cast<float>());
  }
  return cloud;
}

// Fitting a posed body of another shape from its skeleton and cloud
// recovers its joints and surface.
TEST(BodyFitter, RecoversPoseAndShapeOfASyntheticCloud) {
  std::mt19937 rng(11);
  Eigen::VectorXd true_shape(Model().num_shape_components());
  std::normal_distribution<double> g(0.0, 1.0);
  for (int k = 0; k < true_shape.size(); ++k) true_shape[k] = std::clamp(g(rng), -1.5, 1.5);
  std::vector<body::PosedBody> truth;
  std::vector<PointCloud> clouds;
  for (int f = 0; f < 4; ++f) {
    body::BodyPose pose;
    pose.local_rotation[body::Index(KinectV2Joint::kSpineBase)] =
        Eigen::Quaterniond(Eigen::AngleAxisd(0.3 * f, Eigen::Vector3d::UnitY()));
    pose.local_rotation[body::Index(KinectV2Joint::kShoulderRight)] =
        Eigen::Quaterniond(Eigen::AngleAxisd(-0.4 * f, Eigen::Vector3d::UnitZ()));
    pose.local_rotation[body::Index(KinectV2Joint::kKneeLeft)] =
        Eigen::Quaterniond(Eigen::AngleAxisd(0.3 * f, Eigen::Vector3d::UnitX()));
    pose.root_translation_m = Eigen::Vector3d(0.05 * f, 0.0, 0.1);
    auto posed = body::PoseBody(Model(), pose, true_shape);
    ASSERT_TRUE(posed.ok());
    clouds.push_back(CloudOf(*posed, &rng));
    truth.push_back(std::move(*posed));
  }
  BodyFitOptions options;
  options.refine_vertices = false;
  auto fitter = BodyFitter::Create(Model(), options);
  ASSERT_TRUE(fitter.ok()) << fitter.status();
  std::normal_distribution<double> jitter(0.0, 0.01);
  std::vector<FitInput> inputs(clouds.size());
  std::vector<body::BodyPose> poses;
  for (size_t f = 0; f < clouds.size(); ++f) {
    inputs[f].cloud = &clouds[f];
    for (int j = 0; j < kJoints; ++j) {
      inputs[f].skeleton_m[j] =
          truth[f].joints_m[j] + Eigen::Vector3d(jitter(rng), jitter(rng), jitter(rng));
    }
    auto pose = (*fitter)->PoseFromSkeleton(inputs[f].skeleton_m);
    ASSERT_TRUE(pose.ok()) << pose.status();
    poses.push_back(*pose);
  }
  ASSERT_TRUE((*fitter)->FitShape(inputs, &poses).ok());
  double joint_error_mm = 0.0, surface_error_mm = 0.0;
  for (size_t f = 0; f < clouds.size(); ++f) {
    auto fit = (*fitter)->FitFrame(inputs[f], poses[f], nullptr);
    ASSERT_TRUE(fit.ok()) << fit.status();
    for (int j = 0; j < kJoints; ++j) {
      joint_error_mm += 1000.0 * (fit->joints_m[j] - truth[f].joints_m[j]).norm();
    }
    surface_error_mm += 1000.0 * (fit->vertices_m - truth[f].vertices_m).colwise().norm().mean();
  }
  joint_error_mm /= kJoints * clouds.size();
  surface_error_mm /= clouds.size();
  std::printf("synthetic cloud fit: MPJPE %.2f mm, mean vertex error %.2f mm\n", joint_error_mm,
              surface_error_mm);
  // Measured: 2.96 mm and 1.99 mm (2 mm point noise, 1 cm skeleton jitter).
  EXPECT_LT(joint_error_mm, 6.0);
  EXPECT_LT(surface_error_mm, 4.0);
}

// A sequence whose previous fit faces away from the person (after a
// skeleton with left and right swapped): FitNext carries it round to the
// skeleton and fits the cloud.
TEST(BodyFitter, FitNextTurnsAPreviousFitRoundToTheSkeleton) {
  std::mt19937 rng(12);
  body::BodyPose pose;
  pose.local_rotation[body::Index(KinectV2Joint::kShoulderRight)] =
      Eigen::Quaterniond(Eigen::AngleAxisd(-0.6, Eigen::Vector3d::UnitZ()));
  pose.local_rotation[body::Index(KinectV2Joint::kHipLeft)] =
      Eigen::Quaterniond(Eigen::AngleAxisd(0.4, Eigen::Vector3d::UnitX()));
  const Eigen::VectorXd mean_shape = Eigen::VectorXd::Zero(Model().num_shape_components());
  auto posed = body::PoseBody(Model(), pose, mean_shape);
  ASSERT_TRUE(posed.ok());
  const PointCloud cloud = CloudOf(*posed, &rng);
  BodyFitOptions options;
  options.refine_vertices = false;
  auto fitter = BodyFitter::Create(Model(), options);
  ASSERT_TRUE(fitter.ok()) << fitter.status();
  FitInput input;
  input.cloud = &cloud;
  for (int j = 0; j < kJoints; ++j) input.skeleton_m[j] = posed->joints_m[j];
  body::BodyPose turned = pose;
  turned.local_rotation[body::Index(KinectV2Joint::kSpineBase)] =
      Eigen::Quaterniond(Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitY()));
  auto next = (*fitter)->FitNext(input, &turned);
  ASSERT_TRUE(next.ok()) << next.status();
  ASSERT_TRUE(next->has_value());
  double error_mm = 0.0;
  for (int j = 0; j < kJoints; ++j) {
    error_mm += 1000.0 * ((*next)->fit.joints_m[j] - posed->joints_m[j]).norm();
  }
  error_mm /= kJoints;
  std::printf("from a pose turned round: MPJPE %.1f mm\n", error_mm);
  // Measured: 1.0 mm (2 mm point noise).
  EXPECT_LT(error_mm, 5.0);
}

// The tracker swapped the arms: the skeleton puts the raised right arm on
// the left. Started from that skeleton alone the fit crosses the arms and
// stays there; with hypotheses the points outvote the skeleton (the start
// with the arms swapped back explains the cloud, the other does not).
TEST(BodyFitter, ThePointsOutvoteASkeletonWithItsArmsSwapped) {
  std::mt19937 rng(21);
  const auto arms = [](double right_rad, double left_rad) {
    body::BodyPose pose;
    pose.local_rotation[body::Index(KinectV2Joint::kShoulderRight)] =
        Eigen::Quaterniond(Eigen::AngleAxisd(right_rad, Eigen::Vector3d::UnitZ()));
    pose.local_rotation[body::Index(KinectV2Joint::kShoulderLeft)] =
        Eigen::Quaterniond(Eigen::AngleAxisd(left_rad, Eigen::Vector3d::UnitZ()));
    return pose;
  };
  const Eigen::VectorXd mean_shape = Eigen::VectorXd::Zero(Model().num_shape_components());
  // The previous frame (fitted right) and this one: the right arm raised
  // further, the left one a little out.
  const body::BodyPose previous = arms(-1.1, 0.1);
  auto posed = body::PoseBody(Model(), arms(-1.3, 0.25), mean_shape);
  ASSERT_TRUE(posed.ok());
  const PointCloud cloud = CloudOf(*posed, &rng);
  FitInput input;
  input.cloud = &cloud;
  for (int j = 0; j < kJoints; ++j) input.skeleton_m[j] = posed->joints_m[j];
  input.skeleton_m = SwapArms(input.skeleton_m);

  const auto mpjpe_mm = [&](const FrameFit& fit) {
    double sum = 0.0;
    for (int j = 0; j < kJoints; ++j) sum += 1000.0 * (fit.joints_m[j] - posed->joints_m[j]).norm();
    return sum / kJoints;
  };
  BodyFitOptions options;
  options.refine_vertices = false;
  options.hypotheses = false;
  auto alone = BodyFitter::Create(Model(), options);
  ASSERT_TRUE(alone.ok()) << alone.status();
  auto from_skeleton = (*alone)->FitNext(input, &previous);
  ASSERT_TRUE(from_skeleton.ok() && from_skeleton->has_value());
  options.hypotheses = true;
  auto voting = BodyFitter::Create(Model(), options);
  ASSERT_TRUE(voting.ok()) << voting.status();
  auto outvoted = (*voting)->FitNext(input, &previous);
  ASSERT_TRUE(outvoted.ok()) << outvoted.status();
  ASSERT_TRUE(outvoted->has_value());
  const double before = mpjpe_mm((*from_skeleton)->fit);
  const double after = mpjpe_mm((*outvoted)->fit);
  std::printf(
      "arms swapped by the tracker: MPJPE %.1f mm from the skeleton (%.0f%% of points "
      "explained), %.1f mm with hypotheses (%s, %.0f%% explained)\n",
      before, 100.0 * (*from_skeleton)->fit.explained_fraction, after,
      HypothesisName((*outvoted)->hypothesis), 100.0 * (*outvoted)->fit.explained_fraction);
  EXPECT_LT(after, 10.0);
  EXPECT_GT(before, 3 * after);
  EXPECT_NE((*outvoted)->hypothesis, Hypothesis::kFollowSkeleton);
  EXPECT_GT((*outvoted)->fit.explained_fraction, 0.95);
  EXPECT_GT((*outvoted)->fit.explained_fraction, (*from_skeleton)->fit.explained_fraction);
}

// ExplainPose: the true pose explains its own cloud; a pose with an arm
// elsewhere leaves that arm's points unexplained.
TEST(BodyFitter, ExplainPoseCountsThePointsTheBodyLeavesUnexplained) {
  std::mt19937 rng(4);
  body::BodyPose pose;
  pose.local_rotation[body::Index(KinectV2Joint::kShoulderRight)] =
      Eigen::Quaterniond(Eigen::AngleAxisd(-1.2, Eigen::Vector3d::UnitZ()));
  const Eigen::VectorXd mean_shape = Eigen::VectorXd::Zero(Model().num_shape_components());
  auto posed = body::PoseBody(Model(), pose, mean_shape);
  ASSERT_TRUE(posed.ok());
  const PointCloud cloud = CloudOf(*posed, &rng);
  auto fitter = BodyFitter::Create(Model(), {});
  ASSERT_TRUE(fitter.ok());
  const Explanation right = (*fitter)->ExplainPose(pose, cloud, -1);
  EXPECT_EQ(right.points, static_cast<int>(cloud.size()));
  EXPECT_GT(right.fraction(), 0.98);
  EXPECT_LT(std::sqrt(right.cost) * 1000.0, 5.0);  // mm
  body::BodyPose wrong = pose;
  wrong.local_rotation[body::Index(KinectV2Joint::kShoulderRight)] = Eigen::Quaterniond::Identity();
  const Explanation off = (*fitter)->ExplainPose(wrong, cloud, -1);
  std::printf("explained: %.1f%% by the pose, %.1f%% with the arm down\n", 100.0 * right.fraction(),
              100.0 * off.fraction());
  EXPECT_LT(off.fraction(), right.fraction() - 0.03);
  EXPECT_GT(off.cost, 2 * right.cost);
}

// The points of `posed` a sensor at `centre` sees: the vertices facing it
// (no self-occlusion: the poses below hide nothing), 2 mm noise.
PointCloud SensorCloudOf(const body::PosedBody& posed, const Eigen::Vector3d& centre,
                         std::mt19937* rng) {
  const PointCloud all = CloudOf(posed, rng);
  PointCloud cloud;
  for (size_t i = 0; i < all.size(); ++i) {
    const Eigen::Vector3d to_sensor = centre - all.points_m[i].cast<double>();
    if (all.normals[i].cast<double>().dot(to_sensor) < 0.3 * to_sensor.norm()) continue;
    cloud.points_m.push_back(all.points_m[i]);
    cloud.normals.push_back(all.normals[i]);
  }
  cloud.sensor_ranges.push_back({0, 0, cloud.size()});
  return cloud;
}

// DiagnoseFit: the true surface explains one sensor's points and is seen
// where it faces the sensor; with the raised arm put down, the arm's points
// go unexplained and the model's arm hangs where the sensor saw nothing. A
// range of a sensor without a centre is left out, and an empty fit says
// nothing.
TEST(BodyFitter, DiagnoseFitTellsWhereTheSensorContradictsTheSurface) {
  std::mt19937 rng(8);
  body::BodyPose pose;
  pose.local_rotation[body::Index(KinectV2Joint::kShoulderRight)] =
      Eigen::Quaterniond(Eigen::AngleAxisd(-1.2, Eigen::Vector3d::UnitZ()));
  const Eigen::VectorXd mean_shape = Eigen::VectorXd::Zero(Model().num_shape_components());
  auto posed = body::PoseBody(Model(), pose, mean_shape);
  ASSERT_TRUE(posed.ok());
  const Eigen::Vector3d centre(0.3, 1.0, 2.5);
  const PointCloud cloud = SensorCloudOf(*posed, centre, &rng);
  auto fitter = BodyFitter::Create(Model(), {});
  ASSERT_TRUE(fitter.ok());
  FrameFit right;
  right.vertices_m = posed->vertices_m;
  const std::vector<SensorDiagnosis> good =
      (*fitter)->DiagnoseFit(right, cloud, {{centre, nullptr}});
  ASSERT_EQ(good.size(), 1u);
  EXPECT_EQ(good[0].points, static_cast<int>(cloud.size()));

  body::BodyPose down = pose;
  down.local_rotation[body::Index(KinectV2Joint::kShoulderRight)] = Eigen::Quaterniond::Identity();
  auto posed_down = body::PoseBody(Model(), down, mean_shape);
  ASSERT_TRUE(posed_down.ok());
  FrameFit wrong;
  wrong.vertices_m = posed_down->vertices_m;
  const std::vector<SensorDiagnosis> bad =
      (*fitter)->DiagnoseFit(wrong, cloud, {{centre, nullptr}});
  ASSERT_EQ(bad.size(), 1u);
  std::printf(
      "diagnosis of one sensor: the true surface explains %.1f%% of its points (RMS %.1f mm), "
      "%.1f%% of the surface facing it seen (%d vertices); with the arm down %.1f%% and %.1f%%\n",
      100.0 * good[0].explained_fraction(), good[0].rms_mm, 100.0 * good[0].surface_seen_fraction(),
      good[0].facing_vertices, 100.0 * bad[0].explained_fraction(),
      100.0 * bad[0].surface_seen_fraction());
  EXPECT_GT(good[0].explained_fraction(), 0.97);
  EXPECT_LT(good[0].rms_mm, 4.0);
  EXPECT_GT(good[0].surface_seen_fraction(), 0.85);
  EXPECT_LT(bad[0].explained_fraction(), good[0].explained_fraction() - 0.03);
  EXPECT_LT(bad[0].surface_seen_fraction(), good[0].surface_seen_fraction() - 0.03);

  // Surface outside the sensor's view is not judged.
  const SensorView blind{centre, [](const Eigen::Vector3d&) { return false; }};
  const std::vector<SensorDiagnosis> unseen = (*fitter)->DiagnoseFit(wrong, cloud, {blind});
  ASSERT_EQ(unseen.size(), 1u);
  EXPECT_EQ(unseen[0].facing_vertices, 0);
  EXPECT_EQ(unseen[0].surface_seen_fraction(), 1.0);
  EXPECT_EQ(unseen[0].explained, bad[0].explained);

  PointCloud elsewhere = cloud;
  elsewhere.sensor_ranges = {{3, 0, cloud.size()}, {0, cloud.size(), cloud.size() + 5}};
  EXPECT_TRUE((*fitter)->DiagnoseFit(right, elsewhere, {{centre, nullptr}}).empty());
  EXPECT_TRUE((*fitter)->DiagnoseFit(FrameFit{}, cloud, {{centre, nullptr}}).empty());
}

// A skeleton with NaN joints (a tracker's lost joints written as NaN): the
// fit runs on what is finite and stays finite; a skeleton without a torso
// and no previous fit gives nothing to start from, not an error.
TEST(BodyFitter, NaNJointsInTheSkeletonAreLeftOut) {
  std::mt19937 rng(12);
  body::BodyPose pose;
  pose.local_rotation[body::Index(KinectV2Joint::kElbowLeft)] =
      Eigen::Quaterniond(Eigen::AngleAxisd(0.6, Eigen::Vector3d::UnitX()));
  const Eigen::VectorXd mean_shape = Eigen::VectorXd::Zero(Model().num_shape_components());
  auto posed = body::PoseBody(Model(), pose, mean_shape);
  ASSERT_TRUE(posed.ok());
  const PointCloud cloud = CloudOf(*posed, &rng);
  FitInput input;
  input.cloud = &cloud;
  for (int j = 0; j < kJoints; ++j) input.skeleton_m[j] = posed->joints_m[j];
  const double nan = std::numeric_limits<double>::quiet_NaN();
  for (KinectV2Joint j : {KinectV2Joint::kWristLeft, KinectV2Joint::kKneeRight}) {
    input.skeleton_m[body::Index(j)] = Eigen::Vector3d(nan, 0.0, nan);
  }
  BodyFitOptions options;
  options.refine_vertices = false;
  auto fitter = BodyFitter::Create(Model(), options);
  ASSERT_TRUE(fitter.ok());
  auto fit = (*fitter)->FitNext(input, nullptr);
  ASSERT_TRUE(fit.ok()) << fit.status();
  ASSERT_TRUE(fit->has_value());
  EXPECT_TRUE((*fit)->fit.vertices_m.allFinite());
  double sum = 0.0;
  for (int j = 0; j < kJoints; ++j)
    sum += 1000.0 * ((*fit)->fit.joints_m[j] - posed->joints_m[j]).norm();
  EXPECT_LT(sum / kJoints, 15.0) << "mm";

  input.skeleton_m[body::Index(KinectV2Joint::kSpineBase)] = Eigen::Vector3d::Constant(nan);
  auto nothing = (*fitter)->FitNext(input, nullptr);
  ASSERT_TRUE(nothing.ok()) << nothing.status();
  EXPECT_FALSE(nothing->has_value());
}

TEST(BodyFitOptions, RejectsBadValues) {
  BodyFitOptions options;
  options.normal_epsilon = 0.5;
  EXPECT_EQ(options.Validate().code(), absl::StatusCode::kInvalidArgument);
  options = {};
  options.max_points = 0;
  EXPECT_EQ(options.Validate().code(), absl::StatusCode::kInvalidArgument);
}

}  // namespace
}  // namespace reenact::bodyfit
