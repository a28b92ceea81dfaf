#include "common/tracking/tracker_evaluation.h"

#include <chrono>

#include "common/base/status_macros.h"

namespace reenact::tracking {

absl::StatusOr<TrackerEvaluation> EvaluateTracker(BodyTracker& tracker,
                                                  const std::vector<TrainingImage>& images,
                                                  bool sequence) {
  SkeletonErrorAccumulator errors;
  double seconds = 0;
  for (const TrainingImage& image : images) {
    if (image.full_depth_mm.empty()) {
      return absl::InvalidArgumentError("evaluation images need their full frames");
    }
    if (!sequence) tracker.Reset();
    const auto start = std::chrono::steady_clock::now();
    ASSIGN_OR_RETURN(std::vector<TrackedPerson> people,
                     tracker.Track(image.full_depth_mm, image.full_intrinsics, &image.full_mask));
    seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    std::array<Eigen::Vector3d, body::kNumKinectV2Joints> estimate;
    std::array<bool, body::kNumKinectV2Joints> valid{};
    if (!people.empty()) {
      for (int j = 0; j < body::kNumKinectV2Joints; ++j) {
        estimate[j] = people[0].joints[j].position_in_camera_m;
        valid[j] = people[0].joints[j].state != JointState::kNotTracked;
      }
    }
    errors.Add(estimate, valid, image.joints_in_camera_m);
  }
  TrackerEvaluation result;
  result.all = errors.Result();
  result.mean_track_ms = images.empty() ? 0 : 1000.0 * seconds / images.size();
  return result;
}

}  // namespace reenact::tracking
