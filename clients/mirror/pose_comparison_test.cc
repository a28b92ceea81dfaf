#include "clients/mirror/pose_comparison.h"

#include <algorithm>
#include <cmath>
#include <functional>
#include <iostream>
#include <limits>
#include <random>

#include <gtest/gtest.h>

#include "clients/mirror/body_parts.h"
#include "clients/mirror/testing/mocap_learners.h"

namespace reenact::mirror {
namespace {

using body::KinectV2Joint;
using body::SkeletonPose;
using testing::Joint;
using testing::LoadCmuTeacher;

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

TEST(BodyPartName, NamesAllThirteenParts) {
  EXPECT_EQ(BodyPartName(BodyPart::kHead), "head");
  EXPECT_EQ(BodyPartName(BodyPart::kRightLowerArm), "right_lower_arm");
  EXPECT_EQ(BodyPartName(BodyPart::kLeftLowerLeg), "left_lower_leg");
  EXPECT_EQ(BodyPartBone(BodyPart::kRightLowerArm).from, KinectV2Joint::kElbowRight);
  EXPECT_EQ(BodyPartBone(BodyPart::kRightLowerArm).to, KinectV2Joint::kWristRight);
  EXPECT_EQ(BodyPartBone(BodyPart::kTorso).from, KinectV2Joint::kSpineMid);
  EXPECT_EQ(BodyPartBone(BodyPart::kAbdomen).to, KinectV2Joint::kSpineMid);
}

TEST(ComparePoses, LearnerEqualToTeacherOnCmuMocapIsUnderOneDegree) {
  REENACT_REQUIRE_TEST_FILE(testing::CmuClipPath());
  const std::vector<SkeletonPose> teacher = LoadCmuTeacher(4);
  ASSERT_GT(teacher.size(), 200u);
  double worst_mean_deg = 0.0;
  double sum_mean_deg = 0.0;
  for (const SkeletonPose& pose_in_world : teacher) {
    // The learner as a sensor in front of them sees them: same pose, other frame.
    const SkeletonPose learner_in_sensor =
        TransformPose(testing::SensorInFrontOf(pose_in_world), pose_in_world);
    const PoseComparison comparison = ComparePoses(learner_in_sensor, pose_in_world);
    ASSERT_EQ(comparison.num_parts_compared, kNumBodyParts);
    ASSERT_TRUE(comparison.mean_error_deg);
    worst_mean_deg = std::max(worst_mean_deg, *comparison.mean_error_deg);
    sum_mean_deg += *comparison.mean_error_deg;
  }
  const double mean_deg = sum_mean_deg / teacher.size();
  std::cout << "learner == teacher (CMU 131_01, " << teacher.size() << " frames): mean error "
            << mean_deg << " deg, worst frame " << worst_mean_deg << " deg\n";
  RecordProperty("mean_error_deg", std::to_string(mean_deg));
  EXPECT_LT(mean_deg, 1.0);
  EXPECT_LT(worst_mean_deg, 1.0);
}

TEST(ComparePoses, ForearmTurnedThirtyDegreesShowsOnTheRightLowerArmOnly) {
  REENACT_REQUIRE_TEST_FILE(testing::CmuClipPath());
  const std::vector<SkeletonPose> teacher = LoadCmuTeacher(8);
  ASSERT_FALSE(teacher.empty());
  double min_forearm_deg = 180.0;
  double max_forearm_deg = 0.0;
  double max_other_deg = 0.0;
  for (const SkeletonPose& pose : teacher) {
    const PoseComparison comparison = ComparePoses(testing::TurnRightForearm(pose, 30.0), pose);
    for (int p = 0; p < kNumBodyParts; ++p) {
      ASSERT_TRUE(comparison.part_error_deg[p]) << BodyPartName(BodyPartAt(p));
      const double e = *comparison.part_error_deg[p];
      if (BodyPartAt(p) == BodyPart::kRightLowerArm) {
        min_forearm_deg = std::min(min_forearm_deg, e);
        max_forearm_deg = std::max(max_forearm_deg, e);
      } else {
        max_other_deg = std::max(max_other_deg, e);
      }
    }
  }
  std::cout << "right forearm turned 30 deg (" << teacher.size() << " frames): right_lower_arm "
            << min_forearm_deg << " .. " << max_forearm_deg << " deg, other parts at most "
            << max_other_deg << " deg\n";
  RecordProperty("right_lower_arm_min_deg", std::to_string(min_forearm_deg));
  RecordProperty("right_lower_arm_max_deg", std::to_string(max_forearm_deg));
  RecordProperty("other_parts_max_deg", std::to_string(max_other_deg));
  EXPECT_NEAR(min_forearm_deg, 30.0, 3.0);
  EXPECT_NEAR(max_forearm_deg, 30.0, 3.0);
  EXPECT_LT(max_other_deg, 3.0);
}

// Largest change of a part error when the learner (right forearm turned by
// 30 degrees) is placed somewhere else, turned, and given the bone scales
// that `scale_for` draws, against the same learner in place.
double LargestErrorChangeDeg(
    const std::function<std::array<double, body::kNumKinectV2Joints>(std::mt19937&)>& scale_for) {
  const std::vector<SkeletonPose> teacher = LoadCmuTeacher(16);
  std::mt19937 random(7);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  double largest_deg = 0.0;
  for (const SkeletonPose& pose : teacher) {
    const SkeletonPose learner = testing::TurnRightForearm(pose, 30.0);
    const PoseComparison reference = ComparePoses(learner, pose);
    const Eigen::Isometry3d somewhere =
        Eigen::Translation3d(3.0 * unit(random), unit(random), 3.0 * unit(random)) *
        Eigen::AngleAxisd(3.0 * unit(random),
                          Eigen::Vector3d(unit(random), unit(random), unit(random)).normalized());
    const PoseComparison moved = ComparePoses(
        TransformPose(somewhere, testing::ScaleBones(learner, scale_for(random))), pose);
    for (int p = 0; p < kNumBodyParts; ++p) {
      if (!moved.part_error_deg[p] || !reference.part_error_deg[p]) return 180.0;
      largest_deg =
          std::max(largest_deg, std::abs(*moved.part_error_deg[p] - *reference.part_error_deg[p]));
    }
  }
  return largest_deg;
}

TEST(ComparePoses, SameForLearnerPlacedTurnedAndWithOtherBoneLengths) {
  REENACT_REQUIRE_TEST_FILE(testing::CmuClipPath());
  // Every limb, the neck and head, the shoulders: each bone its own scale in
  // [0.7, 1.3]; the two spine bones share one scale, the two hips another
  // (a bigger or smaller trunk).
  const double limbs_deg = LargestErrorChangeDeg([](std::mt19937& random) {
    std::uniform_real_distribution<double> bone_scale(0.7, 1.3);
    std::array<double, body::kNumKinectV2Joints> scale;
    for (double& s : scale) s = bone_scale(random);
    const double spine = bone_scale(random);
    const double hips = bone_scale(random);
    scale[body::Index(KinectV2Joint::kSpineMid)] = spine;
    scale[body::Index(KinectV2Joint::kSpineShoulder)] = spine;
    scale[body::Index(KinectV2Joint::kHipLeft)] = hips;
    scale[body::Index(KinectV2Joint::kHipRight)] = hips;
    return scale;
  });
  // Other trunk proportions: abdomen and torso scaled 10% apart, which tilts
  // SpineBase->SpineShoulder where the spine is curved (body_parts.h).
  const double trunk_deg = LargestErrorChangeDeg([](std::mt19937& random) {
    std::array<double, body::kNumKinectV2Joints> scale;
    scale.fill(1.0);
    scale[body::Index(KinectV2Joint::kSpineMid)] = 1.05;
    scale[body::Index(KinectV2Joint::kSpineShoulder)] = 0.95;
    return scale;
  });
  std::cout << "learner placed, turned, limb bones scaled 0.7-1.3 independently: largest change "
               "of a part error "
            << limbs_deg << " deg; abdomen/torso 10% apart: " << trunk_deg << " deg\n";
  RecordProperty("limb_scaling_change_deg", std::to_string(limbs_deg));
  RecordProperty("trunk_proportion_change_deg", std::to_string(trunk_deg));
  EXPECT_LT(limbs_deg, 1e-6);
  EXPECT_LT(trunk_deg, 3.0);
}

TEST(ComparePoses, NanAndMissingJointsGiveMissingPartsWithoutCrashing) {
  REENACT_REQUIRE_TEST_FILE(testing::CmuClipPath());
  const SkeletonPose teacher = LoadCmuTeacher(1, 1).at(0);
  SkeletonPose learner = teacher;
  learner.position_m[body::Index(KinectV2Joint::kWristRight)].x() = kNaN;
  learner.valid[body::Index(KinectV2Joint::kKneeLeft)] = false;
  learner.position_m[body::Index(KinectV2Joint::kHead)].z() =
      std::numeric_limits<double>::infinity();
  const PoseComparison comparison = ComparePoses(learner, teacher);
  EXPECT_FALSE(comparison.part_error_deg[Index(BodyPart::kRightLowerArm)]);
  EXPECT_FALSE(comparison.part_error_deg[Index(BodyPart::kLeftUpperLeg)]);
  EXPECT_FALSE(comparison.part_error_deg[Index(BodyPart::kLeftLowerLeg)]);
  EXPECT_FALSE(comparison.part_error_deg[Index(BodyPart::kHead)]);
  EXPECT_EQ(comparison.num_parts_compared, kNumBodyParts - 4);
  ASSERT_TRUE(comparison.mean_error_deg);
  EXPECT_LT(*comparison.mean_error_deg, 1e-6);
  const auto joints = JointErrorsDeg(comparison);
  EXPECT_FALSE(joints[body::Index(KinectV2Joint::kHandRight)]);
  EXPECT_FALSE(joints[body::Index(KinectV2Joint::kKneeLeft)]);
  EXPECT_TRUE(joints[body::Index(KinectV2Joint::kElbowRight)]);  // Upper arm is there.

  SkeletonPose no_spine = teacher;
  no_spine.position_m[body::Index(KinectV2Joint::kSpineBase)].setConstant(kNaN);
  const PoseComparison none = ComparePoses(no_spine, teacher);
  EXPECT_EQ(none.num_parts_compared, 0);
  EXPECT_FALSE(none.mean_error_deg);

  SkeletonPose all_nan;
  for (auto& p : all_nan.position_m) p.setConstant(kNaN);
  all_nan.valid.fill(true);
  EXPECT_EQ(ComparePoses(all_nan, all_nan).num_parts_compared, 0);
  EXPECT_EQ(ComparePoses(SkeletonPose{}, teacher).num_parts_compared, 0);
}

TEST(JointErrorsDeg, TakesTheWorstTouchingPartAndHandsFollowTheForearm) {
  PoseComparison comparison;
  comparison.part_error_deg[Index(BodyPart::kRightUpperArm)] = 10.0;
  comparison.part_error_deg[Index(BodyPart::kRightLowerArm)] = 25.0;
  comparison.part_error_deg[Index(BodyPart::kRightShoulder)] = 4.0;
  const auto joints = JointErrorsDeg(comparison);
  EXPECT_DOUBLE_EQ(*joints[body::Index(KinectV2Joint::kElbowRight)], 25.0);
  EXPECT_DOUBLE_EQ(*joints[body::Index(KinectV2Joint::kShoulderRight)], 10.0);
  EXPECT_DOUBLE_EQ(*joints[body::Index(KinectV2Joint::kWristRight)], 25.0);
  EXPECT_DOUBLE_EQ(*joints[body::Index(KinectV2Joint::kHandTipRight)], 25.0);
  EXPECT_DOUBLE_EQ(*joints[body::Index(KinectV2Joint::kSpineShoulder)], 4.0);
  EXPECT_FALSE(joints[body::Index(KinectV2Joint::kHandLeft)]);
  EXPECT_FALSE(joints[body::Index(KinectV2Joint::kFootRight)]);
}

TEST(ErrorToSrgb, GreenAtZeroYellowAtFifteenRedFromThirty) {
  const ErrorColorOptions options;
  EXPECT_EQ(ErrorToSrgb(0.0), options.green_color);
  EXPECT_EQ(ErrorToSrgb(-3.0), options.green_color);
  EXPECT_EQ(ErrorToSrgb(15.0), options.yellow_color);
  EXPECT_EQ(ErrorToSrgb(30.0), options.red_color);
  EXPECT_EQ(ErrorToSrgb(95.0), options.red_color);
  EXPECT_EQ(ErrorToSrgb(kNaN), options.missing_color);
  EXPECT_EQ(ErrorToSrgb(std::optional<double>()), options.missing_color);
  const Srgb8 between = ErrorToSrgb(7.5);
  EXPECT_GT(between.r, options.green_color.r);
  EXPECT_LT(between.r, options.yellow_color.r);

  ErrorColorOptions strict;
  strict.yellow_deg = 5.0;
  strict.red_deg = 10.0;
  ASSERT_TRUE(strict.Validate().ok());
  EXPECT_EQ(ErrorToSrgb(10.0, strict), strict.red_color);
  EXPECT_EQ(ErrorToSrgb(5.0, strict), strict.yellow_color);
  strict.red_deg = 4.0;
  EXPECT_FALSE(strict.Validate().ok());
}

}  // namespace
}  // namespace reenact::mirror
