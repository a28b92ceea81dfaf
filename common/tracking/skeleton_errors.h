// Errors of estimated skeletons against ground truth: MPJPE (mean per-joint
// position error, Ionescu et al., Human3.6M, TPAMI 2014) and PCK at a
// distance (the share of joints within it; ITOP's mAP@10cm counts the same).
#pragma once

#include <array>

#include <Eigen/Core>

#include "common/body/joint_set.h"

namespace reenact::tracking {

struct SkeletonErrors {
  int frames = 0;
  int64_t joints = 0;   // Joints compared (a missing estimate counts as a miss).
  double mpjpe_mm = 0;  // Over the joints with an estimate.
  double pck = 0;       // Share (0..1) of all compared joints within the PCK distance.
  std::array<double, body::kNumKinectV2Joints> joint_mean_mm{};  // Per joint, estimated ones.
  std::array<int64_t, body::kNumKinectV2Joints> joint_count{};
};

class SkeletonErrorAccumulator {
 public:
  explicit SkeletonErrorAccumulator(double pck_distance_m = 0.10) : pck_m_(pck_distance_m) {}

  // One frame: `valid[j]` false for a joint without an estimate (a PCK miss).
  void Add(const std::array<Eigen::Vector3d, body::kNumKinectV2Joints>& estimate,
           const std::array<bool, body::kNumKinectV2Joints>& valid,
           const std::array<Eigen::Vector3d, body::kNumKinectV2Joints>& truth);

  SkeletonErrors Result() const;

 private:
  double pck_m_;
  int frames_ = 0;
  int64_t compared_ = 0, within_ = 0;
  std::array<double, body::kNumKinectV2Joints> sum_mm_{};
  std::array<int64_t, body::kNumKinectV2Joints> count_{};
};

}  // namespace reenact::tracking
