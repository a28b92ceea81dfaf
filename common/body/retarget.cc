#include "common/body/retarget.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <optional>
#include <string>

#include <Eigen/Geometry>

#include "absl/strings/str_cat.h"
#include "common/base/status_macros.h"

namespace reenact::body {
namespace {

using J = KinectV2Joint;
using Joints = std::array<Eigen::Vector3d, kNumKinectV2Joints>;

// Shorter motion bones than this carry no usable direction.
constexpr double kMinBoneLengthM = 0.01;

// The child whose direction a joint's bone follows; nullopt for leaf joints
// and for the torso joints, which use frames instead.
std::optional<J> BoneChild(J joint) {
  switch (joint) {
    case J::kSpineBase:
      return J::kSpineMid;
    case J::kSpineMid:
      return J::kSpineShoulder;
    case J::kSpineShoulder:
      return J::kNeck;
    case J::kNeck:
      return J::kHead;
    case J::kShoulderLeft:
      return J::kElbowLeft;
    case J::kElbowLeft:
      return J::kWristLeft;
    case J::kWristLeft:
      return J::kHandLeft;
    case J::kHandLeft:
      return J::kHandTipLeft;
    case J::kShoulderRight:
      return J::kElbowRight;
    case J::kElbowRight:
      return J::kWristRight;
    case J::kWristRight:
      return J::kHandRight;
    case J::kHandRight:
      return J::kHandTipRight;
    case J::kHipLeft:
      return J::kKneeLeft;
    case J::kKneeLeft:
      return J::kAnkleLeft;
    case J::kAnkleLeft:
      return J::kFootLeft;
    case J::kHipRight:
      return J::kKneeRight;
    case J::kKneeRight:
      return J::kAnkleRight;
    case J::kAnkleRight:
      return J::kFootRight;
    default:
      return std::nullopt;
  }
}

// The lateral line (right -> left) that fixes a torso joint's twist.
std::optional<std::pair<J, J>> TorsoLateral(J joint) {
  if (joint == J::kSpineBase) return std::make_pair(J::kHipRight, J::kHipLeft);
  if (joint == J::kSpineMid || joint == J::kSpineShoulder) {
    return std::make_pair(J::kShoulderRight, J::kShoulderLeft);
  }
  return std::nullopt;
}

// Orthonormal frame [lateral, up, lateral x up] from an up vector and a
// lateral vector; nullopt when either is degenerate.
std::optional<Eigen::Matrix3d> TorsoFrame(const Eigen::Vector3d& up,
                                          const Eigen::Vector3d& lateral) {
  if (up.norm() < kMinBoneLengthM) return std::nullopt;
  const Eigen::Vector3d u = up.normalized();
  const Eigen::Vector3d l_raw = lateral - lateral.dot(u) * u;
  if (l_raw.norm() < kMinBoneLengthM) return std::nullopt;
  Eigen::Matrix3d frame;
  frame.col(0) = l_raw.normalized();
  frame.col(1) = u;
  frame.col(2) = frame.col(0).cross(u);
  return frame;
}

// What one frame of the motion says about the canonical joints.
struct MotionFrame {
  SkeletonPose pose;  // Canonical joint positions, motion world, metres.
  std::array<std::optional<Eigen::Matrix3d>, kNumKinectV2Joints> rotation;  // D_j.
};

MotionFrame ReadMotionFrame(const Motion& motion, int frame,
                            const std::vector<Eigen::Isometry3d>& rest) {
  const std::vector<Eigen::Isometry3d> world = motion.WorldFromJoints(frame);
  MotionFrame out;
  out.pose = motion.CanonicalPoseFrom(world);
  for (int c = 0; c < kNumKinectV2Joints; ++c) {
    const int source = motion.canonical_to_source()[c];
    if (source < 0) continue;
    out.rotation[c] = world[source].linear() * rest[source].linear().transpose();
  }
  return out;
}

double LegLength(const Joints& joints) {
  double sum = 0.0;
  for (auto [hip, knee, ankle] : {std::array{J::kHipLeft, J::kKneeLeft, J::kAnkleLeft},
                                  std::array{J::kHipRight, J::kKneeRight, J::kAnkleRight}}) {
    sum += (joints[Index(hip)] - joints[Index(knee)]).norm() +
           (joints[Index(knee)] - joints[Index(ankle)]).norm();
  }
  return 0.5 * sum;
}

constexpr std::array<J, 6> kLegJoints = {J::kHipLeft,  J::kKneeLeft,  J::kAnkleLeft,
                                         J::kHipRight, J::kKneeRight, J::kAnkleRight};
// Joints the floor is measured from (ankles: their height above the sole is
// alike across skeletons, unlike the toe joints').
constexpr std::array<J, 2> kSoleJoints = {J::kAnkleLeft, J::kAnkleRight};

// Everything that is the same for every frame of one retargeting.
struct Setup {
  Joints model_rest_m;
  std::vector<Eigen::Isometry3d> motion_rest;
  double scale = 1.0;
  double motion_floor_y_m = 0.0;
};

absl::StatusOr<Setup> Prepare(const Motion& motion, const BodyModel& model,
                              const Eigen::VectorXd& shape, const RetargetOptions& options) {
  RETURN_IF_ERROR(options.Validate());
  if (motion.num_frames() <= 0) {
    return absl::FailedPreconditionError(
        absl::StrCat(motion.info().path, ": motion has no frames"));
  }
  Setup setup;
  ASSIGN_OR_RETURN(setup.model_rest_m, RestJointPositions(model, shape));
  setup.motion_rest = motion.RestWorldFromJoints();
  const SkeletonPose motion_rest_pose = motion.CanonicalPoseFrom(setup.motion_rest);
  Joints motion_rest_m;
  for (J joint : kLegJoints) {
    if (!motion_rest_pose.valid[Index(joint)]) {
      return absl::FailedPreconditionError(absl::StrCat(motion.info().path, ": motion has no ",
                                                        std::string(KinectV2JointName(joint)),
                                                        " to scale by"));
    }
    motion_rest_m[Index(joint)] = motion_rest_pose.position_m[Index(joint)];
  }
  const double motion_leg_m = LegLength(motion_rest_m);
  if (!(motion_leg_m > kMinBoneLengthM)) {
    return absl::FailedPreconditionError(
        absl::StrCat(motion.info().path, ": motion legs have no length"));
  }
  setup.scale = LegLength(setup.model_rest_m) / motion_leg_m;
  if (!std::isnan(options.motion_floor_y_m)) {
    setup.motion_floor_y_m = options.motion_floor_y_m;
    return setup;
  }
  // Floor: lowest sole joint over the clip, less that joint's rest height in
  // the model brought to motion units.
  double lowest_y_m = std::numeric_limits<double>::infinity();
  J lowest_joint = J::kAnkleLeft;
  for (int f = 0; f < motion.num_frames(); f += options.floor_sample_stride) {
    const MotionFrame frame = ReadMotionFrame(motion, f, setup.motion_rest);
    for (J joint : kSoleJoints) {
      if (frame.pose.valid[Index(joint)] && frame.pose.position_m[Index(joint)].y() < lowest_y_m) {
        lowest_y_m = frame.pose.position_m[Index(joint)].y();
        lowest_joint = joint;
      }
    }
  }
  setup.motion_floor_y_m = lowest_y_m - setup.model_rest_m[Index(lowest_joint)].y() / setup.scale;
  return setup;
}

// World rotation of joint `j` of the model (see the header for the rules).
Eigen::Matrix3d TargetRotation(J joint, const Eigen::Matrix3d& parent_rotation,
                               std::optional<J> parent, const MotionFrame& frame,
                               const Joints& model_rest_m, const RetargetOptions& options) {
  const int j = Index(joint);
  const auto& valid = frame.pose.valid;
  const auto& p = frame.pose.position_m;
  if (const auto lateral = TorsoLateral(joint); lateral.has_value()) {
    const int child = Index(*BoneChild(joint));
    const int right = Index(lateral->first), left = Index(lateral->second);
    if (valid[j] && valid[child] && valid[right] && valid[left]) {
      const auto motion_frame = TorsoFrame(p[child] - p[j], p[left] - p[right]);
      const auto model_frame = TorsoFrame(model_rest_m[child] - model_rest_m[j],
                                          model_rest_m[left] - model_rest_m[right]);
      if (motion_frame && model_frame) return *motion_frame * model_frame->transpose();
    }
  }
  if (!valid[j] || !frame.rotation[j].has_value()) return parent_rotation;
  Eigen::Matrix3d reference = parent_rotation;
  if (options.twist_from_motion) {
    const bool has_parent = parent.has_value() && frame.rotation[Index(*parent)].has_value();
    reference =
        has_parent ? Eigen::Matrix3d(parent_rotation * frame.rotation[Index(*parent)]->transpose() *
                                     *frame.rotation[j])
                   : *frame.rotation[j];
  }
  const std::optional<J> child = BoneChild(joint);
  if (!child.has_value() || !valid[Index(*child)]) return reference;
  const Eigen::Vector3d target = p[Index(*child)] - p[j];
  const Eigen::Vector3d rest = model_rest_m[Index(*child)] - model_rest_m[j];
  if (target.norm() < kMinBoneLengthM || rest.norm() < 1e-9) return reference;
  // Swing from where the reference sends the model's bone onto the motion's.
  const Eigen::Quaterniond swing =
      Eigen::Quaterniond::FromTwoVectors(reference * rest.normalized(), target.normalized());
  return swing.toRotationMatrix() * reference;
}

BodyPose RetargetWithSetup(const Motion& motion, int frame_index, const Setup& setup,
                           const RetargetOptions& options) {
  const MotionFrame frame = ReadMotionFrame(motion, frame_index, setup.motion_rest);
  std::array<Eigen::Matrix3d, kNumKinectV2Joints> world_rotation;
  BodyPose pose;
  for (int j : KinectV2JointsParentsFirst()) {
    const J joint = static_cast<J>(j);
    const std::optional<J> parent = KinectV2Parent(joint);
    const Eigen::Matrix3d parent_rotation =
        parent.has_value() ? world_rotation[Index(*parent)] : Eigen::Matrix3d::Identity();
    world_rotation[j] =
        TargetRotation(joint, parent_rotation, parent, frame, setup.model_rest_m, options);
    // G_j = G_parent * [R_j | ...]: the local rotation is relative to the parent.
    pose.local_rotation[j] = Eigen::Quaterniond(parent_rotation.transpose() * world_rotation[j]);
    pose.local_rotation[j].normalize();
  }
  const int root = Index(J::kSpineBase);
  const Eigen::Vector3d motion_root_m =
      frame.pose.valid[root] ? frame.pose.position_m[root] : motion.root_translation_m(frame_index);
  const Eigen::Vector3d target_root_m =
      setup.scale * (motion_root_m - Eigen::Vector3d(0, setup.motion_floor_y_m, 0));
  pose.root_translation_m = target_root_m - setup.model_rest_m[root];
  return pose;
}

}  // namespace

absl::Status RetargetOptions::Validate() const {
  if (floor_sample_stride < 1) {
    return absl::InvalidArgumentError(absl::StrCat(
        "RetargetOptions.floor_sample_stride must be >= 1, got ", floor_sample_stride));
  }
  if (std::isinf(motion_floor_y_m)) {
    return absl::InvalidArgumentError("RetargetOptions.motion_floor_y_m must be finite or NaN");
  }
  return absl::OkStatus();
}

absl::StatusOr<BodyPose> RetargetFrame(const Motion& motion, int frame, const BodyModel& model,
                                       const Eigen::VectorXd& shape,
                                       const RetargetOptions& options) {
  if (frame < 0 || frame >= motion.num_frames()) {
    return absl::OutOfRangeError(absl::StrCat(motion.info().path, ": frame ", frame,
                                              " outside [0, ", motion.num_frames(), ")"));
  }
  ASSIGN_OR_RETURN(const Setup setup, Prepare(motion, model, shape, options));
  return RetargetWithSetup(motion, frame, setup, options);
}

absl::StatusOr<RetargetedMotion> RetargetMotion(const Motion& motion, const BodyModel& model,
                                                const Eigen::VectorXd& shape,
                                                const RetargetOptions& options) {
  ASSIGN_OR_RETURN(const Setup setup, Prepare(motion, model, shape, options));
  RetargetedMotion result;
  result.fps = motion.fps();
  result.scale = setup.scale;
  result.motion_floor_y_m = setup.motion_floor_y_m;
  result.poses.reserve(motion.num_frames());
  for (int f = 0; f < motion.num_frames(); ++f) {
    result.poses.push_back(RetargetWithSetup(motion, f, setup, options));
  }
  return result;
}

}  // namespace reenact::body
