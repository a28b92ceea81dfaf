// MirrorSession: the magic mirror's logic, driven frame by frame (thesis
// sec. 4.5.1), with no rendering, sensors or windows.
//
// States, in a loop ("once the action plays completely, it resets and the
// learner can adjust his or her facing again"):
//
//   kWaitingForLearner --learner with a facing--> kReadingFacing
//   kReadingFacing --facing held within tolerance for hold_s--> kPlaying
//   kReadingFacing --learner lost--> kWaitingForLearner
//   kPlaying --teacher's last frame passed--> report, then kReadingFacing
//                                             (or kFinished after the last
//                                             of `repetitions`)
//
// How to drive it: call Update once per learner sensor frame with the frame's
// stamp (non-decreasing, nanoseconds, any clock: the session reads time only
// from these stamps, so it is deterministic and replays identically) and the
// tracked skeleton in the sensor's OpenCV frame (x right, y down, z forward,
// metres, joints labelled with the person's own left and right, NOT mirrored
// for display; Kinect v2 SDK camera space, x to the sensor's left and y up,
// converts by negating x and y), or nullopt when nobody is tracked. Draw what
// the returned MirrorFrame says:
//  - the teacher: its skeleton/mesh at frame `teacher_frame`, with every
//    world point p drawn at teacher_turn.turned_from_original * p, seen from
//    world_from_virtual_camera() (OpenCV camera convention), and the render
//    flipped left-right like the learner's colour image (facing.h explains
//    why both are flipped and the turn is not negated);
//  - the learner's feedback: joint j of the learner in joint_color[j], part
//    p in part_color[p] (anatomical sides; draw them where the flipped image
//    shows those joints);
//  - while reading the facing, a progress cue of facing.held_s / hold_s;
//  - when `finished_report` is set, the repetition's summary (the files are
//    already written when report_dir is set; report_status says whether
//    that worked).
//
// Teacher timing: playing starts at the stamp of the frame on which the
// facing became steady (teacher frame 0) and the teacher frame is
// floor(elapsed_s * teacher_fps * playback_speed). Learner frames are
// compared with the teacher frame on screen at their stamp (one to one, as in
// thesis sec. 4.6.1) or, with use_dtw, re-paired by DTW over the whole
// repetition when it ends (time_alignment.h; both ends anchored, so a learner
// still catching up when the teacher ends has their last frame paired with
// the teacher's last frames); the live per-frame errors are always the
// one-to-one ones. While the facing is read, the live errors compare the
// learner with teacher frame 0, the start pose they are getting into. The
// frame on which a repetition ends starts the next facing hold on the frame
// after it.
//
// Challenge mode (thesis sec. 4.7, future work: "the system sets a view for the
// user instead of the user choosing a view"): the teacher is shown at a view
// yaw chosen by the session instead of the learner's facing. The session
// still waits for the learner to hold a facing (any facing) before each
// repetition, so that they are ready. kCycle takes the listed views in turn;
// kHardestView shows each listed view once, then always the view whose
// repetitions have the largest mean error so far (ties: the earlier listed),
// so the learner drills their weakest view.
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "clients/mirror/body_parts.h"
#include "clients/mirror/facing.h"
#include "clients/mirror/grading.h"
#include "clients/mirror/pose_comparison.h"
#include "clients/mirror/repetition_report.h"
#include "clients/mirror/time_alignment.h"
#include "common/body/joint_set.h"

