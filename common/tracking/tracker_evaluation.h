// The tracker measured on synthesised frames (training_data.h with full
// frames): each frame's noisy depth and person mask go through
// BodyTracker::Track and the person's joints are compared with the truth.
#pragma once

#include <vector>

#include "absl/status/statusor.h"
#include "common/tracking/body_tracker.h"
#include "common/tracking/skeleton_errors.h"
#include "common/tracking/training_data.h"

namespace reenact::tracking {

struct TrackerEvaluation {
  SkeletonErrors all;
  double mean_track_ms = 0;  // Wall time of Track per frame (this thread).
};

// `images` must hold full frames (SynthesizeTrainingImages with
// keep_full_frames). Each frame is tracked on its own (Reset between
// frames) unless `sequence`: the images are then a take, tracked in order.
absl::StatusOr<TrackerEvaluation> EvaluateTracker(BodyTracker& tracker,
                                                  const std::vector<TrainingImage>& images,
                                                  bool sequence = false);

}  // namespace reenact::tracking
