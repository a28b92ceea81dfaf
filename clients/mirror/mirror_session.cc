#include "clients/mirror/mirror_session.h"

#include <algorithm>
#include <cmath>
#include <utility>

#include "absl/strings/str_cat.h"
#include "common/base/status_macros.h"

namespace reenact::mirror {
namespace {

absl::Status InvalidOption(const char* field, const char* why) {
  return absl::InvalidArgumentError(absl::StrCat("mirror option ", field, " ", why));
}

absl::Status ValidateChallenge(const MirrorSessionOptions& options) {
  if (options.challenge == ChallengeMode::kOff) return absl::OkStatus();
  if (options.challenge_view_yaws_deg.empty()) {
    return InvalidOption("challenge_view_yaws_deg", "must not be empty in challenge mode");
  }
  for (double yaw_deg : options.challenge_view_yaws_deg) {
    if (!std::isfinite(yaw_deg)) return InvalidOption("challenge_view_yaws_deg", "must be finite");
  }
  return absl::OkStatus();
}

}  // namespace

std::string_view MirrorStateName(MirrorState state) {
  switch (state) {
    case MirrorState::kWaitingForLearner:
      return "waiting_for_learner";
    case MirrorState::kReadingFacing:
      return "reading_facing";
    case MirrorState::kPlaying:
      return "playing";
    case MirrorState::kFinished:
      return "finished";
  }
  return "unknown";
}

absl::Status MirrorSessionOptions::Validate() const {
  if (repetitions < 0) return InvalidOption("repetitions", "must be >= 0");
  RETURN_IF_ERROR(facing.Validate());
  if (!(playback_speed > 0.0 && std::isfinite(playback_speed))) {
    return InvalidOption("playback_speed", "must be > 0 and finite");
  }
  RETURN_IF_ERROR(dtw.Validate());
  RETURN_IF_ERROR(ValidateChallenge(*this));
  if (!std::isfinite(teacher_facing_window_s)) {
    return InvalidOption("teacher_facing_window_s", "must be finite");
  }
  if (!up_in_sensor.allFinite() || !(up_in_sensor.norm() > 0.0)) {
    return InvalidOption("up_in_sensor", "must be finite and non-zero");
  }
  if (world_from_virtual_camera && !world_from_virtual_camera->matrix().allFinite()) {
    return InvalidOption("world_from_virtual_camera", "must be finite");
  }
  if (!(virtual_camera_distance_m > 0.0 && std::isfinite(virtual_camera_distance_m)) ||
      !std::isfinite(virtual_camera_height_m)) {
    return InvalidOption("virtual_camera_distance_m/height_m", "must be finite, distance > 0");
  }
  return colors.Validate();
}

absl::StatusOr<MirrorSession> MirrorSession::Create(
    std::vector<body::SkeletonPose> teacher_in_world, double teacher_fps,
    const MirrorSessionOptions& options) {
  RETURN_IF_ERROR(options.Validate());
  if (teacher_in_world.empty()) return absl::InvalidArgumentError("the teacher has no frames");
  MirrorSession session;
  session.options_ = options;
  ASSIGN_OR_RETURN(session.teacher_facing_, MeasureTeacherFacing(teacher_in_world, teacher_fps,
                                                                 options.teacher_facing_window_s));
  if (options.world_from_virtual_camera) {
    session.world_from_camera_ = *options.world_from_virtual_camera;
  } else {
    ASSIGN_OR_RETURN(
        session.world_from_camera_,
        PlaceVirtualCamera(session.teacher_facing_.pivot_in_world,
                           session.teacher_facing_.facing_yaw_world_deg,
                           options.virtual_camera_distance_m, options.virtual_camera_height_m));
  }
  // Checks that the camera gives a turn at all (it must not look straight down).
  ASSIGN_OR_RETURN(session.turn_,
                   ComputeTeacherTurn(session.teacher_facing_, 0.0, session.world_from_camera_));
  ASSIGN_OR_RETURN(SteadinessDetector detector, SteadinessDetector::Create(options.facing));
  session.steadiness_.emplace(std::move(detector));
  session.teacher_fps_ = teacher_fps;
  RETURN_IF_ERROR(session.SetComparisonTeacher(teacher_in_world));
  session.teacher_ = std::move(teacher_in_world);
  session.view_error_sum_deg_.assign(options.challenge_view_yaws_deg.size(), 0.0);
  session.view_repetitions_.assign(options.challenge_view_yaws_deg.size(), 0);
  if (std::optional<int> view = session.ChallengeViewIndex()) {
    session.turn_ = session.TurnFor(options.challenge_view_yaws_deg[*view]);
  }
  return session;
}

absl::StatusOr<MirrorFrame> MirrorSession::Update(
    int64_t stamp_ns, const std::optional<body::SkeletonPose>& learner_in_sensor) {
  return Update(stamp_ns, learner_in_sensor, nullptr);
}

absl::StatusOr<MirrorFrame> MirrorSession::Update(
    int64_t stamp_ns, const std::optional<body::SkeletonPose>& learner_in_sensor,
    const std::array<bool, body::kNumKinectV2Joints>* joint_seen, int people_in_view) {
  if (last_stamp_ns_ && stamp_ns < *last_stamp_ns_) {
    return absl::InvalidArgumentError(absl::StrCat(
        "learner stamp ", stamp_ns, " ns is earlier than the previous ", *last_stamp_ns_, " ns"));
  }
  last_stamp_ns_ = stamp_ns;
  std::optional<double> yaw_deg;
  std::optional<PerPart<Eigen::Vector3d>> learner;
  GradeFrame learner_frame;
  learner_frame.pose = learner_in_sensor;
  if (joint_seen != nullptr && learner_in_sensor) {
    learner_frame.seen = *joint_seen;
  } else {
    MarkValidJointsSeen(learner_frame);
  }
  if (learner_in_sensor) {
    yaw_deg = FacingYawInSensorDeg(*learner_in_sensor, options_.up_in_sensor);
    learner = PartDirectionsInSpine(*learner_in_sensor);
    // Grade only what the sensor saw: a part with an inferred joint is
    // left out (drawn in missing_color, out of the report's means).
    if (joint_seen != nullptr) {
      for (int p = 0; p < kNumBodyParts; ++p) {
        const PartBone bone = BodyPartBone(BodyPartAt(p));
        if (!(*joint_seen)[body::Index(bone.from)] || !(*joint_seen)[body::Index(bone.to)]) {
          (*learner)[p].reset();
        }
      }
    }
  }
  MirrorFrame frame;
  frame.learner_facing_yaw_deg = yaw_deg;
  if (state_ == MirrorState::kWaitingForLearner && yaw_deg) {
    state_ = MirrorState::kReadingFacing;
  }
  if (state_ == MirrorState::kReadingFacing) UpdateReadingFacing(stamp_ns, yaw_deg);
  if (state_ == MirrorState::kPlaying) {
    UpdatePlaying(stamp_ns, learner ? &*learner : nullptr, learner_frame, people_in_view, frame);
  }
  frame.state = state_;
  frame.repetition = state_ == MirrorState::kFinished ? repetitions_done_ : repetitions_done_ + 1;
  frame.teacher_frame = state_ == MirrorState::kPlaying ? teacher_frame_ : 0;
  frame.teacher_turn = turn_;
  frame.facing = steadiness_->status();
  FillFeedback(learner ? &*learner : nullptr, frame);
  return frame;
}

void MirrorSession::UpdateReadingFacing(int64_t stamp_ns, const std::optional<double>& yaw_deg) {
  if (!yaw_deg) {
    steadiness_->Reset();
    state_ = MirrorState::kWaitingForLearner;
    return;
  }
  const SteadinessStatus& status = steadiness_->Add(stamp_ns, yaw_deg);
  const std::optional<int> challenge_view = ChallengeViewIndex();
  if (!challenge_view) turn_ = TurnFor(*yaw_deg);  // Live preview (thesis sec. 4.5.1).
  if (!status.steady || !status.mean_yaw_deg) return;
  locked_learner_yaw_deg_ = status.mean_yaw_deg;
  turn_ = TurnFor(challenge_view ? options_.challenge_view_yaws_deg[*challenge_view]
                                 : *status.mean_yaw_deg);
  StartPlaying(stamp_ns);
}

void MirrorSession::StartPlaying(int64_t stamp_ns) {
  state_ = MirrorState::kPlaying;
  play_start_ns_ = stamp_ns;
  teacher_frame_ = 0;
  learner_frames_in_repetition_ = 0;
  frames_without_learner_in_repetition_ = 0;
  frames_with_several_people_in_repetition_ = 0;
  played_.clear();
}

void MirrorSession::UpdatePlaying(int64_t stamp_ns, const PerPart<Eigen::Vector3d>* learner,
                                  const GradeFrame& learner_frame, int people_in_view,
                                  MirrorFrame& frame) {
  const double elapsed_s = (stamp_ns - play_start_ns_) * 1e-9;
  // A microframe of slack so that stamps landing exactly on a frame count.
  const double position = elapsed_s * teacher_fps_ * options_.playback_speed + 1e-6;
  if (position >= static_cast<double>(teacher_.size())) {
    FinishRepetition(stamp_ns, frame);
    return;
  }
  teacher_frame_ = static_cast<int>(std::floor(position));
  if (people_in_view > 1) ++frames_with_several_people_in_repetition_;
  if (learner == nullptr) {
    ++frames_without_learner_in_repetition_;
    return;
  }
  ++learner_frames_in_repetition_;
  played_.push_back({stamp_ns, teacher_frame_, *learner, learner_frame});
}

absl::Status MirrorSession::SetComparisonTeacher(
    const std::vector<body::SkeletonPose>& teacher_in_world) {
  if (teacher_fps_ <= 0.0 || (!teacher_.empty() && teacher_in_world.size() != teacher_.size())) {
    return absl::InvalidArgumentError(absl::StrCat("the comparison teacher has ",
                                                   teacher_in_world.size(), " frames, the teacher ",
                                                   teacher_.size()));
  }
  std::vector<PerPart<Eigen::Vector3d>> directions;
  directions.reserve(teacher_in_world.size());
  auto grade_frames = std::make_shared<std::vector<GradeFrame>>();
  grade_frames->reserve(teacher_in_world.size());
  for (const body::SkeletonPose& pose : teacher_in_world) {
    directions.push_back(PartDirectionsInSpine(pose));
    GradeFrame frame;
    frame.time_s = static_cast<double>(grade_frames->size()) / teacher_fps_;
    frame.pose = pose;
    MarkValidJointsSeen(frame);
    grade_frames->push_back(std::move(frame));
  }
  teacher_directions_ = std::move(directions);
  teacher_grade_frames_ = std::move(grade_frames);
  return absl::OkStatus();
}

bool MirrorSession::TeacherFrameHasSkeleton(int k) const {
  if (k < 0 || k >= static_cast<int>(teacher_directions_.size())) return false;
  const PerPart<Eigen::Vector3d>& d = teacher_directions_[k];
  return std::any_of(d.begin(), d.end(), [](const auto& v) { return v.has_value(); });
}

std::optional<MirrorFrame> MirrorSession::EndEarly(int64_t stamp_ns) {
  if (state_ != MirrorState::kPlaying || played_.empty()) return std::nullopt;
  MirrorFrame frame;
  frame.repetition = repetitions_done_ + 1;
  frame.teacher_frame = teacher_frame_;
  frame.teacher_turn = turn_;
  FinishRepetition(std::max(stamp_ns, played_.back().stamp_ns), frame, /*complete=*/false);
  state_ = MirrorState::kFinished;
  frame.state = state_;
  return frame;
}

void MirrorSession::FinishRepetition(int64_t stamp_ns, MirrorFrame& frame, bool complete) {
  RepetitionReport report =
      BuildReport(played_.empty() ? stamp_ns : played_.back().stamp_ns, complete);
  if (std::optional<int> view = ChallengeViewIndex(); view && report.mean_error_deg) {
    view_error_sum_deg_[*view] += *report.mean_error_deg;
    ++view_repetitions_[*view];
  }
  if (!options_.report_dir.empty()) {
    absl::StatusOr<RepetitionFiles> files = WriteRepetitionReport(report, options_.report_dir);
    if (files.ok()) frame.report_files = *files;
    frame.report_status = files.status();
  }
  reports_.push_back(report);
  frame.finished_report = std::move(report);
  ++repetitions_done_;
  played_.clear();
  steadiness_->Reset();
  locked_learner_yaw_deg_.reset();
  const bool done = options_.repetitions > 0 && repetitions_done_ >= options_.repetitions;
  state_ = done ? MirrorState::kFinished : MirrorState::kReadingFacing;
  if (std::optional<int> view = ChallengeViewIndex(); view && !done) {
    turn_ = TurnFor(options_.challenge_view_yaws_deg[*view]);
  }
}

RepetitionReport MirrorSession::BuildReport(int64_t end_stamp_ns, bool complete) const {
  RepetitionReport report;
  report.repetition = repetitions_done_ + 1;
  report.challenge = options_.challenge != ChallengeMode::kOff;
  report.learner_facing_yaw_deg = locked_learner_yaw_deg_;
  report.view_yaw_deg = turn_.view_yaw_deg;
  report.teacher_turn_yaw_deg = turn_.turn_yaw_deg;
  report.teacher_facing_yaw_world_deg = teacher_facing_.facing_yaw_world_deg;
  report.playback_speed = options_.playback_speed;
  report.start_stamp_ns = play_start_ns_;
  report.end_stamp_ns = end_stamp_ns;
  report.num_learner_frames = learner_frames_in_repetition_;
  report.frames_without_learner = frames_without_learner_in_repetition_;
  report.frames_with_several_people = frames_with_several_people_in_repetition_;
  report.num_teacher_frames = static_cast<int>(teacher_.size());
  report.complete = complete;
  report.teacher_frames_played = complete
                                     ? report.num_teacher_frames
                                     : (played_.empty() ? 0 : played_.back().teacher_frame + 1);
  for (int k = 0; k < report.teacher_frames_played; ++k) {
    report.teacher_frames_without_skeleton += !TeacherFrameHasSkeleton(k);
  }
  std::vector<FramePair> pairs;
  report.frames = PairedFrames(report.teacher_frames_played, report.used_dtw, &pairs);
  SummarizeErrors(report);
  // The same pairs through the grading library: corrections, worst moments.
  report.learner_frames.reserve(played_.size());
  for (const PlayedFrame& played : played_) {
    report.learner_frames.push_back(played.learner);
    report.learner_frames.back().time_s = (played.stamp_ns - play_start_ns_) * 1e-9;
  }
  absl::StatusOr<Grade> grade = GradePairs(*teacher_grade_frames_, report.learner_frames, pairs);
  if (grade.ok()) {
    report.grade = *std::move(grade);
    report.teacher_frames = teacher_grade_frames_;
  } else {
    report.learner_frames.clear();
  }
  return report;
}

std::vector<ComparedFrame> MirrorSession::PairedFrames(int teacher_frames_played, bool& used_dtw,
                                                       std::vector<FramePair>* pairs) const {
  Alignment alignment;
  used_dtw = false;
  if (options_.use_dtw && !played_.empty()) {
    std::vector<PerPart<Eigen::Vector3d>> learner;
    learner.reserve(played_.size());
    for (const PlayedFrame& played : played_) learner.push_back(played.directions);
    // An incomplete repetition is aligned with the part of the action that
    // was played, so that its end is not pulled to the teacher's last frame.
    const bool whole = teacher_frames_played == static_cast<int>(teacher_directions_.size());
    const std::vector<PerPart<Eigen::Vector3d>> played_teacher =
        whole
            ? std::vector<PerPart<Eigen::Vector3d>>()
            : std::vector<PerPart<Eigen::Vector3d>>(
                  teacher_directions_.begin(), teacher_directions_.begin() + teacher_frames_played);
    absl::StatusOr<Alignment> dtw =
        AlignDirectionsByDtw(learner, whole ? teacher_directions_ : played_teacher, options_.dtw);
    if (dtw.ok()) {
      alignment = *std::move(dtw);
      used_dtw = true;
    }
  }
  if (!used_dtw) {  // One to one by time; also the fallback when DTW cannot run.
    for (int i = 0; i < static_cast<int>(played_.size()); ++i) {
      alignment.pairs.push_back({i, played_[i].teacher_frame});
    }
  }
  if (pairs != nullptr) *pairs = alignment.pairs;
  std::vector<ComparedFrame> frames;
  frames.reserve(alignment.pairs.size());
  for (const FramePair& pair : alignment.pairs) {
    const PlayedFrame& played = played_[pair.learner_frame];
    frames.push_back(
        {(played.stamp_ns - play_start_ns_) * 1e-9, pair.teacher_frame, played.stamp_ns,
         CompareDirections(played.directions, teacher_directions_[pair.teacher_frame])});
  }
  return frames;
}

std::optional<int> MirrorSession::ChallengeViewIndex() const {
  const int num_views = static_cast<int>(options_.challenge_view_yaws_deg.size());
  const int next = repetitions_done_;  // 0-based index of the coming repetition.
  switch (options_.challenge) {
    case ChallengeMode::kOff:
      return std::nullopt;
    case ChallengeMode::kCycle:
      return next % num_views;
    case ChallengeMode::kHardestView:
      break;
  }
  if (next < num_views) return next;
  int hardest = 0;
  double hardest_mean_deg = -1.0;
  for (int v = 0; v < num_views; ++v) {
    if (view_repetitions_[v] == 0) return v;  // Never measured: show it first.
    const double mean_deg = view_error_sum_deg_[v] / view_repetitions_[v];
    if (mean_deg > hardest_mean_deg) {
      hardest = v;
      hardest_mean_deg = mean_deg;
    }
  }
  return hardest;
}

TeacherTurn MirrorSession::TurnFor(double view_yaw_deg) const {
  // The camera was checked in Create and the view yaw is finite: this succeeds.
  absl::StatusOr<TeacherTurn> turn =
      ComputeTeacherTurn(teacher_facing_, view_yaw_deg, world_from_camera_);
  return turn.ok() ? *turn : turn_;
}

void MirrorSession::FillFeedback(const PerPart<Eigen::Vector3d>* learner,
                                 MirrorFrame& frame) const {
  if (learner != nullptr && state_ != MirrorState::kFinished) {
    frame.comparison = CompareDirections(*learner, teacher_directions_[frame.teacher_frame]);
  }
  frame.joint_error_deg = JointErrorsDeg(frame.comparison);
  for (int p = 0; p < kNumBodyParts; ++p) {
    frame.part_color[p] = ErrorToSrgb(frame.comparison.part_error_deg[p], options_.colors);
  }
  for (int j = 0; j < body::kNumKinectV2Joints; ++j) {
    frame.joint_color[j] = ErrorToSrgb(frame.joint_error_deg[j], options_.colors);
  }
}

}  // namespace reenact::mirror