namespace reenact::mirror {

enum class MirrorState { kWaitingForLearner, kReadingFacing, kPlaying, kFinished };

// "waiting_for_learner", "reading_facing", "playing", "finished".
std::string_view MirrorStateName(MirrorState state);

enum class ChallengeMode {
  kOff,          // The teacher follows the learner's facing (thesis sec. 4.5.1).
  kCycle,        // Views taken in turn from challenge_view_yaws_deg.
  kHardestView,  // Each listed view once, then the one with the largest mean error.
};

struct MirrorSessionOptions {
  // Repetitions to play before kFinished; 0 loops forever. Must be >= 0.
  int repetitions = 0;
  // When the learner's facing counts as held: +-10 degrees for 2 s.
  SteadinessOptions facing;
  // Teacher frames advance at teacher_fps * playback_speed. Must be > 0.
  double playback_speed = 1.0;
  // Re-pair each finished repetition by DTW (time_alignment.h) for its report.
  bool use_dtw = false;
  // DTW settings (band, cost of frames without a skeleton).
  DtwOptions dtw;
  // Who chooses the view of the teacher (see the top of this header).
  ChallengeMode challenge = ChallengeMode::kOff;
  // Views (teacher facing yaw relative to the virtual camera, degrees, the
  // convention of facing.h) for challenge mode; non-empty and finite when
  // challenge is on.
  std::vector<double> challenge_view_yaws_deg = {0.0, 90.0, 180.0, -90.0};
  // The teacher's facing is the circular mean over its first
  // teacher_facing_window_s seconds (<= 0: the whole action).
  double teacher_facing_window_s = 0.5;
  // Up (against gravity) in the learner sensor's OpenCV frame; (0, -1, 0) for
  // a level sensor. Finite and non-zero.
  Eigen::Vector3d up_in_sensor = LevelSensorUp();
  // The virtual camera that films the teacher (world_from_camera, OpenCV
  // convention). Unset: PlaceVirtualCamera in front of the teacher (bearing =
  // its start facing) at the distance and height below.
  std::optional<Eigen::Isometry3d> world_from_virtual_camera;
  // Horizontal distance (metres, > 0) and height above the floor (metres) of
  // the default virtual camera.
  double virtual_camera_distance_m = 3.0;
  double virtual_camera_height_m = 1.2;
  // Folder for rep-NNN.{csv,json,png}; empty writes no files.
  std::string report_dir;
  // Colours of the per-part and per-joint feedback.
  ErrorColorOptions colors;

  // InvalidArgument naming the first bad field.
  absl::Status Validate() const;
};

// What the app draws for one learner frame.
struct MirrorFrame {
  MirrorState state = MirrorState::kWaitingForLearner;
  // 1-based repetition: the one playing, or the next one while waiting or
  // reading the facing (the last one once finished).
  int repetition = 1;
  // Teacher frame to draw (0 until playing).
  int teacher_frame = 0;
  // The teacher turn to draw: follows the live facing while reading it (or
  // the challenge view), fixed while playing.
  TeacherTurn teacher_turn;
  // The learner's facing yaw relative to the sensor in this frame.
  std::optional<double> learner_facing_yaw_deg;
  // Progress of the facing hold (held_s against options.facing.hold_s).
  SteadinessStatus facing;
  // Learner against teacher_frame (empty when nobody is tracked).
  PoseComparison comparison;
  std::array<std::optional<double>, body::kNumKinectV2Joints> joint_error_deg;
  std::array<Srgb8, kNumBodyParts> part_color;
  std::array<Srgb8, body::kNumKinectV2Joints> joint_color;
  // Set on the frame a repetition ends (that frame is already in the next
  // state).
  std::optional<RepetitionReport> finished_report;
  // Where the report went (when report_dir is set and writing worked).
  std::optional<RepetitionFiles> report_files;
  // Error of writing the report files; OK otherwise.
  absl::Status report_status;
};

class MirrorSession {
 public:
  // `teacher_in_world`: the teacher's skeleton per frame (world: +Y up,
  // metres; e.g. a reenactment's per-frame joints_in_world_m, missing joints
  // marked invalid or NaN), played at `teacher_fps`. InvalidArgument for bad
  // options, no frames, fps <= 0, or a teacher whose pivot or start facing
  // cannot be measured.
  static absl::StatusOr<MirrorSession> Create(std::vector<body::SkeletonPose> teacher_in_world,
                                              double teacher_fps,
                                              const MirrorSessionOptions& options);

  // Advances by one learner frame (see the top of this header).
  // InvalidArgument, with nothing changed, when stamp_ns is earlier than the
  // previous frame's.
  absl::StatusOr<MirrorFrame> Update(int64_t stamp_ns,
                                     const std::optional<body::SkeletonPose>& learner_in_sensor);
  // The same, grading only the parts the sensor saw: `joint_seen` (per joint
  // of learner_in_sensor, e.g. LearnerFrame::joint_seen) false for a joint
  // that was only inferred leaves out the parts it ends; they are drawn in
  // colors.missing_color and stay out of the report's means and coverage.
  // nullptr grades every valid joint. `people_in_view`: how many people the
  // tracker found in the frame (LearnerFrame::people_in_view); frames with
  // more than one are counted in the report (the learner is still the one
  // the source chose).
  absl::StatusOr<MirrorFrame> Update(int64_t stamp_ns,
                                     const std::optional<body::SkeletonPose>& learner_in_sensor,
                                     const std::array<bool, body::kNumKinectV2Joints>* joint_seen,
                                     int people_in_view = 1);

