#include "server/recon/body_parts.h"

#include <cmath>
#include <set>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

namespace reenact::recon {
namespace {

using body::KinectV2Joint;
using Eigen::Vector3d;
using J = KinectV2Joint;
using Joints = std::array<Vector3d, body::kNumKinectV2Joints>;

// A T-pose skeleton facing world +Z (left = +X), metres.
Joints TPose() {
  Joints j;
  auto set = [&](J joint, double x, double y, double z) { j[body::Index(joint)] = {x, y, z}; };
  set(J::kSpineBase, 0, 0.95, 0);
  set(J::kSpineMid, 0, 1.16, 0);
  set(J::kSpineShoulder, 0, 1.43, 0);
  set(J::kNeck, 0, 1.51, 0);
  set(J::kHead, 0, 1.64, 0.01);
  for (double side : {1.0, -1.0}) {
    const bool left = side > 0;
    set(left ? J::kShoulderLeft : J::kShoulderRight, side * 0.18, 1.43, 0);
    set(left ? J::kElbowLeft : J::kElbowRight, side * 0.50, 1.43, 0);
    set(left ? J::kWristLeft : J::kWristRight, side * 0.75, 1.43, 0);
    set(left ? J::kHandLeft : J::kHandRight, side * 0.83, 1.43, 0);
    set(left ? J::kHandTipLeft : J::kHandTipRight, side * 0.92, 1.43, 0);
    set(left ? J::kThumbLeft : J::kThumbRight, side * 0.82, 1.43, 0.05);
    set(left ? J::kHipLeft : J::kHipRight, side * 0.09, 0.93, 0);
    set(left ? J::kKneeLeft : J::kKneeRight, side * 0.10, 0.50, 0);
    set(left ? J::kAnkleLeft : J::kAnkleRight, side * 0.11, 0.07, 0);
    set(left ? J::kFootLeft : J::kFootRight, side * 0.11, 0.03, 0.15);
  }
  return j;
}

void ExpectOrthonormal(const Eigen::Isometry3d& t, const std::string& what) {
  const Eigen::Matrix3d r = t.linear();
  EXPECT_NEAR((r.transpose() * r - Eigen::Matrix3d::Identity()).norm(), 0.0, 1e-9) << what;
  EXPECT_NEAR(r.determinant(), 1.0, 1e-9) << what;
}

TEST(BodyParts, FifteenPartsInIdOrderWithUniqueNames) {
  const auto& parts = BodyParts();
  std::set<std::string> names;
  for (int i = 0; i < kNumBodyParts; ++i) {
    EXPECT_EQ(Index(parts[i].part), i);
    names.insert(std::string(parts[i].name));
    EXPECT_EQ(BodyPartFromName(parts[i].name), parts[i].part);
  }
  EXPECT_EQ(names.size(), 15u);
  EXPECT_EQ(BodyPartNames()[0], "head");
  EXPECT_EQ(BodyPartNames()[14], "foot_right");
  EXPECT_EQ(GetBodyPartInfo(BodyPart::kForearmRight).proximal, J::kElbowRight);
  EXPECT_EQ(GetBodyPartInfo(BodyPart::kForearmRight).distal, J::kWristRight);
  EXPECT_FALSE(BodyPartFromName("tail").has_value());
}

TEST(PartPosesFromJoints, FramesOrthonormalYAlongBoneLengthsRight) {
  const Joints joints = TPose();
  const PartPoses poses = PartPosesFromJoints(joints);
  for (int i = 0; i < kNumBodyParts; ++i) {
    const BodyPartInfo& info = BodyParts()[i];
    const PartPose& pose = poses[i];
    ASSERT_TRUE(pose.valid) << info.name;
    ExpectOrthonormal(pose.world_from_part, std::string(info.name));
    const Vector3d a = joints[body::Index(info.proximal)];
    const Vector3d b = joints[body::Index(info.distal)];
    EXPECT_NEAR(pose.length_m, (b - a).norm(), 1e-12) << info.name;
    // Origin at the proximal joint, the distal joint at (0, l, 0).
    EXPECT_NEAR((pose.world_from_part.translation() - a).norm(), 0.0, 1e-12) << info.name;
    const Vector3d distal_in_part = pose.world_from_part.inverse() * b;
    EXPECT_NEAR((distal_in_part - Vector3d(0, pose.length_m, 0)).norm(), 0.0, 1e-9) << info.name;
  }
  // Known lengths, metres.
  EXPECT_NEAR(poses[Index(BodyPart::kUpperArmLeft)].length_m, 0.32, 1e-9);
  EXPECT_NEAR(poses[Index(BodyPart::kForearmRight)].length_m, 0.25, 1e-9);
  EXPECT_NEAR(poses[Index(BodyPart::kChest)].length_m, 0.27, 1e-9);
  EXPECT_NEAR(poses[Index(BodyPart::kThighLeft)].length_m, std::hypot(0.01, 0.43), 1e-9);
}

TEST(PartPosesFromJoints, RestPoseAxesFollowTheHeader) {
  const PartPoses poses = PartPosesFromJoints(TPose());
  auto axis = [&](BodyPart part, int column) -> Vector3d {
    return poses[Index(part)].world_from_part.linear().col(column);
  };
  // Torso: X to the person's left (+X), Y up, Z forward (+Z).
  EXPECT_GT(axis(BodyPart::kChest, 0).x(), 0.999);
  EXPECT_GT(axis(BodyPart::kAbdomen, 2).z(), 0.999);
  EXPECT_GT(axis(BodyPart::kHead, 1).y(), 0.99);
  // Every part but the feet has Z forward in the rest pose.
  for (int i = 0; i < kNumBodyParts; ++i) {
    const auto part = static_cast<BodyPart>(i);
    if (part == BodyPart::kFootLeft || part == BodyPart::kFootRight) continue;
    EXPECT_GT(axis(part, 2).z(), 0.99) << BodyParts()[i].name;
  }
  // Arms point outward, legs down, feet forward with Z up.
  EXPECT_GT(axis(BodyPart::kUpperArmLeft, 1).x(), 0.999);
  EXPECT_LT(axis(BodyPart::kUpperArmRight, 1).x(), -0.999);
  EXPECT_LT(axis(BodyPart::kShinLeft, 1).y(), -0.99);
  EXPECT_GT(axis(BodyPart::kFootRight, 1).z(), 0.9);
  EXPECT_GT(axis(BodyPart::kFootRight, 2).y(), 0.9);
}

// Rotating the whole skeleton rotates every frame the same way.
TEST(PartPosesFromJoints, EquivariantUnderRigidMotion) {
  const Joints joints = TPose();
  const Eigen::Isometry3d motion = Eigen::Translation3d(0.3, -0.1, 2.0) *
                                   Eigen::AngleAxisd(1.1, Vector3d(0.2, 1.0, -0.3).normalized());
  Joints moved;
  for (int j = 0; j < body::kNumKinectV2Joints; ++j) moved[j] = motion * joints[j];
  const PartPoses a = PartPosesFromJoints(joints);
  const PartPoses b = PartPosesFromJoints(moved);
  for (int i = 0; i < kNumBodyParts; ++i) {
    const Eigen::Matrix4d expected = (motion * a[i].world_from_part).matrix();
    EXPECT_NEAR((expected - b[i].world_from_part.matrix()).norm(), 0.0, 1e-9)
        << BodyParts()[i].name;
  }
}

// Raising an arm from hanging to straight out sideways turns its frame
// smoothly: no twist jump where the bone crosses the shoulder line.
TEST(PartPosesFromJoints, ArmRaiseHasNoTwistJump) {
  Joints joints = TPose();
  const Vector3d shoulder = joints[body::Index(J::kShoulderLeft)];
  Eigen::Matrix3d previous;
  double max_step_deg = 0.0;
  for (int step = 0; step <= 170; ++step) {
    // From hanging (-Y) over sideways (+X) to nearly straight up (+Y).
    const double angle = (step - 90) * M_PI / 180.0;
    const Vector3d dir(std::cos(angle), std::sin(angle), 0.0);
    joints[body::Index(J::kElbowLeft)] = shoulder + 0.32 * dir;
    joints[body::Index(J::kWristLeft)] = shoulder + 0.57 * dir;
    joints[body::Index(J::kHandTipLeft)] = shoulder + 0.74 * dir;
    const PartPoses poses = PartPosesFromJoints(joints);
    const Eigen::Matrix3d r = poses[Index(BodyPart::kUpperArmLeft)].world_from_part.linear();
    if (step > 0) {
      const double step_deg = Eigen::AngleAxisd(previous.transpose() * r).angle() * 180.0 / M_PI;
      max_step_deg = std::max(max_step_deg, step_deg);
    }
    previous = r;
  }
  // The bone turns 1 degree per step; the frame may not turn more.
  EXPECT_LT(max_step_deg, 1.0 + 1e-6);
}

TEST(PartPosesFromJoints, MissingJointsMakeOnlyTheirPartsInvalid) {
  Joints joints = TPose();
  joints[body::Index(J::kElbowLeft)] = Vector3d::Constant(std::nan(""));
  const PartPoses poses = PartPosesFromJoints(joints);
  EXPECT_FALSE(poses[Index(BodyPart::kUpperArmLeft)].valid);
  EXPECT_FALSE(poses[Index(BodyPart::kForearmLeft)].valid);
  EXPECT_TRUE(poses[Index(BodyPart::kHandLeft)].valid);
  ExpectOrthonormal(poses[Index(BodyPart::kHandLeft)].world_from_part, "hand_left");
  EXPECT_TRUE(poses[Index(BodyPart::kChest)].valid);

  Joints none;
  none.fill(Vector3d::Constant(std::nan("")));
  for (const PartPose& pose : PartPosesFromJoints(none)) EXPECT_FALSE(pose.valid);

  // Degenerate: all joints at one point.
  Joints collapsed;
  collapsed.fill(Vector3d(1, 1, 1));
  for (const PartPose& pose : PartPosesFromJoints(collapsed)) EXPECT_FALSE(pose.valid);
}

TEST(PartPosesFromJoints, ArmThroughTheChestStillGivesAFrame) {
  Joints joints = TPose();
  const Vector3d shoulder = joints[body::Index(J::kShoulderLeft)];
  // Left arm pointing exactly to the right: opposite the rest direction.
  joints[body::Index(J::kElbowLeft)] = shoulder + Vector3d(-0.32, 0, 0);
  const PartPoses poses = PartPosesFromJoints(joints);
  ASSERT_TRUE(poses[Index(BodyPart::kUpperArmLeft)].valid);
  ExpectOrthonormal(poses[Index(BodyPart::kUpperArmLeft)].world_from_part, "upper_arm_left");
  EXPECT_LT(poses[Index(BodyPart::kUpperArmLeft)].world_from_part.linear().col(1).x(), -0.999);
}

}  // namespace
}  // namespace reenact::recon
