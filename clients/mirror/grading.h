// Grading a learner's whole take against a teacher, with no window, video or
// sensor: what `reenact grade` runs for a class's recordings in a batch, and
// what the mirror's reports are made of.
//
// The comparison is the mirror's (pose_comparison.h): each part's bone
// direction in its own skeleton's spine frame, so where each person stands
// and which way they face drop out (thesis sec. 4.6.1), then DTW
// (time_alignment.h) to pair the learner's frames with the teacher's.
//
// Grade only what is seen. A learner's joint carries whether the sensor saw
// it (the tracker's TRACKED state: on a surface the camera sees) or only
// guessed it (INFERRED: hidden behind the body, outside the view). A part is
// graded in a pair only when both of its joints, and the four joints of both
// spine frames, were seen in the learner's frame and are present in the
// teacher's; otherwise the pair's part is "not seen" (with the reason) and is
// left out of every mean. The grade says how much of the body it covers
// (graded part-pairs over all part-pairs). DTW itself pairs frames on the
// parts present in both, seen or not, so that a hidden arm does not pull the
// pairing.
//
// Departures from the thesis, written down here:
//  - The thesis compares every part in every frame; a guessed part is not
//    graded here, since a tracker's guess for a hidden arm can be 0.5 m off.
//  - Frames are paired by DTW over the whole take (the thesis pairs them one
//    to one while the teacher plays); a learner at another speed is graded
//    on their poses, not their timing.
//
// Corrections in words. Each part's error over the pairs is smoothed (a
// moving mean over smoothing_s seconds of learner time); the corrections are
// the largest smoothed errors above min_correction_deg, at most one per part,
// and each is phrased from how the learner's part differs from the
// teacher's: for a lower arm or leg, by how much more or less the elbow or
// knee should bend when that explains most of the error; otherwise by the
// axis of the spine frame along which the teacher's bone points more
// ("raise", "lower", "forward", "back", "to your left", "to your right").
#pragma once

#include <array>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "clients/mirror/body_parts.h"
#include "clients/mirror/pose_comparison.h"
#include "clients/mirror/time_alignment.h"
#include "common/body/joint_set.h"

namespace reenact::mirror {

// One frame of either side of a comparison.
struct GradeFrame {
  // Seconds from the start of the sequence (non-decreasing).
  double time_s = 0.0;
  // The skeleton in any right-handed frame (pose_comparison.h); nullopt when
  // nobody was tracked.
  std::optional<body::SkeletonPose> pose;
  // Per joint: seen by the sensor (a valid joint that was only inferred is
  // false). Ignored for the teacher, whose valid joints all count.
  std::array<bool, body::kNumKinectV2Joints> seen{};
};

// Marks every valid joint of `frame.pose` as seen (for skeletons that carry
// no tracking state, such as a stored SDK skeleton or a reenactment's fit).
void MarkValidJointsSeen(GradeFrame& frame);

// Why a part of a pair is not graded.
enum class PartStatus : int {
  kGraded = 0,
  kNoLearner,      // No learner skeleton in that frame.
  kNotSeen,        // The learner's part (or spine) was inferred, not seen.
  kNoTeacherPart,  // The teacher's frame lacks the part (missing joints or frame).
};
// "graded", "no_learner", "not_seen", "no_teacher_part".
std::string_view PartStatusName(PartStatus status);

struct GradeOptions {
  // Pair frames by DTW (else one to one, index by index).
  bool use_dtw = true;
  DtwOptions dtw;
  // Width of the moving mean over the part errors for corrections, worst
  // moments and the heat map, seconds (>= 0; 0 smooths nothing).
  double smoothing_s = 0.3;
  // Corrections: at most max_corrections (0..13), each a smoothed error of
  // at least min_correction_deg.
  int max_corrections = 3;
  double min_correction_deg = 15.0;
  // Worst moments: at most max_worst_moments (>= 0), at least
  // worst_separation_s of learner time apart.
  int max_worst_moments = 3;
  double worst_separation_s = 0.5;
  // A part is reported "not graded" overall when it was graded in fewer than
  // this share of the pairs (0..1).
  double min_part_coverage = 0.2;
  // The action-weighted error weighs each graded part by how much the
  // teacher moves it (teacher_motion_deg) plus this floor (degrees, >= 0;
  // > 0 keeps a part the teacher holds still from counting for nothing).
  double motion_weight_floor_deg = 5.0;

