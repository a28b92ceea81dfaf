#include "common/body/motion.h"

#include <algorithm>
#include <cctype>
#include <filesystem>
#include <utility>

#include "absl/strings/str_cat.h"
#include "common/base/status_macros.h"

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
  const int n = static_cast<int>(joints_.size());
  std::vector<bool> placed(joints_.size(), false);
  for (bool progress = true; progress;) {
    progress = false;
    for (int j = 0; j < n; ++j) {
      const int parent = joints_[j].parent;
      if (placed[j] || (parent >= 0 && parent < n && !placed[parent])) continue;
      parents_first_.push_back(j);
      placed[j] = progress = true;
    }
  }
  for (int j = 0; j < n; ++j) {
    if (!placed[j]) parents_first_.push_back(j);
  }
  std::vector<std::string> names;
  std::vector<int> parents;
  for (const MotionJoint& joint : joints_) {
    names.push_back(joint.name);
    parents.push_back(joint.parent);
  }
  const CanonicalSources sources =
      ResolveJointSet(info_.joint_set, info_.joint_map, names, parents);
  for (size_t c = 0; c < sources.size(); ++c) {
    canonical_to_source_[c] = sources[c].joint;
    canonical_in_source_m_[c].setZero();
    if (sources[c].toward >= 0) {
      canonical_in_source_m_[c] =
          sources[c].fraction * joints_[static_cast<size_t>(sources[c].toward)].offset_m;
    }
  }
}

const std::vector<Eigen::Quaterniond>& Motion::local_rotations(int frame) const {
  return local_rotations_[static_cast<size_t>(frame)];
}

const Eigen::Vector3d& Motion::root_translation_m(int frame) const {
  return root_translations_m_[static_cast<size_t>(frame)];
}

// One pass in parents-first order composes world_from_parent *
// parent_from_joint.
std::vector<Eigen::Isometry3d> Motion::WorldFromJoints(int frame) const {
  const std::vector<Eigen::Quaterniond>& rotations = local_rotations(frame);
  std::vector<Eigen::Isometry3d> world_from_joint(joints_.size(), Eigen::Isometry3d::Identity());
  for (int j : parents_first_) {
    Eigen::Isometry3d parent_from_joint = Eigen::Isometry3d::Identity();
    parent_from_joint.linear() = rotations[j].normalized().toRotationMatrix();
    const int parent = joints_[j].parent;
    if (parent < 0 || parent >= static_cast<int>(joints_.size())) {
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
  for (int j : parents_first_) {
    const int parent = joints_[j].parent;
    if (parent < 0 || parent >= static_cast<int>(joints_.size())) continue;
    world_from_joint[j] =
        world_from_joint[static_cast<size_t>(parent)] * Eigen::Translation3d(joints_[j].offset_m);
  }
  return world_from_joint;
}

SkeletonPose Motion::CanonicalPose(int frame) const {
  return CanonicalPoseFrom(WorldFromJoints(frame));
}

SkeletonPose Motion::CanonicalPoseFrom(
    const std::vector<Eigen::Isometry3d>& world_from_joint) const {
  SkeletonPose pose;
  for (size_t c = 0; c < canonical_to_source_.size(); ++c) {
    const int source = canonical_to_source_[c];
    pose.valid[c] = source >= 0;
    pose.position_m[c] = source >= 0
                             ? Eigen::Vector3d(world_from_joint[static_cast<size_t>(source)] *
                                               canonical_in_source_m_[c])
                             : Eigen::Vector3d::Zero();
  }
  return pose;
}

absl::StatusOr<Motion> ReadMotion(const std::string& path, const std::string& asf_path) {
  return ReadMotion(path, MotionReadOptions{.asf_path = asf_path});
}

absl::Status MotionReadOptions::Validate() const {
  if (!(metres_per_unit <= kMaxMetresPerUnit)) {
    return absl::InvalidArgumentError(
        absl::StrCat("metres per unit must be a finite length of at most ", kMaxMetresPerUnit,
                     " m, got ", metres_per_unit));
  }
  return absl::OkStatus();
}

absl::StatusOr<Motion> ReadMotion(const std::string& path, const MotionReadOptions& options) {
  RETURN_IF_ERROR(options.Validate());
  std::string extension = std::filesystem::path(path).extension().string();
  std::transform(extension.begin(), extension.end(), extension.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  if (extension == ".bvh") {
    return ReadBvh(path,
                   {.metres_per_unit = options.metres_per_unit, .joint_map = options.joint_map});
  }
  if (extension == ".amc") {
    if (options.asf_path.empty()) {
      return absl::InvalidArgumentError(
          absl::StrCat(path, ": an AMC motion needs its ASF skeleton (--asf)"));
    }
    return ReadAsfAmc(options.asf_path, path,
                      {.metres_per_unit = options.metres_per_unit, .joint_map = options.joint_map});
  }
  return absl::InvalidArgumentError(
      absl::StrCat(path, ": unknown motion format '", extension, "' (expected .bvh or .amc)"));
}

}  // namespace reenact::body
