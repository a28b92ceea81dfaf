#include "common/synth/builtin_motions.h"

#include <algorithm>
#include <cmath>
#include <iostream>
#include <string>

#include <gtest/gtest.h>

#include "common/body/body_model.h"
#include "common/body/joint_set.h"
#include "common/body/procedural_body.h"
#include "common/body/retarget.h"

namespace reenact::synth {
namespace {

using J = body::KinectV2Joint;

constexpr double kFps = 30.0;

Eigen::Vector3d JointAt(const body::Motion& motion, int frame, J joint) {
  return motion.CanonicalPose(frame).position_m[body::Index(joint)];
}

// Height (m) of the lowest foot contact: foot joints, or ankles less the
// 5 cm ankle height.
double LowestFootHeight(const body::Motion& motion, int frame) {
  const body::SkeletonPose pose = motion.CanonicalPose(frame);
  auto y = [&pose](J joint) { return pose.position_m[body::Index(joint)].y(); };
  return std::min(
      {y(J::kFootLeft), y(J::kFootRight), y(J::kAnkleLeft) - 0.05, y(J::kAnkleRight) - 0.05});
}

TEST(MakeBuiltinMotion, EveryNameBuildsWithFeetOnFloor) {
  const auto names = BuiltinMotionNames();
  ASSERT_EQ(names.size(), 3u);
  for (const std::string& name : names) {
    auto motion = MakeBuiltinMotion(name, 4.0, kFps);
    ASSERT_TRUE(motion.ok()) << name << ": " << motion.status();
    EXPECT_EQ(motion->num_frames(), 120) << name;
    EXPECT_NEAR(motion->fps(), kFps, 1e-9) << name;
    double worst_mm = 0.0;
    for (int f = 0; f < motion->num_frames(); ++f) {
      worst_mm = std::max(worst_mm, std::abs(LowestFootHeight(*motion, f)) * 1e3);
    }
    std::cout << name << ": lowest foot off the floor by at most " << worst_mm << " mm\n";
    EXPECT_LT(worst_mm, 10.0) << name;  // mm
  }
}

TEST(MakeBuiltinMotion, ArmRaiseLiftsLeftArmFromBelowToAboveHorizontal) {
  auto motion = MakeBuiltinMotion("arm-raise", 8.0, kFps);
  ASSERT_TRUE(motion.ok()) << motion.status();
  double lowest_deg = 90.0, highest_deg = -90.0;
  for (int f = 0; f < motion->num_frames(); ++f) {
    const Eigen::Vector3d upper_arm =
        JointAt(*motion, f, J::kElbowLeft) - JointAt(*motion, f, J::kShoulderLeft);
    const double elevation_deg = std::asin(upper_arm.normalized().y()) * 180.0 / M_PI;
    lowest_deg = std::min(lowest_deg, elevation_deg);
    highest_deg = std::max(highest_deg, elevation_deg);
  }
  std::cout << "left upper arm elevation from " << lowest_deg << " to " << highest_deg
            << " degrees\n";
  EXPECT_LT(lowest_deg, -60.0);  // degrees
  EXPECT_GT(highest_deg, 60.0);  // degrees
}

TEST(MakeBuiltinMotion, SquatLowersPelvis) {
  auto motion = MakeBuiltinMotion("squat", 4.0, kFps);
  ASSERT_TRUE(motion.ok()) << motion.status();
  double low = 1e9, high = -1e9;
  for (int f = 0; f < motion->num_frames(); ++f) {
    const double y = JointAt(*motion, f, J::kSpineBase).y();
    low = std::min(low, y);
    high = std::max(high, y);
  }
  std::cout << "SpineBase from " << high << " m down to " << low << " m\n";
  EXPECT_GT(high - low, 0.25);  // m
}

TEST(MakeBuiltinMotion, FrontKickRaisesRightFootOnly) {
  auto motion = MakeBuiltinMotion("front-kick", 3.0, kFps);
  ASSERT_TRUE(motion.ok()) << motion.status();
  double right_high = -1e9, left_high = -1e9;
  for (int f = 0; f < motion->num_frames(); ++f) {
    right_high = std::max(right_high, JointAt(*motion, f, J::kFootRight).y());
    left_high = std::max(left_high, JointAt(*motion, f, J::kFootLeft).y());
  }
  std::cout << "highest right foot " << right_high << " m, highest left foot " << left_high
            << " m\n";
  EXPECT_GT(right_high, 0.5);  // m
  EXPECT_LT(left_high, 0.05);  // m
}

TEST(MakeBuiltinMotion, UnknownNameIsNotFoundListingNames) {
  auto motion = MakeBuiltinMotion("moonwalk");
  ASSERT_EQ(motion.status().code(), absl::StatusCode::kNotFound) << motion.status();
  for (const std::string& name : BuiltinMotionNames()) {
    EXPECT_NE(motion.status().message().find(name), std::string::npos) << motion.status();
  }
}

}  // namespace

// Retargeted onto the procedural body, every bone of a built-in motion points
// where the motion's bone points (the synthetic teacher's ground truth is
// the posed body's joints).
TEST(MakeBuiltinMotion, RetargetedOntoTheProceduralBodyEveryBonePointsAsInTheMotion) {
  auto model = body::BuildProceduralBody();
  ASSERT_TRUE(model.ok()) << model.status();
  const Eigen::VectorXd shape = Eigen::VectorXd::Zero(model->num_shape_components());
  for (const std::string& name : BuiltinMotionNames()) {
    auto motion = MakeBuiltinMotion(name, 4.0, kFps);
    ASSERT_TRUE(motion.ok()) << name << ": " << motion.status();
    auto retargeted = body::RetargetMotion(*motion, *model, shape);
    ASSERT_TRUE(retargeted.ok()) << name << ": " << retargeted.status();
    double worst_deg = 0.0;
    std::string worst_bone;
    for (int f = 0; f < motion->num_frames(); f += 5) {
      auto posed = body::PoseBody(*model, retargeted->poses[f], shape);
      ASSERT_TRUE(posed.ok()) << posed.status();
      const body::SkeletonPose truth = motion->CanonicalPose(f);
      for (int j = 1; j < body::kNumKinectV2Joints; ++j) {
        const auto parent = body::KinectV2Parent(static_cast<J>(j));
        const int p = body::Index(*parent);
        const Eigen::Vector3d a = truth.position_m[j] - truth.position_m[p];
        const Eigen::Vector3d b = posed->joints_m[j] - posed->joints_m[p];
        if (a.norm() < 0.03 || b.norm() < 0.03) continue;
        const double deg =
            std::acos(std::clamp(a.normalized().dot(b.normalized()), -1.0, 1.0)) * 180.0 / M_PI;
        if (deg > worst_deg) {
          worst_deg = deg;
          worst_bone = std::string(body::KinectV2JointName(static_cast<J>(j)));
        }
      }
    }
    std::cout << name << ": worst bone direction off by " << worst_deg << " deg (" << worst_bone
              << ")\n";
    EXPECT_LT(worst_deg, 30.0) << name << " " << worst_bone;  // degrees
  }
}

}  // namespace reenact::synth