  // InvalidArgument naming the first bad field.
  absl::Status Validate() const;
};

// One compared pair.
struct GradedPair {
  int learner_frame = 0;
  int teacher_frame = 0;
  double time_s = 0.0;  // The learner frame's time.
  // Error of each graded part (degrees); nullopt where not graded.
  PerPart<double> error_deg;
  std::array<PartStatus, kNumBodyParts> status{};
  // The same errors smoothed over time (see the top); nullopt where the
  // window holds no graded value.
  PerPart<double> smoothed_deg;
  // Mean of the graded parts; nullopt when none is graded.
  std::optional<double> mean_error_deg;
};

struct PartGrade {
  // Mean error over the pairs where the part was graded.
  std::optional<double> mean_error_deg;
  // How much the teacher moves the part: the mean angle (degrees) between
  // its direction in each teacher frame and its mean direction.
  double teacher_motion_deg = 0.0;
  int graded_pairs = 0;
  // Share of all pairs where it was graded.
  double coverage = 0.0;
  // False when coverage < min_part_coverage: the part is shown neutral.
  bool graded = false;
  // The commonest reason it was not graded (when graded is false): one of
  // PartStatusName's strings, in words for people (NotGradedReason).
  std::string not_graded_reason;
};

struct Correction {
  BodyPart part = BodyPart::kHead;
  int pair_index = 0;
  double time_s = 0.0;
  double error_deg = 0.0;  // Smoothed.
  // E.g. "left knee: bend about 20 degrees more at 1.2 s".
  std::string text;
};

struct WorstMoment {
  int pair_index = 0;
  int learner_frame = 0;
  int teacher_frame = 0;
  double time_s = 0.0;
  // The part with the largest smoothed error there, and that error.
  BodyPart part = BodyPart::kHead;
  double error_deg = 0.0;
};

struct Grade {
  std::vector<GradedPair> pairs;
  bool used_dtw = false;
  std::array<PartGrade, kNumBodyParts> parts;
  // Mean over the graded part-pairs of the parts that are graded overall
  // (each part weighted by its graded pairs); nullopt when nothing is.
  std::optional<double> mean_error_deg;
  // The grade of the action: the mean of the graded parts' mean errors,
  // each weighted by teacher_motion_deg + motion_weight_floor_deg, so that
  // the parts the action is about count most (a wave is graded mostly on
  // the waving arm, not on the stance); nullopt when nothing is graded.
  std::optional<double> action_error_deg;
  // Graded part-pairs over all part-pairs, 0..1.
  double coverage = 0.0;
  std::vector<Correction> corrections;
  std::vector<WorstMoment> worst_moments;
  int num_learner_frames = 0;
  int num_teacher_frames = 0;
  // Learner frames without a skeleton.
  int learner_frames_without_skeleton = 0;
};

// Grades `learner` against `teacher` (see the top). InvalidArgument for bad
// options, an empty side, or a side with no usable skeleton at all (the
// message says which); DTW's errors for sequences too long for its table.
absl::StatusOr<Grade> GradeSequences(const std::vector<GradeFrame>& teacher,
                                     const std::vector<GradeFrame>& learner,
                                     const GradeOptions& options = {});

// The same over pairs chosen by the caller (e.g. the mirror's pairing of
// each learner frame with the teacher frame on screen); used_dtw is false.
// InvalidArgument for a pair outside either sequence, besides the errors of
// GradeSequences.
absl::StatusOr<Grade> GradePairs(const std::vector<GradeFrame>& teacher,
                                 const std::vector<GradeFrame>& learner,
                                 const std::vector<FramePair>& pairs,
                                 const GradeOptions& options = {});

// How much each part moves over a sequence of part directions: the mean
// angle (degrees) between its direction in each frame and its mean
// direction; 0 for a part in no frame (PartGrade::teacher_motion_deg).
std::array<double, kNumBodyParts> PartMotionDeg(
    const std::vector<PerPart<Eigen::Vector3d>>& directions);

// "left knee", "right upper arm", "head", ... (for sentences).
std::string PartWords(BodyPart part);

// The grade as JSON text (parts, coverage, corrections, worst moments; the
// per-pair errors when with_pairs).
std::string GradeJson(const Grade& grade, bool with_pairs = false);

// PNG bytes of the parts x time heat map: one row per part, one column per
// pair, coloured by the smoothed error (pose_comparison.h's colour map),
// hatched grey where the part was not graded, with the part names, a time
// axis and the coverage per part. Internal on encoder failure.
absl::StatusOr<std::string> GradeHeatMapPng(const Grade& grade,
                                            const ErrorColorOptions& colors = {});

// PNG bytes of the worst moments: per moment, the learner's and the
// teacher's skeletons drawn side by side from the front of their own spine
// frames (so the teacher is turned to the learner's facing), the part
// outlined, with the time and error. `teacher` and `learner` are the
// sequences that were graded. Internal on encoder failure.
absl::StatusOr<std::string> WorstMomentsPng(const Grade& grade,
                                            const std::vector<GradeFrame>& teacher,
                                            const std::vector<GradeFrame>& learner);

}  // namespace reenact::mirror
