// The report of one repetition: the compared frames, per-part and overall
// mean errors (thesis sec. 4.6.1 and Fig. 4.4: average error in degrees per
// part and per frame), and the files it is written to.
//
// WriteRepetitionReport writes, into a report folder, for repetition N:
//   rep-NNN.csv   one row per compared frame:
//                 time_s,teacher_frame,learner_stamp_ns,<13 part names>,mean_error_deg
//                 (degrees; an empty field is a missing part or mean);
//   rep-NNN.json  {"repetition", "mean_error_deg", "parts": {"head": ..., ...},
//                 "coverage", "learner_facing_yaw_deg", "view_yaw_deg", "teacher_turn_yaw_deg",
//                 "teacher_facing_yaw_world_deg", "challenge", "dtw",
//                 "playback_speed", "start_stamp_ns", "end_stamp_ns", "duration_s",
//                 "num_learner_frames", "num_teacher_frames",
//                 "num_compared_frames", "files"} (null where missing);
//   rep-NNN.png   per-part error (degrees) over time (seconds), one coloured
//                 line per part, the frame mean in black, with a legend;
//   rep-NNN-heatmap.png, rep-NNN-worst.png  when the report has a grade: the
//                 parts x time heat map and the worst moments (grading.h),
//                 and the JSON then carries "grade" (GradeJson).
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "clients/mirror/body_parts.h"
#include "clients/mirror/grading.h"
#include "clients/mirror/pose_comparison.h"

namespace reenact::mirror {

// One compared learner/teacher pair.
struct ComparedFrame {
  // Learner stamp minus the repetition's start, seconds.
  double time_s = 0.0;
  // Index of the teacher frame compared.
  int teacher_frame = 0;
  // The learner frame's stamp, nanoseconds (the app's clock).
  int64_t learner_stamp_ns = 0;
  PoseComparison comparison;
};

struct RepetitionReport {
  // 1-based repetition number (the NNN of the file names).
  int repetition = 0;
  // Whether the pairs come from DTW (time_alignment.h) or one to one.
  bool used_dtw = false;
  // Whether the view was chosen by challenge mode rather than the learner.
  bool challenge = false;
  // The learner's locked facing yaw relative to the sensor, degrees.
  std::optional<double> learner_facing_yaw_deg;
  // The teacher's facing relative to the virtual camera, degrees.
  double view_yaw_deg = 0.0;
  // The teacher turn about world +Y, degrees (facing.h).
  double teacher_turn_yaw_deg = 0.0;
  // The teacher's own start facing in world, degrees.
  double teacher_facing_yaw_world_deg = 0.0;
  // Teacher frames per learner second divided by the teacher's fps.
  double playback_speed = 1.0;
  // Stamps of the first and last learner frame of the repetition.
  int64_t start_stamp_ns = 0;
  int64_t end_stamp_ns = 0;
  // Learner frames with a skeleton received while playing.
  int num_learner_frames = 0;
  // Frames received while playing with no learner skeleton (out of view, no
  // depth), and frames with more than one person in view.
  int frames_without_learner = 0;
  int frames_with_several_people = 0;
  // Teacher frames played that have no skeleton to compare with (a
  // reenactment with missing frames): nothing is graded against them.
  int teacher_frames_without_skeleton = 0;
  // Frames of the teacher's action.
  int num_teacher_frames = 0;
  // False when the learner stopped (the take ended, the app was stopped)
  // before the teacher's last frame: the report covers teacher frames
  // [0, teacher_frames_played) only.
  bool complete = true;
  int teacher_frames_played = 0;
  // The compared pairs, in order.
  std::vector<ComparedFrame> frames;
  // Per part: mean of its error over the frames where it is present.
  PerPart<double> part_mean_error_deg;
  // Mean over the compared pairs of each pair's mean part error (with DTW a
  // learner frame may be in several pairs).
  std::optional<double> mean_error_deg;
  // Compared part-frames over all part-frames (0..1): how much of the body
  // the means cover (parts the sensor did not see are not compared).
  double coverage = 0.0;
  // The repetition graded over the same pairs by the grading library
  // (grading.h): the parts not graded and why, the action-weighted error,
  // at most three corrections in words and the worst moments; nullopt when
  // it could not be graded.
  std::optional<Grade> grade;
  // The frames graded (learner: the repetition's, timed from its start;
  // teacher: the whole action, shared by every report of a session), for the
  // worst moments' thumbnails; teacher_frames is null when not graded.
  std::vector<GradeFrame> learner_frames;
  std::shared_ptr<const std::vector<GradeFrame>> teacher_frames;
};

// Fills part_mean_error_deg and mean_error_deg from `frames`.
void SummarizeErrors(RepetitionReport& report);

// What went wrong with the input of a repetition, in words for the learner
// (the learner out of view or no depth, several people in view, teacher
// frames without a skeleton); empty when nothing did.
std::vector<std::string> InputProblems(const RepetitionReport& report);

// The three files' contents (see the top of this header).
std::string RepetitionCsv(const RepetitionReport& report);
std::string RepetitionJson(const RepetitionReport& report);
// PNG bytes of the error plot, 1280 x 720. Internal on encoder failure.
absl::StatusOr<std::string> RepetitionPlotPng(const RepetitionReport& report);

// "rep-NNN" for repetition N (at least three digits).
std::string RepetitionFileStem(int repetition);

struct RepetitionFiles {
  std::string csv_path;
  std::string json_path;
  std::string png_path;
  // rep-NNN-heatmap.png and rep-NNN-worst.png (GradeHeatMapPng,
  // WorstMomentsPng); empty when the report has no grade.
  std::string heatmap_path;
  std::string worst_path;
};

// Creates `report_dir` if needed and writes the three files, each through a
// temporary file and a rename. PermissionDenied (or the error of the file
// system) when the folder cannot be made or written; files already there for
// other repetitions are left alone.
absl::StatusOr<RepetitionFiles> WriteRepetitionReport(const RepetitionReport& report,
                                                      const std::string& report_dir);

}  // namespace reenact::mirror
