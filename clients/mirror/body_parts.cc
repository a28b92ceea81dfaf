#include "clients/mirror/body_parts.h"

#include <cmath>

#include <Eigen/Geometry>

namespace reenact::mirror {
namespace {

using body::KinectV2Joint;

constexpr double kMinBoneLengthM = 0.01;
// sin(3 degrees): the hip line must be at least this far from the spine axis.
constexpr double kMinHipSine = 0.05;

struct PartEntry {
  std::string_view name;
  PartBone bone;
};

constexpr std::array<PartEntry, kNumBodyParts> kParts = {{
    {"head", {KinectV2Joint::kNeck, KinectV2Joint::kHead}},
    {"left_shoulder", {KinectV2Joint::kSpineShoulder, KinectV2Joint::kShoulderLeft}},
    {"right_shoulder", {KinectV2Joint::kSpineShoulder, KinectV2Joint::kShoulderRight}},
    {"left_upper_arm", {KinectV2Joint::kShoulderLeft, KinectV2Joint::kElbowLeft}},
    {"right_upper_arm", {KinectV2Joint::kShoulderRight, KinectV2Joint::kElbowRight}},
    {"left_lower_arm", {KinectV2Joint::kElbowLeft, KinectV2Joint::kWristLeft}},
    {"right_lower_arm", {KinectV2Joint::kElbowRight, KinectV2Joint::kWristRight}},
    {"torso", {KinectV2Joint::kSpineMid, KinectV2Joint::kSpineShoulder}},
    {"abdomen", {KinectV2Joint::kSpineBase, KinectV2Joint::kSpineMid}},
    {"left_upper_leg", {KinectV2Joint::kHipLeft, KinectV2Joint::kKneeLeft}},
    {"right_upper_leg", {KinectV2Joint::kHipRight, KinectV2Joint::kKneeRight}},
    {"left_lower_leg", {KinectV2Joint::kKneeLeft, KinectV2Joint::kAnkleLeft}},
    {"right_lower_leg", {KinectV2Joint::kKneeRight, KinectV2Joint::kAnkleRight}},
}};

const Eigen::Vector3d& At(const body::SkeletonPose& pose, KinectV2Joint joint) {
  return pose.position_m[body::Index(joint)];
}

}  // namespace

PartBone BodyPartBone(BodyPart part) { return kParts[Index(part)].bone; }

std::string_view BodyPartName(BodyPart part) { return kParts[Index(part)].name; }

bool IsJointUsable(const body::SkeletonPose& pose, KinectV2Joint joint) {
  const int j = body::Index(joint);
  return pose.valid[j] && pose.position_m[j].allFinite();
}

std::optional<Eigen::Matrix3d> SpineFrame(const body::SkeletonPose& pose) {
  for (KinectV2Joint j : {KinectV2Joint::kSpineBase, KinectV2Joint::kSpineShoulder,
                          KinectV2Joint::kHipLeft, KinectV2Joint::kHipRight}) {
    if (!IsJointUsable(pose, j)) return std::nullopt;
  }
  const Eigen::Vector3d spine =
      At(pose, KinectV2Joint::kSpineShoulder) - At(pose, KinectV2Joint::kSpineBase);
  if (spine.norm() < kMinBoneLengthM) return std::nullopt;
  const Eigen::Vector3d up = spine.normalized();
  const Eigen::Vector3d hips =
      At(pose, KinectV2Joint::kHipLeft) - At(pose, KinectV2Joint::kHipRight);
  const Eigen::Vector3d across = hips - hips.dot(up) * up;  // Gram-Schmidt.
  if (hips.norm() < kMinBoneLengthM || across.norm() < kMinHipSine * hips.norm()) {
    return std::nullopt;
  }
  const Eigen::Vector3d left = across.normalized();
  Eigen::Matrix3d frame_from_spine;
  frame_from_spine.col(0) = left;
  frame_from_spine.col(1) = up;
  frame_from_spine.col(2) = left.cross(up);  // Forward, out of the chest.
  return frame_from_spine;
}

PerPart<Eigen::Vector3d> PartDirectionsInSpine(const body::SkeletonPose& pose) {
  PerPart<Eigen::Vector3d> directions;
  const std::optional<Eigen::Matrix3d> frame_from_spine = SpineFrame(pose);
  if (!frame_from_spine) return directions;
  const Eigen::Matrix3d spine_from_frame = frame_from_spine->transpose();
  for (int p = 0; p < kNumBodyParts; ++p) {
    const PartBone bone = kParts[p].bone;
    if (!IsJointUsable(pose, bone.from) || !IsJointUsable(pose, bone.to)) continue;
    const Eigen::Vector3d vector_in_frame = At(pose, bone.to) - At(pose, bone.from);
    if (vector_in_frame.norm() < 1e-6) continue;
    directions[p] = spine_from_frame * vector_in_frame.normalized();
  }
  return directions;
}

}  // namespace reenact::mirror