  // Ends a repetition that is playing when the learner stops early (a take
  // ends, the app is told to stop): its report covers the teacher frames
  // played so far and is marked incomplete (RepetitionReport::complete), and
  // is written to report_dir like any other. Returns the frame carrying the
  // report (state kFinished), or nullopt, with nothing changed, when nothing
  // is playing or no learner frame was compared yet. Update must not be
  // called afterwards.
  std::optional<MirrorFrame> EndEarly(int64_t stamp_ns);

  MirrorState state() const { return state_; }
  const TeacherFacing& teacher_facing() const { return teacher_facing_; }
  const Eigen::Isometry3d& world_from_virtual_camera() const { return world_from_camera_; }
  int num_teacher_frames() const { return static_cast<int>(teacher_.size()); }
  // Replaces the teacher skeletons the learner is compared with (one per
  // teacher frame, world), e.g. by the teacher's joints as the learner's
  // tracker finds them (TeacherSkeletonsAsTracked); the facing, turn and
  // timing keep the skeletons the session was created with. Takes effect
  // from the next frame compared. InvalidArgument for another frame count.
  absl::Status SetComparisonTeacher(const std::vector<body::SkeletonPose>& teacher_in_world);
  // The learner's facing locked for the repetition playing or last played.
  const std::optional<double>& locked_learner_yaw_deg() const { return locked_learner_yaw_deg_; }
  // Whether teacher frame `k` has a skeleton to compare with (a spine and at
  // least one part); false also for k outside the teacher.
  bool TeacherFrameHasSkeleton(int k) const;
  double teacher_fps() const { return teacher_fps_; }
  // Reports of the finished repetitions, in order.
  const std::vector<RepetitionReport>& reports() const { return reports_; }

 private:
  // A learner frame received while playing.
  struct PlayedFrame {
    int64_t stamp_ns;
    int teacher_frame;
    PerPart<Eigen::Vector3d> directions;
    GradeFrame learner;  // The skeleton and which joints were seen.
  };

  MirrorSession() = default;
  void UpdateReadingFacing(int64_t stamp_ns, const std::optional<double>& yaw_deg);
  void StartPlaying(int64_t stamp_ns);
  void UpdatePlaying(int64_t stamp_ns, const PerPart<Eigen::Vector3d>* learner,
                     const GradeFrame& learner_frame, int people_in_view, MirrorFrame& frame);
  void FinishRepetition(int64_t stamp_ns, MirrorFrame& frame, bool complete = true);
  RepetitionReport BuildReport(int64_t end_stamp_ns, bool complete) const;
  // The compared pairs over teacher frames [0, teacher_frames_played).
  std::vector<ComparedFrame> PairedFrames(int teacher_frames_played, bool& used_dtw,
                                          std::vector<FramePair>* pairs = nullptr) const;
  // Index into challenge_view_yaws_deg of the view for the coming (or
  // playing) repetition; nullopt when challenge mode is off.
  std::optional<int> ChallengeViewIndex() const;
  TeacherTurn TurnFor(double view_yaw_deg) const;
  void FillFeedback(const PerPart<Eigen::Vector3d>* learner, MirrorFrame& frame) const;

  MirrorSessionOptions options_;
  std::vector<body::SkeletonPose> teacher_;
  std::vector<PerPart<Eigen::Vector3d>> teacher_directions_;
  // Shared with every report (RepetitionReport::teacher_frames).
  std::shared_ptr<const std::vector<GradeFrame>> teacher_grade_frames_;
  double teacher_fps_ = 0.0;
  TeacherFacing teacher_facing_;
  Eigen::Isometry3d world_from_camera_ = Eigen::Isometry3d::Identity();
  std::optional<SteadinessDetector> steadiness_;

  MirrorState state_ = MirrorState::kWaitingForLearner;
  std::optional<int64_t> last_stamp_ns_;
  int repetitions_done_ = 0;
  TeacherTurn turn_;
  std::optional<double> locked_learner_yaw_deg_;
  int64_t play_start_ns_ = 0;
  int teacher_frame_ = 0;
  int learner_frames_in_repetition_ = 0;
  int frames_without_learner_in_repetition_ = 0;
  int frames_with_several_people_in_repetition_ = 0;
  std::vector<PlayedFrame> played_;
  std::vector<RepetitionReport> reports_;
  // Challenge kHardestView: per listed view, summed repetition means and count.
  std::vector<double> view_error_sum_deg_;
  std::vector<int> view_repetitions_;
};

}  // namespace reenact::mirror
