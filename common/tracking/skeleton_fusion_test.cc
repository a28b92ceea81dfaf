#include "common/tracking/skeleton_fusion.h"

#include <cmath>
#include <iostream>
#include <limits>
#include <random>
#include <vector>

#include <gtest/gtest.h>

namespace reenact::tracking {
namespace {

using body::Index;
using J = body::KinectV2Joint;
constexpr int kNumJoints = body::kNumKinectV2Joints;
constexpr double kMm = 1e-3;

using Pose = std::array<Eigen::Vector3d, kNumJoints>;

// A person standing at the origin facing +Z (+Y up, so their left is +X),
// arms a little out and forward, feet pointing forward. World metres.
Pose TruthPose() {
  Pose p;
  auto set = [&p](J j, double x, double y, double z) { p[Index(j)] = Eigen::Vector3d(x, y, z); };
  set(J::kSpineBase, 0, 1.00, 0);
  set(J::kSpineMid, 0, 1.25, 0.01);
  set(J::kSpineShoulder, 0, 1.45, 0);
  set(J::kNeck, 0, 1.55, 0);
  set(J::kHead, 0, 1.70, 0.02);
  for (double side : {1.0, -1.0}) {
    const bool left = side > 0;
    set(left ? J::kShoulderLeft : J::kShoulderRight, 0.18 * side, 1.42, 0);
    set(left ? J::kElbowLeft : J::kElbowRight, 0.27 * side, 1.16, 0.06);
    set(left ? J::kWristLeft : J::kWristRight, 0.31 * side, 0.93, 0.14);
    set(left ? J::kHandLeft : J::kHandRight, 0.32 * side, 0.86, 0.16);
    set(left ? J::kHandTipLeft : J::kHandTipRight, 0.33 * side, 0.79, 0.18);
    set(left ? J::kThumbLeft : J::kThumbRight, 0.28 * side, 0.87, 0.20);
    set(left ? J::kHipLeft : J::kHipRight, 0.10 * side, 0.95, 0);
    set(left ? J::kKneeLeft : J::kKneeRight, 0.12 * side, 0.52, 0.05);
    set(left ? J::kAnkleLeft : J::kAnkleRight, 0.12 * side, 0.10, 0);
    set(left ? J::kFootLeft : J::kFootRight, 0.13 * side, 0.05, 0.12);
  }
  return p;
}

// A camera at `position_m` looking at the person's middle, OpenCV axes (x
// right, y down, z forward).
Rigid3d CameraAt(const Eigen::Vector3d& position_m) {
  const Eigen::Vector3d z = (Eigen::Vector3d(0, 1.0, 0) - position_m).normalized();
  const Eigen::Vector3d x = (-Eigen::Vector3d::UnitY()).cross(z).normalized();
  Eigen::Matrix3d rotation;
  rotation << x, z.cross(x), z;
  return Rigid3d(Eigen::Quaterniond(rotation), position_m);
}

Rigid3d FrontCamera() { return CameraAt({0, 1.0, 2.5}); }
Rigid3d BackCamera() { return CameraAt({0, 1.0, -2.5}); }
Rigid3d SideCamera() { return CameraAt({2.5, 1.0, 0.3}); }

// The person as `camera` tracks it: every joint tracked at confidence 1,
// with Gaussian noise of `sigma_m` per axis.
SensorSkeleton View(const std::string& id, const Rigid3d& world_from_camera, const Pose& truth,
                    double sigma_m, std::mt19937_64* rng) {
  std::normal_distribution<double> normal(0.0, sigma_m);
  SensorSkeleton s;
  s.sensor_id = id;
  s.world_from_camera = world_from_camera;
  const Rigid3d camera_from_world = world_from_camera.Inverse();
  for (int j = 0; j < kNumJoints; ++j) {
    TrackedJoint& joint = s.joints[j];
    const Eigen::Vector3d noise(normal(*rng), normal(*rng), normal(*rng));
    joint.position_in_camera_m = camera_from_world * truth[j] + noise;
    joint.confidence = 1.0;
    joint.state = JointState::kTracked;
  }
  return s;
}

// Exchanges every left joint with its right one (a tracker that took the
// person's back for their front).
void SwapLeftRight(SensorSkeleton* s) {
  for (int j = 0; j < kNumJoints; ++j) {
    const int m = Index(MirrorKinectV2Joint(static_cast<J>(j)));
    if (m > j) std::swap(s->joints[j], s->joints[m]);
  }
}

double MeanErrorM(const FusedSkeleton& fused, const Pose& truth) {
  double sum = 0.0;
  for (int j = 0; j < kNumJoints; ++j)
    sum += (fused.joints[j].position_in_world_m - truth[j]).norm();
  return sum / kNumJoints;
}

double MeanErrorM(const SensorSkeleton& s, const Pose& truth) {
  double sum = 0.0;
  for (int j = 0; j < kNumJoints; ++j) {
    sum += (s.world_from_camera * s.joints[j].position_in_camera_m - truth[j]).norm();
  }
  return sum / kNumJoints;
}

SkeletonFusionSummary FuseOk(const std::vector<SensorSkeleton>& sensors,
                             const SkeletonFusionOptions& options = {},
                             const FusedSkeleton* previous = nullptr) {
  absl::StatusOr<SkeletonFusionSummary> summary = FuseSkeletons(sensors, options, previous);
  EXPECT_TRUE(summary.ok()) << summary.status();
  return summary.ok() ? *summary : SkeletonFusionSummary{};
}

TEST(MirrorKinectV2Joint, PairsLeftWithRightAndKeepsTheMidline) {
  for (int j = 0; j < kNumJoints; ++j) {
    const auto joint = static_cast<J>(j);
    const J mirror = MirrorKinectV2Joint(joint);
    EXPECT_EQ(MirrorKinectV2Joint(mirror), joint) << body::KinectV2JointName(joint);
    std::string name(body::KinectV2JointName(joint)), mirror_name(body::KinectV2JointName(mirror));
    for (auto [from, to] : {std::pair{"Left", "Right"}, {"Right", "Left"}}) {
      if (const size_t at = name.find(from); at != std::string::npos) {
        name.replace(at, std::string(from).size(), to);
        break;
      }
    }
    EXPECT_EQ(name, mirror_name);
  }
  EXPECT_EQ(MirrorKinectV2Joint(J::kHead), J::kHead);
  EXPECT_EQ(MirrorKinectV2Joint(J::kThumbLeft), J::kThumbRight);
}

TEST(FuseSkeletons, ExactViewsGiveTheTruthInTheWorld) {
  std::mt19937_64 rng(1);
  const Pose truth = TruthPose();
  const SkeletonFusionSummary s = FuseOk({View("front", FrontCamera(), truth, 0.0, &rng),
                                          View("side", SideCamera(), truth, 0.0, &rng)});
  EXPECT_LT(MeanErrorM(s.skeleton, truth), 1e-6 * kMm);
  EXPECT_EQ(s.num_tracked, kNumJoints);
  for (const FusedJoint& joint : s.skeleton.joints) {
    EXPECT_EQ(joint.sensors, (std::vector<int>{0, 1}));
    EXPECT_NEAR(joint.confidence, 1.0, 1e-12);
  }
  for (const SensorFusionReport& r : s.sensors) {
    EXPECT_TRUE(r.used);
    EXPECT_FALSE(r.swapped_left_right);
    EXPECT_EQ(r.joints_used, kNumJoints);
  }
}

TEST(FuseSkeletons, TwoNoisyViewsFuseCloserToTheTruthThanEither) {
  std::mt19937_64 rng(7);
  const Pose truth = TruthPose();
  constexpr int kInstants = 200;
  double front_m = 0, side_m = 0, fused_m = 0;
  for (int i = 0; i < kInstants; ++i) {
    const SensorSkeleton front = View("front", FrontCamera(), truth, 10 * kMm, &rng);
    const SensorSkeleton side = View("side", SideCamera(), truth, 10 * kMm, &rng);
    front_m += MeanErrorM(front, truth) / kInstants;
    side_m += MeanErrorM(side, truth) / kInstants;
    fused_m += MeanErrorM(FuseOk({front, side}).skeleton, truth) / kInstants;
  }
  std::cout << "mean joint error, 10 mm per axis: front " << front_m / kMm << " mm, side "
            << side_m / kMm << " mm, fused " << fused_m / kMm << " mm\n";
  // E|N(0, s^2 I3)| = s sqrt(8 / pi) = 15.96 mm per view; the mean of two
  // views divides it by sqrt(2): 11.28 mm.
  EXPECT_NEAR(front_m / kMm, 15.96, 0.6);
  EXPECT_NEAR(side_m / kMm, 15.96, 0.6);
  EXPECT_NEAR(fused_m / kMm, 11.28, 0.6);
  EXPECT_LT(fused_m, 0.75 * std::min(front_m, side_m));
}

TEST(FuseSkeletons, TrackedOutweighsInferred) {
  std::mt19937_64 rng(3);
  const Pose truth = TruthPose();
  SensorSkeleton front = View("front", FrontCamera(), truth, 0.0, &rng);
  SensorSkeleton side = View("side", SideCamera(), truth, 0.0, &rng);
  const int hand = Index(J::kHandRight);
  side.joints[hand].state = JointState::kInferred;
  side.joints[hand].position_in_camera_m += Eigen::Vector3d(0.03, 0, 0);  // Within the kernel.
  const SkeletonFusionSummary s = FuseOk({front, side});
  const double error_m = (s.skeleton.joints[hand].position_in_world_m - truth[hand]).norm();
  std::cout << "tracked 0 mm off + inferred 30 mm off: fused " << error_m / kMm << " mm off\n";
  EXPECT_LT(error_m, 3.0 * kMm);  // 0.1 / 1.1 of 30 mm, less the kernel's pull.
  EXPECT_EQ(s.skeleton.joints[hand].state, JointState::kTracked);
}

TEST(FuseSkeletons, SensorWithLeftAndRightSwappedIsDetectedAndFixed) {
  std::mt19937_64 rng(11);
  const Pose truth = TruthPose();
  SensorSkeleton back = View("back", BackCamera(), truth, 5 * kMm, &rng);
  SwapLeftRight(&back);
  const std::vector<SensorSkeleton> sensors = {View("front", FrontCamera(), truth, 5 * kMm, &rng),
                                               View("side", SideCamera(), truth, 5 * kMm, &rng),
                                               back};
  const SkeletonFusionSummary s = FuseOk(sensors);
  std::cout << s.BriefReport() << "\n";
  EXPECT_FALSE(s.sensors[0].swapped_left_right);
  EXPECT_FALSE(s.sensors[1].swapped_left_right);
  EXPECT_TRUE(s.sensors[2].swapped_left_right);
  for (int p = 0; p < kNumLimbPairs; ++p) {
    EXPECT_TRUE(s.sensors[2].swapped_limbs[p]) << LimbPairName(static_cast<LimbPair>(p));
  }
  const double error_m = MeanErrorM(s.skeleton, truth);
  std::cout << "three views (one swapped), 5 mm per axis: fused " << error_m / kMm << " mm\n";
  EXPECT_LT(error_m, 6.0 * kMm);  // 5 mm * 1.6 / sqrt(3) = 4.6 mm expected.
  for (const FusedJoint& joint : s.skeleton.joints) EXPECT_EQ(joint.sensors.size(), 3u);
}

TEST(FuseSkeletons, TwoViewsFrontAndBackTrustTheFeetForWhichIsSwapped) {
  std::mt19937_64 rng(12);
  const Pose truth = TruthPose();
  SensorSkeleton back = View("back", BackCamera(), truth, 5 * kMm, &rng);
  SwapLeftRight(&back);
  // Either order of the input: the swapped one is the one whose labels face
  // away from where its feet point.
  for (bool back_first : {false, true}) {
    const SensorSkeleton front = View("front", FrontCamera(), truth, 5 * kMm, &rng);
    const std::vector<SensorSkeleton> sensors =
        back_first ? std::vector{back, front} : std::vector{front, back};
    const SkeletonFusionSummary s = FuseOk(sensors);
    const int b = back_first ? 0 : 1;
    EXPECT_TRUE(s.sensors[b].swapped_left_right);
    EXPECT_FALSE(s.sensors[1 - b].swapped_left_right);
    EXPECT_LT(s.sensors[b].facing_agreement, -0.9);
    EXPECT_GT(s.sensors[1 - b].facing_agreement, 0.9);
    EXPECT_LT(MeanErrorM(s.skeleton, truth), 8.0 * kMm);
  }
}

TEST(FuseSkeletons, OneSwappedArmOnlySwapsTheArm) {
  std::mt19937_64 rng(13);
  const Pose truth = TruthPose();
  SensorSkeleton side = View("side", SideCamera(), truth, 5 * kMm, &rng);
  for (J left : LimbPairLeftJoints(LimbPair::kArms)) {
    std::swap(side.joints[Index(left)], side.joints[Index(MirrorKinectV2Joint(left))]);
  }
  const SkeletonFusionSummary s = FuseOk({View("front", FrontCamera(), truth, 5 * kMm, &rng),
                                          View("back", BackCamera(), truth, 5 * kMm, &rng), side});
  for (int p = 0; p < kNumLimbPairs; ++p) {
    EXPECT_EQ(s.sensors[2].swapped_limbs[p], static_cast<LimbPair>(p) == LimbPair::kArms)
        << LimbPairName(static_cast<LimbPair>(p));
  }
  EXPECT_LT(MeanErrorM(s.skeleton, truth), 6.0 * kMm);
}

TEST(FuseSkeletons, NoSwapWithoutEvidence) {
  // Agreeing views, and a lone view with nothing to compare to, keep their labels.
  std::mt19937_64 rng(14);
  const Pose truth = TruthPose();
  SensorSkeleton back = View("back", BackCamera(), truth, 5 * kMm, &rng);
  SwapLeftRight(&back);
  EXPECT_FALSE(FuseOk({back}).sensors[0].swapped_left_right);
  const SkeletonFusionSummary s = FuseOk({View("front", FrontCamera(), truth, 5 * kMm, &rng),
                                          View("back", BackCamera(), truth, 5 * kMm, &rng)});
  EXPECT_FALSE(s.sensors[0].swapped_left_right);
  EXPECT_FALSE(s.sensors[1].swapped_left_right);
}

TEST(FuseSkeletons, PreviousSkeletonDecidesTheSwapOfALoneSensor) {
  std::mt19937_64 rng(15);
  const Pose truth = TruthPose();
  const FusedSkeleton previous =
      FuseOk({View("front", FrontCamera(), truth, 5 * kMm, &rng)}).skeleton;
  SensorSkeleton back = View("back", BackCamera(), truth, 5 * kMm, &rng);
  SwapLeftRight(&back);
  const SkeletonFusionSummary s = FuseOk({back}, {}, &previous);
  EXPECT_TRUE(s.used_previous);
  EXPECT_TRUE(s.sensors[0].swapped_left_right);
  EXPECT_LT(MeanErrorM(s.skeleton, truth), 12.0 * kMm);
}

TEST(SequentialSkeletonFusion, CarriesThePreviousSkeletonWithinTheGap) {
  std::mt19937_64 rng(16);
  const Pose truth = TruthPose();
  SequentialSkeletonFusion sequence({}, /*max_gap_ns=*/100'000'000);
  SensorSkeleton back = View("back", BackCamera(), truth, 5 * kMm, &rng);
  SwapLeftRight(&back);
  ASSERT_TRUE(sequence.Fuse({View("front", FrontCamera(), truth, 5 * kMm, &rng)}, 0).ok());
  absl::StatusOr<SkeletonFusionSummary> next = sequence.Fuse({back}, 33'000'000);
  ASSERT_TRUE(next.ok()) << next.status();
  EXPECT_TRUE(next->used_previous);
  EXPECT_TRUE(next->sensors[0].swapped_left_right);
  // The swap was fixed, so the next frame sees the same person; a gap past
  // the limit forgets it.
  next = sequence.Fuse({back}, 66'000'000);
  ASSERT_TRUE(next.ok());
  EXPECT_TRUE(next->sensors[0].swapped_left_right);
  next = sequence.Fuse({back}, 500'000'000);
  ASSERT_TRUE(next.ok());
  EXPECT_FALSE(next->used_previous);
  EXPECT_FALSE(next->sensors[0].swapped_left_right);
}

// A lone sensor's first skeleton had left and right swapped, the next ones
// are right: the previous skeleton overrules them for a while (a device
// that flips for a frame or two is held), then the sensors win.
TEST(SequentialSkeletonFusion, AnEarlySwapIsNotCarriedOnForEver) {
  std::mt19937_64 rng(17);
  const Pose truth = TruthPose();
  SkeletonFusionOptions options;
  ASSERT_EQ(options.max_overruled_instants, 3);
  SequentialSkeletonFusion sequence(options);
  SensorSkeleton first = View("front", FrontCamera(), truth, 5 * kMm, &rng);
  SwapLeftRight(&first);
  ASSERT_TRUE(sequence.Fuse({first}, 0).ok());
  for (int i = 1; i <= 6; ++i) {
    absl::StatusOr<SkeletonFusionSummary> next =
        sequence.Fuse({View("front", FrontCamera(), truth, 5 * kMm, &rng)}, i * 33'000'000);
    ASSERT_TRUE(next.ok()) << next.status();
    SCOPED_TRACE(i);
    if (i < 3) {
      EXPECT_TRUE(next->sensors[0].swapped_left_right);
      EXPECT_GT(MeanErrorM(next->skeleton, truth), 50.0 * kMm);
    } else {
      EXPECT_FALSE(next->sensors[0].swapped_left_right);
      EXPECT_LT(MeanErrorM(next->skeleton, truth), 12.0 * kMm);
    }
  }
}

TEST(FuseSkeletons, LostHandHardlyPullsTheFusedHand) {
  std::mt19937_64 rng(21);
  const Pose truth = TruthPose();
  std::vector<SensorSkeleton> sensors = {View("front", FrontCamera(), truth, 5 * kMm, &rng),
                                         View("side", SideCamera(), truth, 5 * kMm, &rng),
                                         View("back", BackCamera(), truth, 5 * kMm, &rng)};
  const int hand = Index(J::kHandLeft);
  const Eigen::Vector3d clean_m = FuseOk(sensors).skeleton.joints[hand].position_in_world_m;
  sensors[1].joints[hand].position_in_camera_m += Eigen::Vector3d(0.0, -0.40, 0.0);  // 40 cm.
  const SkeletonFusionSummary s = FuseOk(sensors);
  const FusedJoint& fused = s.skeleton.joints[hand];
  const double pull_m = (fused.position_in_world_m - clean_m).norm();
  std::cout << "hand 40 cm off in one of three views: fused hand moved " << pull_m / kMm
            << " mm (the plain mean would move 133 mm)\n";
  EXPECT_LT(pull_m, 4.0 * kMm);
  EXPECT_EQ(fused.sensors, (std::vector<int>{0, 2}));
  EXPECT_EQ(fused.state, JointState::kTracked);
  EXPECT_EQ(s.sensors[1].joints_outlying, 1);
  EXPECT_FALSE(s.sensors[1].swapped_left_right);
}

TEST(FuseSkeletons, CauchyRejectsALostHandBetterThanHuber) {
  std::mt19937_64 rng(22);
  const Pose truth = TruthPose();
  std::vector<SensorSkeleton> sensors = {View("front", FrontCamera(), truth, 0.0, &rng),
                                         View("side", SideCamera(), truth, 0.0, &rng),
                                         View("back", BackCamera(), truth, 0.0, &rng)};
  const int hand = Index(J::kHandLeft);
  sensors[1].joints[hand].position_in_camera_m += Eigen::Vector3d(0.0, -0.40, 0.0);
  SkeletonFusionOptions huber;
  huber.kernel = SkeletonFusionOptions::Kernel::kHuber;
  const double cauchy_m =
      (FuseOk(sensors).skeleton.joints[hand].position_in_world_m - truth[hand]).norm();
  const double huber_m =
      (FuseOk(sensors, huber).skeleton.joints[hand].position_in_world_m - truth[hand]).norm();
  std::cout << "hand 40 cm off, exact others: Cauchy " << cauchy_m / kMm << " mm, Huber "
            << huber_m / kMm << " mm\n";
  EXPECT_LT(cauchy_m, 3.0 * kMm);  // Weight 1/101 of 3 votes: 2.0 mm.
  EXPECT_GT(huber_m, 3.0 * cauchy_m);
}

TEST(FuseSkeletons, TwoDisagreeingViewsFollowThePreviousSkeleton) {
  std::mt19937_64 rng(23);
  const Pose truth = TruthPose();
  std::vector<SensorSkeleton> sensors = {View("front", FrontCamera(), truth, 0.0, &rng),
                                         View("side", SideCamera(), truth, 0.0, &rng)};
  const FusedSkeleton previous = FuseOk(sensors).skeleton;
  const int hand = Index(J::kHandLeft);
  sensors[1].joints[hand].position_in_camera_m += Eigen::Vector3d(0.0, -0.40, 0.0);
  // Without a previous skeleton neither view is the consensus: the mean, inferred.
  const FusedJoint alone = FuseOk(sensors).skeleton.joints[hand];
  EXPECT_EQ(alone.state, JointState::kInferred);
  EXPECT_LT(alone.confidence, 0.1);
  const FusedJoint with_previous = FuseOk(sensors, {}, &previous).skeleton.joints[hand];
  const double error_m = (with_previous.position_in_world_m - truth[hand]).norm();
  std::cout << "hand 40 cm off in one of two views, with the previous frame: " << error_m / kMm
            << " mm\n";
  EXPECT_LT(error_m, 8.0 * kMm);
  EXPECT_EQ(with_previous.sensors, std::vector<int>{0});
}

TEST(FuseSkeletons, NonFiniteJointsAndPosesAreLeftOut) {
  std::mt19937_64 rng(31);
  const Pose truth = TruthPose();
  const double nan = std::numeric_limits<double>::quiet_NaN();
  SensorSkeleton front = View("front", FrontCamera(), truth, 0.0, &rng);
  SensorSkeleton side = View("side", SideCamera(), truth, 0.0, &rng);
  front.joints[Index(J::kHead)].position_in_camera_m.x() = nan;
  front.joints[Index(J::kKneeLeft)].confidence = nan;
  side.joints[Index(J::kHead)].position_in_camera_m.z() = std::numeric_limits<double>::infinity();
  SensorSkeleton broken = View("broken", SideCamera(), truth, 0.0, &rng);
  broken.world_from_camera.translation.y() = nan;
  const SkeletonFusionSummary s = FuseOk({front, side, broken});
  EXPECT_EQ(s.sensors[0].joints_rejected, 2);
  EXPECT_EQ(s.sensors[1].joints_rejected, 1);
  EXPECT_FALSE(s.sensors[2].used);
  EXPECT_EQ(s.skeleton.joints[Index(J::kHead)].state, JointState::kNotTracked);
  EXPECT_EQ(s.skeleton.joints[Index(J::kKneeLeft)].sensors, std::vector<int>{1});
  EXPECT_EQ(s.num_tracked, kNumJoints - 1);
  for (const FusedJoint& joint : s.skeleton.joints)
    EXPECT_TRUE(joint.position_in_world_m.allFinite());
  const int knee = Index(J::kKneeLeft);
  EXPECT_LT((s.skeleton.joints[knee].position_in_world_m - truth[knee]).norm(), 1e-6 * kMm);
}

TEST(FuseSkeletons, NothingUsableGivesAnUntrackedSkeleton) {
  std::mt19937_64 rng(32);
  SensorSkeleton s = View("front", FrontCamera(), TruthPose(), 0.0, &rng);
  for (TrackedJoint& joint : s.joints) joint.position_in_camera_m.setConstant(std::nan(""));
  const SkeletonFusionSummary summary = FuseOk({s});
  EXPECT_EQ(summary.num_tracked + summary.num_inferred, 0);
  EXPECT_FALSE(summary.sensors[0].used);
  EXPECT_EQ(summary.sensors[0].joints_rejected, kNumJoints);
}

TEST(FuseSkeletons, EmptyInputTooManySensorsAndBadOptionsAreErrors) {
  absl::StatusOr<SkeletonFusionSummary> empty = FuseSkeletons({});
  ASSERT_FALSE(empty.ok());
  EXPECT_EQ(empty.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_NE(empty.status().message().find("no sensor skeletons"), std::string::npos);
  std::mt19937_64 rng(33);
  const SensorSkeleton one = View("front", FrontCamera(), TruthPose(), 0.0, &rng);
  EXPECT_EQ(FuseSkeletons(std::vector<SensorSkeleton>(kMaxFusionSensors + 1, one)).status().code(),
            absl::StatusCode::kInvalidArgument);
  SkeletonFusionOptions bad;
  bad.robust_scale_m = 0.0;
  EXPECT_EQ(FuseSkeletons({one}, bad).status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_TRUE(SkeletonFusionOptions{}.Validate().ok());
}

}  // namespace
}  // namespace reenact::tracking
