// The 13 body parts that the magic mirror compares, and their orientations
// normalised to the spine.
//
// Thesis sec. 4.6.1: "We compare body part orientations, normalizing all
// orientations relative to the spine." The parts are the 13 of thesis
// Fig. 4.3b (head, shoulders, upper arms, lower arms, torso, abdomen, upper
// legs, lower legs), each taken as the bone between two Kinect v2 joints.
//
// Departures from the thesis, written down here:
//  - Hands and feet are left out, as in Fig. 4.3b; the Kinect hand joints
//    (HandTip, Thumb, Hand) are also too noisy to grade a learner on.
//  - A part's orientation is its bone direction only (2 degrees of freedom);
//    the twist of a limb about its own axis cannot be seen from two joints.
//
// "Left" and "right" are always the person's own (anatomical) sides, as in
// common/body/joint_set.h.
#pragma once

#include <array>
#include <optional>
#include <string_view>

#include <Eigen/Core>

#include "common/body/joint_set.h"

namespace reenact::mirror {

enum class BodyPart : int {
  kHead = 0,       // Neck -> Head.
  kLeftShoulder,   // SpineShoulder -> ShoulderLeft.
  kRightShoulder,  // SpineShoulder -> ShoulderRight.
  kLeftUpperArm,   // ShoulderLeft -> ElbowLeft.
  kRightUpperArm,  // ShoulderRight -> ElbowRight.
  kLeftLowerArm,   // ElbowLeft -> WristLeft.
  kRightLowerArm,  // ElbowRight -> WristRight.
  kTorso,          // SpineMid -> SpineShoulder.
  kAbdomen,        // SpineBase -> SpineMid.
  kLeftUpperLeg,   // HipLeft -> KneeLeft.
  kRightUpperLeg,  // HipRight -> KneeRight.
  kLeftLowerLeg,   // KneeLeft -> AnkleLeft.
  kRightLowerLeg,  // KneeRight -> AnkleRight.
};
inline constexpr int kNumBodyParts = 13;

inline constexpr int Index(BodyPart part) { return static_cast<int>(part); }
inline constexpr BodyPart BodyPartAt(int index) { return static_cast<BodyPart>(index); }

// The bone of a part: from its proximal joint to its distal joint.
struct PartBone {
  body::KinectV2Joint from;
  body::KinectV2Joint to;
};
PartBone BodyPartBone(BodyPart part);

// Snake-case name used in reports: "head", "left_shoulder", ...,
// "right_lower_arm", "torso", "abdomen", ..., "right_lower_leg".
std::string_view BodyPartName(BodyPart part);

// Per-part values (errors, directions); nullopt where a part is missing.
template <typename T>
using PerPart = std::array<std::optional<T>, kNumBodyParts>;

// True when `pose` has joint `joint` marked valid with finite coordinates.
bool IsJointUsable(const body::SkeletonPose& pose, body::KinectV2Joint joint);

// The spine frame of a skeleton, as the rotation frame_from_spine whose
// columns are the spine axes expressed in the skeleton's own frame:
//   up      = unit(SpineShoulder - SpineBase),
//   left    = unit(hip line HipRight -> HipLeft with its component along up
//             removed) (the person's left),
//   forward = left x up (points out of the chest).
// Columns in the order (left, up, forward): a right-handed frame whenever the
// skeleton's frame is right-handed (world, OpenCV camera). nullopt when one of
// the four joints is unusable or the frame is degenerate (spine shorter than
// 1 cm, or hip line within ~3 degrees of the spine).
std::optional<Eigen::Matrix3d> SpineFrame(const body::SkeletonPose& pose);

// The unit direction of each part's bone expressed in the spine frame
// (spine_from_frame * unit(to - from)). A part is missing when either of its
// joints is unusable or coincides with the other; all parts are missing when
// the spine frame is. Invariant to where the skeleton stands, how it is
// turned and how long its bones are.
PerPart<Eigen::Vector3d> PartDirectionsInSpine(const body::SkeletonPose& pose);

}  // namespace reenact::mirror
