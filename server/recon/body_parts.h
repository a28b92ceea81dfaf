// The 15 rigid body parts of the rigid reenactment methods (thesis 3.3-3.4,
// Fig. 3.10), the Kinect v2 joints that span them, and their part frames.
//
// Part ids (the index everywhere: ReenactmentInfo.part_names, PartMesh.part,
// PartFrame.parts) and joints, proximal -> distal:
//    0 head            Neck -> Head
//    1 chest           SpineMid -> SpineShoulder
//    2 abdomen         SpineBase -> SpineMid
//    3 upper_arm_left  ShoulderLeft -> ElbowLeft
//    4 forearm_left    ElbowLeft -> WristLeft
//    5 hand_left       WristLeft -> HandTipLeft
//    6 upper_arm_right, 7 forearm_right, 8 hand_right (the same, Right)
//    9 thigh_left      HipLeft -> KneeLeft
//   10 shin_left       KneeLeft -> AnkleLeft
//   11 foot_left       AnkleLeft -> FootLeft
//   12 thigh_right, 13 shin_right, 14 foot_right (the same, Right)
//
// Part frame (world_from_part, metres): origin at the proximal joint, +Y along
// the bone toward the distal joint (for head, chest and abdomen +Y points up
// the spine). X and Z are fixed by a twist reference; on a person standing
// upright in the rest pose (arms out sideways, legs straight down, feet
// forward) facing world +Z, every part frame but the feet' has Z pointing
// forward (+Z), and X = Y x Z:
//   chest, abdomen  X = the shoulder line (chest) or hip line (abdomen), from
//                   the right joint to the left one, made orthogonal to the
//                   bone (Gram-Schmidt); so X points to the person's left,
//                   Y up, Z forward. When that line is missing or nearly
//                   parallel to the bone, the other torso line is used, then
//                   world +Z / +X.
//   head            the chest frame, swung onto the head bone (below).
//   upper arms      the chest frame, swung from the rest direction (+X of the
//                   chest for the left arm, -X for the right) onto the bone.
//   thighs          the abdomen frame, swung from -Y of the abdomen (down).
//   forearms, hands, shins: the parent limb's frame, swung from its +Y (a
//                   straight elbow, wrist or knee) onto the bone.
//   feet            the shin frame turned +90 degrees about its X axis
//                   (rest: Y forward along the foot, Z up, X as the shin's),
//                   swung from the shin's +Z onto the bone.
// "Swung" means: the parent's rest frame turned by the smallest rotation that
// takes the rest direction onto the bone (parallel transport; no twist about
// the bone is added).
//
// Departure from the brief "arms: project the chest's shoulder line
// orthogonal to the bone, legs: the hip line": a projected reference is
// undefined when the bone is parallel to it, which for the arms is the
// T-pose (arms out sideways, the very pose the representative frame of
// Eq. 3.4 looks for), and switching to a fallback there makes the part frame
// jump by up to 180 degrees about the bone between two frames. The swing
// from the parent frame is singular only when the bone points exactly
// opposite the rest direction (a left arm pointing straight through the
// chest to the right, a thigh pointing straight up, an elbow folded flat,
// a foot pointing backwards), which bodies do not do; near there (within
// ~2 degrees) the swing is a half turn about the rest frame's Z axis, so the
// function never fails.
#pragma once

#include <array>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "common/body/joint_set.h"

namespace reenact::recon {

inline constexpr int kNumBodyParts = 15;

enum class BodyPart : int {
  kHead = 0,
  kChest = 1,
  kAbdomen = 2,
  kUpperArmLeft = 3,
  kForearmLeft = 4,
  kHandLeft = 5,
  kUpperArmRight = 6,
  kForearmRight = 7,
  kHandRight = 8,
  kThighLeft = 9,
  kShinLeft = 10,
  kFootLeft = 11,
  kThighRight = 12,
  kShinRight = 13,
  kFootRight = 14,
};

inline constexpr int Index(BodyPart part) { return static_cast<int>(part); }

// What defines one part.
struct BodyPartInfo {
  BodyPart part;
  std::string_view name;           // e.g. "upper_arm_left".
  body::KinectV2Joint proximal;    // Origin of the part frame.
  body::KinectV2Joint distal;      // +Y points toward it.
  std::optional<BodyPart> parent;  // Part whose frame gives the twist (none for chest, abdomen).
};

// The 15 parts in part-id order.
const std::array<BodyPartInfo, kNumBodyParts>& BodyParts();
const BodyPartInfo& GetBodyPartInfo(BodyPart part);
// "head", "chest", ... in part-id order.
std::vector<std::string> BodyPartNames();
std::optional<BodyPart> BodyPartFromName(std::string_view name);

// The pose of one part at one instant.
struct PartPose {
  // point_in_world = world_from_part * point_in_part (rigid, metres).
  Eigen::Isometry3d world_from_part = Eigen::Isometry3d::Identity();
  // Distance between the proximal and distal joints, metres.
  double length_m = 0.0;
  // False when a joint of the part is missing (non-finite) or the bone is
  // shorter than 1 mm; world_from_part is then the identity and the part
  // should be hidden.
  bool valid = false;
};

using PartPoses = std::array<PartPose, kNumBodyParts>;

// The part frames of a Kinect v2 skeleton (25 joints in the world frame,
// metres; a joint that was not seen is NaN). Frames follow the file comment;
// a part whose parent is invalid is swung from the nearest valid ancestor's
// frame, or from world axes (X = world +X, Z = world +Z) when there is none.
PartPoses PartPosesFromJoints(
    const std::array<Eigen::Vector3d, body::kNumKinectV2Joints>& joints_in_world_m);

}  // namespace reenact::recon
