// Which learner frame is compared with which teacher frame.
//
// Thesis sec. 4.6.1 plays the reenactment while the learner performs and
// "match[es] body pose frames up one to one". That stays the default: the
// session pairs each learner frame with the teacher frame on screen at its
// stamp, and AlignOneToOne pairs two sequences index by index.
//
// Departure (optional): dynamic time warping, for a learner who is ahead or
// behind the teacher. DTW finds the monotone pairing of the two whole
// sequences, anchored at both first and both last frames, with steps
// (learner+1, teacher), (learner, teacher+1) and (learner+1, teacher+1), that
// minimises the summed pose distance; the distance of a pair is the mean part
// angle of ComparePoses (degrees). A Sakoe-Chiba band keeps the pairing within
// `band_frames` learner frames of the diagonal scaled to the two lengths
// (learner index (n-1)/(m-1) * teacher index), so a learner may lead or lag by
// at most that much. DTW grades timing more leniently than one to one: a
// learner who makes the right poses at the wrong speed scores well.
#pragma once

#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "clients/mirror/body_parts.h"
#include "common/body/joint_set.h"

namespace reenact::mirror {

// One compared pair: indices into the learner's and the teacher's sequences.
struct FramePair {
  int learner_frame = 0;
  int teacher_frame = 0;
  bool operator==(const FramePair&) const = default;
};

struct DtwOptions {
  // Sakoe-Chiba band half-width in learner frames around the scaled diagonal;
  // 0 means no band. Too narrow a band for the two lengths is an error.
  int band_frames = 0;
  // Distance (degrees) of a pair where no part can be compared (a frame
  // without a skeleton), so that such frames neither attract nor block the
  // path. Must be in [0, 180].
  double missing_cost_deg = 90.0;
  // Largest learner x teacher frame product accepted (the cost table is held
  // in memory, 9 bytes a cell): 2e7 is about 180 MB.
  int64_t max_cells = 20'000'000;

  // InvalidArgument for a negative band, a cost outside [0, 180] or
  // max_cells < 1.
  absl::Status Validate() const;
};

struct Alignment {
  // The pairs in order; both indices never decrease.
  std::vector<FramePair> pairs;
  // DTW: mean pose distance (degrees) over the pairs, a pair without a
  // comparable part counting missing_cost_deg. AlignOneToOne looks at no
  // poses and leaves it 0.
  double mean_distance_deg = 0.0;
};

// Index i with index i, for i < min(num_learner_frames, num_teacher_frames)
// (mean_distance_deg 0: no poses are looked at).
Alignment AlignOneToOne(int num_learner_frames, int num_teacher_frames);

// DTW over two pose sequences (each skeleton in any right-handed frame; see
// pose_comparison.h). InvalidArgument for bad options, an empty sequence, a
// band too narrow to join the first and last pairs, or a table over
// max_cells.
absl::StatusOr<Alignment> AlignByDtw(const std::vector<body::SkeletonPose>& learner,
                                     const std::vector<body::SkeletonPose>& teacher,
                                     const DtwOptions& options = {});

// The same over part directions already computed by PartDirectionsInSpine.
absl::StatusOr<Alignment> AlignDirectionsByDtw(const std::vector<PerPart<Eigen::Vector3d>>& learner,
                                               const std::vector<PerPart<Eigen::Vector3d>>& teacher,
                                               const DtwOptions& options = {});

}  // namespace reenact::mirror
