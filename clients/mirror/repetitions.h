// Repetitions and holds in a learner's take, for grading with no mirror
// playing the teacher in step (`reenact grade`).
//
// Repetitions. A learner's take may hold the teacher's action several times,
// with pauses or other moves between. Each repetition is a stretch of the
// learner's frames paired with the whole teacher by subsequence DTW: the
// teacher's first frame may pair with any learner frame, its last frame with
// any later one, with the steps of time_alignment.h, minimising the summed
// action-weighted distance of the pairs (each part's angle weighted by how
// much the teacher moves it plus a floor, as Grade::action_error_deg). A
// stretch qualifies when its mean distance per pair is at most
// max_distance_deg and it lasts a plausible share of the teacher's duration;
// of those, the least summed distance is taken (a sum is not lowered by
// resting in the last pose after the action, so the stretch ends where the
// learner reaches it), its frames are removed from the search, and so on.
// So a take with three waves and a bow between gives three repetitions and
// no bow.
//
// Holds. A hold is a pose kept for a time: a run of frames in which every
// compared part stays within still_deg of its mean direction over a window
// of window_s around each frame, lasting at least min_hold_s. Runs touching
// the first or last frame of a sequence are not holds: that is standing
// before or after the action. The teacher's holds are matched with the
// learner's through the pairing: for each teacher hold, the learner hold that
// overlaps most the learner frames paired with it, and how long it lasted.
//
// These are departures from the thesis, which plays the teacher once while
// the learner performs (sec. 4.6.1) and neither counts nor times.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "clients/mirror/grading.h"
#include "clients/mirror/time_alignment.h"

namespace reenact::mirror {

struct RepetitionOptions {
  // A stretch is a repetition when its mean action-weighted distance to the
  // teacher is at most this (degrees, in (0, 180]). 18 was chosen from 8-25
  // on the rgbd-seq dev subjects' SDK skeletons (`reenact grade --real`):
  // two people's same action is counted once in 86 % of recordings, another
  // action none in 80 %; 20 counts 90 % and rejects 72 %, 16 counts 76 %
  // and rejects 90 %. Right-hand gestures of one family (a wave, a circle,
  // a tick) are not told apart by any threshold.
  double max_distance_deg = 18.0;
  // And when it lasts between these multiples of the teacher's duration
  // (0 < min <= max).
  double min_length_ratio = 0.4;
  double max_length_ratio = 2.5;
  // At most this many repetitions (>= 1).
  int max_repetitions = 200;
  // Weight floor per part, as GradeOptions::motion_weight_floor_deg (>= 0).
  double motion_weight_floor_deg = 5.0;
  // Distance of a pair with no part to compare (degrees, [0, 180]).
  double missing_cost_deg = 90.0;
  // Largest learner x teacher frame product accepted (13 bytes a cell).
  int64_t max_cells = 20'000'000;

  // InvalidArgument naming the first bad field.
  absl::Status Validate() const;
};

struct Repetition {
  int first_learner_frame = 0;
  int last_learner_frame = 0;
  double start_s = 0.0;  // Learner times of the first and last frame.
  double end_s = 0.0;
  // The pairing of this stretch with the whole teacher, in order.
  std::vector<FramePair> pairs;
  // Mean action-weighted distance over the pairs (degrees).
  double distance_deg = 0.0;
};

// The repetitions in time order (see the top). InvalidArgument for bad
// options, an empty side, or a table over max_cells; an empty list when no
// stretch is close enough.
absl::StatusOr<std::vector<Repetition>> FindRepetitions(const std::vector<GradeFrame>& teacher,
                                                        const std::vector<GradeFrame>& learner,
                                                        const RepetitionOptions& options = {});

struct HoldOptions {
  // Every compared part within this angle of its window mean (degrees, > 0).
  double still_deg = 12.0;
  // The window around each frame (seconds, > 0).
  double window_s = 0.3;
  // Shortest hold (seconds, > 0).
  double min_hold_s = 0.6;

  absl::Status Validate() const;
};

struct Hold {
  int first_frame = 0;
  int last_frame = 0;
  double start_s = 0.0;
  double duration_s = 0.0;  // Time from the first to the last frame.
};

// The holds of a sequence (see the top). Only seen parts of valid joints
// count (GradeFrame::seen); frames without a skeleton break a hold.
absl::StatusOr<std::vector<Hold>> FindHolds(const std::vector<GradeFrame>& frames,
                                            const HoldOptions& options = {});

struct HoldMatch {
  Hold teacher;
  // The learner's hold over the frames paired with the teacher's, or nullopt
  // when the learner did not hold there.
  std::optional<Hold> learner;
  // learner duration minus teacher duration (seconds; -teacher's when none).
  double difference_s = 0.0;
};

// For each teacher hold that some pair reaches, the learner hold matched to
// it through `pairs` (see the top).
std::vector<HoldMatch> MatchHolds(const std::vector<Hold>& teacher_holds,
                                  const std::vector<Hold>& learner_holds,
                                  const std::vector<FramePair>& pairs);

// A learner's whole take graded against the teacher: its repetitions, each
// graded on its own pairs, and the grade over all of them; the teacher's
// holds and, per repetition, the learner's.
struct TakeGrade {
  std::vector<Repetition> repetitions;
  // Per repetition: its grade (GradePairs over its pairs) and its holds.
  std::vector<Grade> repetition_grades;
  std::vector<std::vector<HoldMatch>> repetition_holds;
  // Over the pairs of every repetition; when none was found, the whole take
  // paired with the teacher as GradeSequences does (whole_take true).
  Grade overall;
  bool whole_take = false;
  std::vector<Hold> teacher_holds;
};

struct TakeGradeOptions {
  GradeOptions grade;
  RepetitionOptions repetitions;
  HoldOptions holds;
};

// Grades `learner` against `teacher` as above; with options.grade.use_dtw
// false (pairs index by index) there is no search: the whole take is one
// repetition's worth, graded as GradeSequences does. The errors of GradeSequences,
// FindRepetitions and FindHolds.
absl::StatusOr<TakeGrade> GradeTake(const std::vector<GradeFrame>& teacher,
                                    const std::vector<GradeFrame>& learner,
                                    const TakeGradeOptions& options = {});

// JSON of the repetitions and holds (the overall grade is GradeJson's).
std::string RepetitionsJson(const TakeGrade& take);

// "hold at 1.0 s (1.1 s): held 1.7 s, 0.6 s longer" and the like.
std::string HoldWords(const HoldMatch& hold);

}  // namespace reenact::mirror
