// Test support for the mirror tests: the teacher from real CMU mocap and
// learners made from it by known changes.
#pragma once

#include <cmath>
#include <numbers>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <Eigen/Core>
#include <Eigen/Geometry>

#include "clients/mirror/facing.h"
#include "common/body/joint_set.h"
#include "common/body/motion.h"
#include "common/testing/test_data.h"

namespace reenact::mirror::testing {

using body::KinectV2Joint;
using body::SkeletonPose;

inline constexpr double kRadPerDeg = std::numbers::pi / 180.0;

inline std::string CmuClipPath() { return reenact::testing::TestDataPath("mocap/cmu/131_01.bvh"); }

// Canonical poses of CMU 131_01 (a dance, 120 fps in the file), every
// `step`-th frame, at most `max_frames` frames; empty when the file is
// missing or unreadable (the test then fails on REENACT_REQUIRE_TEST_FILE).
inline std::vector<SkeletonPose> LoadCmuTeacher(int step, int max_frames = 1 << 30) {
  std::vector<SkeletonPose> poses;
  absl::StatusOr<body::Motion> motion = body::ReadBvh(CmuClipPath());
  if (!motion.ok()) return poses;
  for (int f = 0; f < motion->num_frames() && static_cast<int>(poses.size()) < max_frames;
       f += step) {
    poses.push_back(motion->CanonicalPose(f));
  }
  return poses;
}

inline const Eigen::Vector3d& Joint(const SkeletonPose& pose, KinectV2Joint joint) {
  return pose.position_m[body::Index(joint)];
}

// The pose rotated by `yaw_deg` about world +Y (counter-clockwise seen from
// above, the person turning to their own left) through its SpineBase.
inline SkeletonPose TurnAboutSpineBase(const SkeletonPose& pose, double yaw_deg) {
  const Eigen::Vector3d pivot = Joint(pose, KinectV2Joint::kSpineBase);
  const Eigen::Isometry3d turn = Eigen::Translation3d(pivot) *
                                 Eigen::AngleAxisd(yaw_deg * kRadPerDeg, Eigen::Vector3d::UnitY()) *
                                 Eigen::Translation3d(-pivot);
  return TransformPose(turn, pose);
}

// A level sensor 2.5 m in front of `pose` (facing it) at 1.0 m height:
// sensor_from_world.
inline Eigen::Isometry3d SensorInFrontOf(const SkeletonPose& pose_in_world) {
  const double facing_deg = FacingYawInWorldDeg(pose_in_world).value_or(0.0);
  Eigen::Vector3d target = Joint(pose_in_world, KinectV2Joint::kSpineBase);
  target.y() = 1.0;
  return PlaceVirtualCamera(target, facing_deg, 2.5, 1.0)->inverse();
}

// The teacher's facing yaw relative to a camera (world_from_camera, OpenCV
// convention), read the way a learner's is relative to the sensor; 1e9 when
// it cannot be read.
inline double FacingRelativeToCamera(const SkeletonPose& teacher_in_world,
                                     const Eigen::Isometry3d& world_from_camera) {
  const Eigen::Isometry3d camera_from_world = world_from_camera.inverse();
  return FacingYawInSensorDeg(TransformPose(camera_from_world, teacher_in_world),
                              camera_from_world.linear() * Eigen::Vector3d::UnitY())
      .value_or(1e9);
}

// True when `joint` is `ancestor` or lies below it in the Kinect v2 tree.
inline bool IsAtOrBelow(KinectV2Joint joint, KinectV2Joint ancestor) {
  for (std::optional<KinectV2Joint> j = joint; j; j = body::KinectV2Parent(*j)) {
    if (*j == ancestor) return true;
  }
  return false;
}

// The right wrist and everything beyond it rotated about the right elbow by
// `angle_deg` about an axis perpendicular to the forearm.
inline SkeletonPose TurnRightForearm(const SkeletonPose& pose, double angle_deg) {
  const Eigen::Vector3d elbow = Joint(pose, KinectV2Joint::kElbowRight);
  const Eigen::Vector3d forearm = Joint(pose, KinectV2Joint::kWristRight) - elbow;
  Eigen::Vector3d axis = forearm.cross(Eigen::Vector3d::UnitY());
  if (axis.norm() < 1e-3 * forearm.norm()) axis = forearm.cross(Eigen::Vector3d::UnitX());
  const Eigen::AngleAxisd rotation(angle_deg * kRadPerDeg, axis.normalized());
  SkeletonPose turned = pose;
  for (int j = 0; j < body::kNumKinectV2Joints; ++j) {
    if (!IsAtOrBelow(static_cast<KinectV2Joint>(j), KinectV2Joint::kWristRight)) continue;
    turned.position_m[j] = elbow + rotation * (pose.position_m[j] - elbow);
  }
  return turned;
}

// Every bone (joint minus parent) scaled by scale[j] of its child joint.
inline SkeletonPose ScaleBones(const SkeletonPose& pose,
                               const std::array<double, body::kNumKinectV2Joints>& scale) {
  SkeletonPose scaled = pose;
  std::array<bool, body::kNumKinectV2Joints> done{};
  auto place = [&](auto&& self, KinectV2Joint joint) -> void {
    const int j = body::Index(joint);
    if (done[j]) return;
    done[j] = true;
    const std::optional<KinectV2Joint> parent = body::KinectV2Parent(joint);
    if (!parent) return;
    self(self, *parent);
    const int p = body::Index(*parent);
    scaled.position_m[j] =
        scaled.position_m[p] + scale[j] * (pose.position_m[j] - pose.position_m[p]);
  };
  for (int j = 0; j < body::kNumKinectV2Joints; ++j) place(place, static_cast<KinectV2Joint>(j));
  return scaled;
}

}  // namespace reenact::mirror::testing
