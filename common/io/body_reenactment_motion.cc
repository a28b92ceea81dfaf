#include "common/io/body_reenactment_motion.h"

#include <utility>
#include <vector>

#include "absl/strings/str_cat.h"
#include "common/base/status_macros.h"
#include "common/body/body_model.h"

namespace reenact {

absl::StatusOr<body::Motion> BodyReenactmentMotion(const Reenactment& data) {
  if (!data.is_body()) {
    return absl::InvalidArgumentError(absl::StrCat("reenactment ", data.info.reenactment_id,
                                                   " (method \"", data.info.method,
                                                   "\") is not a body-model reenactment"));
  }
  RETURN_IF_ERROR(ValidateReenactment(data));
  const BodyMesh& mesh = *data.body;
  const std::array<int, body::kNumKinectV2Joints>& order = body::KinectV2JointsParentsFirst();
  std::array<int, body::kNumKinectV2Joints> position{};  // Kinect v2 id -> Motion joint.
  std::vector<body::MotionJoint> joints;
  for (int j : order) {
    const auto joint = static_cast<body::KinectV2Joint>(j);
    body::MotionJoint motion_joint;
    motion_joint.name = std::string(body::KinectV2JointName(joint));
    if (const auto parent = body::KinectV2Parent(joint); parent.has_value()) {
      motion_joint.parent = position[Index(*parent)];
      motion_joint.offset_m = mesh.rest_joints_m[j] - mesh.rest_joints_m[Index(*parent)];
    }
    position[j] = static_cast<int>(joints.size());
    joints.push_back(std::move(motion_joint));
  }
  std::vector<std::vector<Eigen::Quaterniond>> rotations;
  std::vector<Eigen::Vector3d> root_translations_m;
  for (const ReenactmentFrame& frame : data.frames) {
    const body::BodyPose& pose = frame.body->pose;  // Every frame has one (validated).
    std::vector<Eigen::Quaterniond>& local = rotations.emplace_back(joints.size());
    for (int j = 0; j < body::kNumKinectV2Joints; ++j) local[position[j]] = pose.local_rotation[j];
    root_translations_m.push_back(mesh.rest_joints_m[Index(body::KinectV2Joint::kSpineBase)] +
                                  pose.root_translation_m);
  }
  body::MotionInfo info;
  info.path = data.info.reenactment_id;
  info.format = "reenactment";
  info.num_frames = static_cast<int>(data.frames.size());
  info.fps = data.info.fps > 0 ? data.info.fps : 30.0;
  info.joint_set = body::JointSetId::kKinectV2;
  return body::Motion(std::move(info), std::move(joints), std::move(rotations),
                      std::move(root_translations_m));
}

}  // namespace reenact
