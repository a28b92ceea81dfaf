// Training of the body tracker's forest (body_part_forest.h) on synthesised
// images (training_data.h), after Shotton et al., CVPR 2011, sec. 3.4: each
// tree grows depth first; at a node, `features_per_node` random feature
// offsets and `thresholds_per_feature` thresholds are tried and the split
// with the largest information gain over body parts (Eq. 3-4) is kept.
// Leaves keep P(part) and, per joint, the mode of the offsets from the
// leaf's pixels to the joint (Girshick et al., ICCV 2011, sec. 3.1: offsets
// farther than `vote_radius_m` are left out; the mode is found by mean shift
// from their mean). Departure: the split is chosen on at most
// `max_samples_per_split` of a node's pixels (then all are partitioned), which
// keeps the deep nodes exact and the top ones affordable on two cores.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "common/base/progress.h"
#include "common/tracking/body_part_forest.h"
#include "common/tracking/training_data.h"

namespace reenact::tracking {

struct ForestTrainingOptions {
  int num_trees = 3;
  int max_depth = 20;
  int min_samples_leaf = 8;     // A node with fewer samples becomes a leaf.
  int pixels_per_image = 1000;  // Training pixels drawn from each image's person.
  int features_per_node = 200;
  int thresholds_per_feature = 16;
  int max_samples_per_split = 12000;
  double max_offset_m = 0.6;       // Feature offsets drawn in [-max, max]^2 metres.
  double unary_fraction = 0.25;    // Features comparing one probe with the pixel itself.
  double vote_radius_m = 0.6;      // Joints farther from a pixel get no vote from it.
  double vote_bandwidth_m = 0.05;  // Mean-shift bandwidth of the leaf's offset mode.
  int threads = 0;                 // Trees trained in parallel; 0: one per core.
  uint64_t seed = 1;

  absl::Status Validate() const;
};

struct ForestTrainingSummary {
  int64_t samples = 0;  // Training pixels per tree.
  int64_t nodes = 0;
  int64_t leaves = 0;
  int max_depth = 0;
  double seconds = 0;
};

// Trains a forest over `images`; `description` is stored in it. Cancelled
// when `progress` returns false.
absl::StatusOr<BodyPartForest> TrainForest(const std::vector<TrainingImage>& images,
                                           const ForestTrainingOptions& options,
                                           const std::string& description,
                                           ForestTrainingSummary* summary = nullptr,
                                           const ProgressCallback& progress = {});

}  // namespace reenact::tracking
