#include "common/tracking/skeleton_errors.h"

namespace reenact::tracking {

void SkeletonErrorAccumulator::Add(
    const std::array<Eigen::Vector3d, body::kNumKinectV2Joints>& estimate,
    const std::array<bool, body::kNumKinectV2Joints>& valid,
    const std::array<Eigen::Vector3d, body::kNumKinectV2Joints>& truth) {
  ++frames_;
  for (int j = 0; j < body::kNumKinectV2Joints; ++j) {
    ++compared_;
    if (!valid[j] || !estimate[j].allFinite()) continue;
    const double error_m = (estimate[j] - truth[j]).norm();
    sum_mm_[j] += error_m * 1000.0;
    ++count_[j];
    if (error_m <= pck_m_) ++within_;
  }
}

SkeletonErrors SkeletonErrorAccumulator::Result() const {
  SkeletonErrors r;
  r.frames = frames_;
  r.joints = compared_;
  double sum = 0;
  int64_t count = 0;
  for (int j = 0; j < body::kNumKinectV2Joints; ++j) {
    r.joint_count[j] = count_[j];
    r.joint_mean_mm[j] = count_[j] > 0 ? sum_mm_[j] / count_[j] : 0;
    sum += sum_mm_[j];
    count += count_[j];
  }
  r.mpjpe_mm = count > 0 ? sum / count : 0;
  r.pck = compared_ > 0 ? static_cast<double>(within_) / compared_ : 0;
  return r;
}

}  // namespace reenact::tracking
