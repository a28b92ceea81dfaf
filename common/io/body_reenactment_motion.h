// The fitted skeleton of a body-model reenactment (common/io/
// body_reenactment.h) as a body::Motion, e.g. for body::WriteBvh: motion
// capture data of what the reconstruction fitted.
#pragma once

#include "absl/status/statusor.h"
#include "common/body/motion.h"
#include "common/model/reenactment.h"

namespace reenact {

// The Motion of `data`'s BodyMesh skeleton and BodyPoses:
//   - joints: the 25 Kinect v2 joints named by body::KinectV2JointName, in
//     the Kinect v2 tree, parents first (SpineBase the root); offsets the rest
//     joint minus the parent's rest joint, metres (the root's is zero);
//   - per frame: the BodyPose's local rotations, and the root translation
//     rest SpineBase + root_translation_m (world frame, metres);
//   - frame rate: the info's fps (30 when it has none); joint set Kinect v2.
// Conventions: BVH rotations are parent_from_joint, in the parent's frame,
// with offsets in the parent's frame; the BodyPose's are in the joint's
// world-aligned rest frame (SMPL). The rest pose of a BodyMesh has every
// joint frame aligned with the world (no rest rotations), so the two
// coincide and the Motion's forward kinematics gives PoseBodyMesh's joints.
// Per-frame vertex offsets move no joint and have no place here. Poses that
// are not valid are kept as stored (the nearest fitted one).
// InvalidArgument when `data` is not a valid body-model reenactment.
absl::StatusOr<body::Motion> BodyReenactmentMotion(const Reenactment& data);

}  // namespace reenact
