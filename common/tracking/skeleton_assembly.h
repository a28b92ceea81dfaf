// Assembling one skeleton from the forest's per-joint vote modes.
//
// The forest's votes for a joint often gather in more than one place: the
// left knee's votes split between both knees when the person might face
// either way (depth alone barely tells front from back), and a knee raised
// towards the camera gets fewer votes than the standing one. Taking each
// joint's densest mode on its own then gives skeletons with one knee
// counted twice, or with the arms' shoulders from one side and hands from
// the other.
//
// Our departure from Shotton et al. and Girshick et al. (who keep the
// densest mode per joint): each limb pair (both legs, both arms) is chosen
// jointly, level by level from the torso outwards (hip, knee, ankle, foot;
// shoulder, elbow, wrist, hand, hand tip and thumb), among the densest
// modes of the left and the right joint alike, by dynamic programming over
// the levels. A choice scores
//   + vote_weight * (share of the left joint's votes near the left pick
//                    + share of the right joint's votes near the right pick)
//   - sum over bones of rho(((|child - parent| - L) / (bone_sigma * L))^2)
//   - crossing_penalty   where a left knee, ankle or elbow lies right of its
//                        partner (against the lateral axis of the level above)
//   - coincide_penalty   where both picks are one place (closer than
//                        min_pair_distance_m)
//   - sum over joints of rho((|pick - previous| / temporal_sigma_m)^2)
// with rho(s) = min(s, cap) and L the bone's length scaled to the person's
// torso (SpineBase to SpineShoulder). The hips' and the shoulders' left and
// right are tied by a twist term: the hip line and the shoulder line point
// the same way unless the person turns the torso by more than 90 degrees.
#pragma once

#include <array>
#include <functional>
#include <vector>

#include <Eigen/Core>

#include "absl/status/status.h"
#include "common/body/joint_set.h"
#include "common/tracking/tracking_types.h"

namespace reenact::tracking {

// One mode of a joint's votes: where, and the share of the joint's vote
// weight near it (Girshick's density over the total, in [0, 1]).
struct JointMode {
  Eigen::Vector3f position_m = Eigen::Vector3f::Zero();
  float share = 0.0f;
};

struct SkeletonAssemblyOptions {
  double vote_weight = 4.0;
  // Relative standard deviation of bone lengths.
  double bone_sigma = 0.25;
  double crossing_penalty = 3.0;
  double min_pair_distance_m = 0.08;
  double coincide_penalty = 2.0;
  double temporal_sigma_m = 0.15;
  double twist_penalty = 4.0;
  // A pick whose bone length is off by more than this many sigmas is
  // replaced by the straight continuation of its parent's bone.
  double extrapolate_sigmas = 2.0;
  // Cap of every squared term (one bad term cannot outweigh all others).
  double cap = 6.0;
  // Modes closer than this are one candidate, metres.
  double merge_distance_m = 0.05;

  absl::Status Validate() const;
};

// Modes per joint (densest first; empty: the forest gave no votes) and the
// share of joint j's votes near a point (the density the modes came from).
struct JointEvidence {
  std::array<std::vector<JointMode>, body::kNumKinectV2Joints> modes;
  std::function<float(int joint, const Eigen::Vector3f& point)> share_at;
};

// The assembled joints in the camera frame: positions and confidences (the
// share of the joint's own votes near its pick); states are kInferred for
// joints with a position, kNotTracked for joints with no votes. `previous`
// is the same person's skeleton in the frame before, when known.
std::array<TrackedJoint, body::kNumKinectV2Joints> AssembleSkeleton(
    const JointEvidence& evidence,
    const std::array<TrackedJoint, body::kNumKinectV2Joints>* previous,
    const SkeletonAssemblyOptions& options = {});

}  // namespace reenact::tracking
