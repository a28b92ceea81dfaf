#include "common/body/motion.h"

#include <algorithm>
#include <cctype>
#include <filesystem>
#include <utility>

#include "absl/strings/str_cat.h"

namespace reenact::body {

std::string_view UnitSourceName(UnitSource source) {
  switch (source) {
    case UnitSource::kGiven:
      return "given";
    case UnitSource::kAsfHeader:
      return "asf_header";
    case UnitSource::kDetectedFromStature:
      return "detected_from_stature";
  }
  return "unknown";
}

Motion::Motion(MotionInfo info, std::vector<MotionJoint> joints,
               std::vector<std::vector<Eigen::Quaterniond>> local_rotations,
               std::vector<Eigen::Vector3d> root_translations_m)
    : info_(std::move(info)),
      joints_(std::move(joints)),
      local_rotations_(std::move(local_rotations)),
      root_translations_m_(std::move(root_translations_m)) {
  canonical_to_source_.fill(-1);
  for (const JointMapping& row : JointMappingTable(info_.joint_set)) {
    for (size_t i = 0; i < joints_.size(); ++i) {
      if (joints_[i].name == row.source_name) {
        canonical_to_source_[Index(row.target)] = static_cast<int>(i);
        break;
      }
    }
  }
}

const std::vector<Eigen::Quaterniond>& Motion::local_rotations(int frame) const {
  return local_rotations_[static_cast<size_t>(frame)];
}

const Eigen::Vector3d& Motion::root_translation_m(int frame) const {
  return root_translations_m_[static_cast<size_t>(frame)];
}

// Parents precede their children in joints_ (both readers emit depth-first
// order), so one pass composes world_from_parent * parent_from_joint.
std::vector<Eigen::Isometry3d> Motion::WorldFromJoints(int frame) const {
  const std::vector<Eigen::Quaterniond>& rotations = local_rotations(frame);
  std::vector<Eigen::Isometry3d> world_from_joint(joints_.size(), Eigen::Isometry3d::Identity());
  for (size_t j = 0; j < joints_.size(); ++j) {
    Eigen::Isometry3d parent_from_joint = Eigen::Isometry3d::Identity();
    parent_from_joint.linear() = rotations[j].normalized().toRotationMatrix();
    const int parent = joints_[j].parent;
    if (parent < 0) {
      parent_from_joint.translation() = root_translation_m(frame);
      world_from_joint[j] = parent_from_joint;
    } else {
      parent_from_joint.translation() = joints_[j].offset_m;
      world_from_joint[j] = world_from_joint[static_cast<size_t>(parent)] * parent_from_joint;
    }
  }
  return world_from_joint;
}

std::vector<Eigen::Isometry3d> Motion::RestWorldFromJoints() const {
  std::vector<Eigen::Isometry3d> world_from_joint(joints_.size(), Eigen::Isometry3d::Identity());
  for (size_t j = 0; j < joints_.size(); ++j) {
    const int parent = joints_[j].parent;
    if (parent < 0) continue;
    world_from_joint[j] =
        world_from_joint[static_cast<size_t>(parent)] * Eigen::Translation3d(joints_[j].offset_m);
  }
  return world_from_joint;
}

SkeletonPose Motion::CanonicalPose(int frame) const {
  const std::vector<Eigen::Isometry3d> world_from_joint = WorldFromJoints(frame);
  SkeletonPose pose;
  for (int c = 0; c < kNumKinectV2Joints; ++c) {
    const int source = canonical_to_source_[static_cast<size_t>(c)];
    pose.valid[static_cast<size_t>(c)] = source >= 0;
    pose.position_m[static_cast<size_t>(c)] =
        source >= 0 ? Eigen::Vector3d(world_from_joint[static_cast<size_t>(source)].translation())
                    : Eigen::Vector3d::Zero();
  }
  return pose;
}

absl::StatusOr<Motion> ReadMotion(const std::string& path, const std::string& asf_path) {
  std::string extension = std::filesystem::path(path).extension().string();
  std::transform(extension.begin(), extension.end(), extension.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  if (extension == ".bvh") return ReadBvh(path);
  if (extension == ".amc") {
    if (asf_path.empty()) {
      return absl::InvalidArgumentError(
          absl::StrCat(path, ": an AMC motion needs its ASF skeleton (--asf)"));
    }
    return ReadAsfAmc(asf_path, path);
  }
  return absl::InvalidArgumentError(
      absl::StrCat(path, ": unknown motion format '", extension, "' (expected .bvh or .amc)"));
}

}  // namespace reenact::body
