// Retargeting a motion (BVH or ASF/AMC, motion.h) onto a body model: the
// model's bones are turned to point the way the motion's bones point, and the
// root travels the motion's path scaled by the ratio of leg lengths.
//
// Rest poses differ (a BVH T-pose against a model's A-pose), so rotations are
// not copied. Per canonical joint j, in parents-first order, with Q the world
// rotation of a joint's frame (rest-aligned axes, as in PoseBody):
//  - torso (SpineBase, SpineMid, SpineShoulder): Q_j = F_motion * F_model^T,
//    F an orthonormal frame from the bone up the spine and the hips line
//    (SpineBase) or shoulders line (above), so twist comes from the torso;
//  - other joints: a reference Q_ref = Q_parent * D_parent^T * D_j carrying the
//    motion's own rotation relative to its parent (D = the motion joint's world
//    rotation from its rest), then the swing taking the model's rest bone
//    direction (after Q_ref) onto the motion's bone direction: Q_j = S * Q_ref;
//  - joints the motion lacks keep their parent's rotation (local identity).
// Root: the model's root joint is placed at
//   s * (p_motion_root - (0, floor_motion_y, 0)),  s = L_model / L_motion,
// L the mean hip-knee-ankle length of both legs in the rest poses, so feet on
// the motion's floor land on the model's floor (y = 0).
#pragma once

#include <limits>
#include <vector>

#include <Eigen/Core>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "common/body/body_model.h"
#include "common/body/motion.h"

namespace reenact::body {

struct RetargetOptions {
  // Height of the motion's floor in the motion's world frame, metres. NaN:
  // estimate it as the lowest ankle joint over the clip, less the model's
  // rest ankle height divided by the scale s.
  double motion_floor_y_m = std::numeric_limits<double>::quiet_NaN();
  // Frames between samples when estimating the floor (>= 1).
  int floor_sample_stride = 4;
  // Carry the motion's joint rotations (twist about the bones) into the
  // model; false leaves only the minimal swing along the chain.
  bool twist_from_motion = true;

  // InvalidArgument naming the bad field.
  absl::Status Validate() const;
};

// The whole-clip result.
struct RetargetedMotion {
  std::vector<BodyPose> poses;    // One per motion frame.
  double fps = 0.0;               // The motion's frame rate.
  double scale = 1.0;             // s = model leg length / motion leg length.
  double motion_floor_y_m = 0.0;  // The floor used, motion frame, metres.
};

// Pose of `model` (with shape coefficients `shape`) reproducing frame `frame`
// of `motion`. OutOfRange for a bad frame; FailedPrecondition when the motion
// or the model lacks legs (hip, knee, ankle on both sides) to scale by.
absl::StatusOr<BodyPose> RetargetFrame(const Motion& motion, int frame, const BodyModel& model,
                                       const Eigen::VectorXd& shape,
                                       const RetargetOptions& options = {});

// Every frame of `motion`, sharing one scale and floor estimate.
absl::StatusOr<RetargetedMotion> RetargetMotion(const Motion& motion, const BodyModel& model,
                                                const Eigen::VectorXd& shape,
                                                const RetargetOptions& options = {});

}  // namespace reenact::body
