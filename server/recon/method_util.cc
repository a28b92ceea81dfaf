#include "server/recon/method_util.h"

#include <algorithm>
#include <cmath>

#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "common/io/proto_convert.h"

namespace reenact::recon {

StageProgress::StageProgress(const ProgressCallback& callback,
                             std::vector<std::pair<std::string, double>> stages)
    : callback_(callback), stages_(std::move(stages)) {
  for (const auto& [name, weight] : stages_) total_weight_ += std::max(weight, 0.0);
}

double StageProgress::StageStart(const std::string& stage, double* weight) const {
  double start = 0.0;
  *weight = 0.0;
  for (const auto& [name, w] : stages_) {
    if (name == stage) {
      *weight = std::max(w, 0.0);
      break;
    }
    start += std::max(w, 0.0);
  }
  return start;
}

absl::Status StageProgress::Report(const std::string& stage, int64_t done, int64_t total) const {
  if (!callback_) return absl::OkStatus();
  double weight = 0.0;
  const double start = StageStart(stage, &weight);
  const double within = total > 0 ? std::clamp(static_cast<double>(done) / total, 0.0, 1.0) : 0.0;
  Progress p;
  p.stage = stage;
  p.fraction =
      total_weight_ > 0 ? std::clamp((start + weight * within) / total_weight_, 0.0, 1.0) : 0.0;
  p.items_done = done;
  p.items_total = total;
  if (!callback_(p)) return absl::CancelledError(absl::StrCat("cancelled during ", stage));
  return absl::OkStatus();
}

ProgressCallback StageProgress::ForStage(const std::string& stage) const {
  if (!callback_) return {};
  return [this, stage](const Progress& inner) {
    double weight = 0.0;
    const double start = StageStart(stage, &weight);
    Progress p = inner;
    p.stage = stage;
    p.fraction =
        total_weight_ > 0
            ? std::clamp((start + weight * std::clamp(inner.fraction, 0.0, 1.0)) / total_weight_,
                         0.0, 1.0)
            : 0.0;
    return callback_(p);
  };
}

reenact::PartPose ReenactmentPartPose(const PartPose& pose, double scale) {
  reenact::PartPose out;
  if (!pose.valid || !pose.world_from_part.matrix().allFinite() || !(scale > 0) ||
      !std::isfinite(scale)) {
    return out;  // Identity, scale 1, not valid.
  }
  // The rotation re-orthonormalised through a unit quaternion, and the scale
  // at the file's precision (float32), so that what is drawn here is what a
  // reader of the file draws.
  const Eigen::Quaterniond q = Eigen::Quaterniond(pose.world_from_part.linear()).normalized();
  out.world_from_part.linear() = q.toRotationMatrix();
  out.world_from_part.translation() = pose.world_from_part.translation();
  out.scale = static_cast<float>(scale);
  out.valid = true;
  return out;
}

ReenactmentFrame MakePartFrame(int frame_index, int64_t stamp_ns, const PartPoses& poses,
                               const std::array<double, kNumBodyParts>& scales,
                               const JointArray& joints_in_world_m) {
  ReenactmentFrame frame;
  frame.frame_index = frame_index;
  frame.stamp_ns = stamp_ns;
  for (int p = 0; p < kNumBodyParts; ++p) {
    frame.parts.push_back(ReenactmentPartPose(poses[p], scales[p]));
  }
  const bool any = std::any_of(joints_in_world_m.begin(), joints_in_world_m.end(),
                               [](const Eigen::Vector3d& j) { return IsJointValid(j); });
  if (!any) return frame;
  for (int j = 0; j < body::kNumKinectV2Joints; ++j) {
    // Walk up the Kinect v2 tree to the nearest present joint; failing that
    // (a present joint only below this one), the first present joint.
    std::optional<body::KinectV2Joint> joint = static_cast<body::KinectV2Joint>(j);
    while (joint && !IsJointValid(joints_in_world_m[body::Index(*joint)])) {
      joint = body::KinectV2Parent(*joint);
    }
    Eigen::Vector3d p;
    if (joint) {
      p = joints_in_world_m[body::Index(*joint)];
    } else {
      p = *std::find_if(joints_in_world_m.begin(), joints_in_world_m.end(),
                        [](const Eigen::Vector3d& v) { return IsJointValid(v); });
    }
    frame.joints_in_world_m.push_back(p);
  }
  return frame;
}

}  // namespace reenact::recon
