#include "clients/mirror/mirror_app.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <deque>
#include <filesystem>
#include <map>
#include <memory>
#include <mutex>
#include <thread>
#include <utility>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "clients/sdk/follow_stats.h"
#include "common/base/status_macros.h"
#include "common/base/time.h"
#include "common/io/png.h"
#include "common/io/video_writer.h"
#include "common/render/image_window.h"

namespace reenact::mirror {
namespace {

using Clock = std::chrono::steady_clock;

double SecondsSince(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

// Where the composed frames go.
class FrameSink {
 public:
  virtual ~FrameSink() = default;
  // Takes frame `index`; false when the user asked to stop.
  virtual absl::StatusOr<bool> Put(RgbImage image, int index) = 0;
  // Ends the output and fills the summary's output fields; the error of a
  // frame that could not be written.
  virtual absl::Status Finish(MirrorAppSummary* summary) = 0;
  // A window needs the teacher's GL context released before each frame.
  virtual bool is_window() const = 0;
};

// frame_NNNNN.png for every n-th frame, and video.mp4 of all of them,
// written on a thread of the sink while the next frames are drawn.
class FolderSink : public FrameSink {
 public:
  static absl::StatusOr<std::unique_ptr<FrameSink>> Open(const MirrorAppOptions& options,
                                                         double fps) {
    std::error_code ec;
    std::filesystem::create_directories(options.render_to, ec);
    if (ec) return absl::PermissionDeniedError(absl::StrCat(options.render_to, ": ", ec.message()));
    auto sink = std::unique_ptr<FolderSink>(new FolderSink(options));
    if (options.mp4) sink->OpenVideo(fps);
    FolderSink* raw = sink.get();
    sink->writer_ = std::thread([raw] { raw->WriteQueued(); });
    return std::unique_ptr<FrameSink>(std::move(sink));
  }

  ~FolderSink() override { StopWriter(); }

  absl::StatusOr<bool> Put(RgbImage image, int index) override {
    std::unique_lock<std::mutex> lock(mutex_);
    room_.wait(lock, [&] { return queued_.size() < kQueuedFrames; });
    RETURN_IF_ERROR(write_error_);
    queued_.push_back({std::move(image), index});
    ready_.notify_one();
    return true;
  }

  absl::Status Finish(MirrorAppSummary* summary) override {
    StopWriter();
    if (video_ != nullptr) {
      if (absl::Status closed = video_->Close(); !closed.ok()) {
        mp4_problem_ = std::string(closed.message());
      }
      if (video_->frames_written() == 0 && mp4_problem_.empty()) mp4_problem_ = "no frames";
    }
    summary->pngs = pngs_;
    summary->first_png = first_png_;
    summary->mp4_problem = mp4_problem_;
    summary->mp4_path = mp4_problem_.empty() ? mp4_path_ : std::string();
    return write_error_;
  }

  bool is_window() const override { return false; }

 private:
  // Frames waiting for the writer.
  static constexpr size_t kQueuedFrames = 3;
  struct Queued {
    RgbImage image;
    int index = 0;
  };

  explicit FolderSink(const MirrorAppOptions& options)
      : dir_(options.render_to),
        every_(options.png_every),
        width_(options.composition.width),
        height_(options.composition.height) {}

  void OpenVideo(double fps) {
    mp4_path_ = (std::filesystem::path(dir_) / "video.mp4").string();
    VideoWriterOptions video_options;
    video_options.preset = "veryfast";
    absl::StatusOr<std::unique_ptr<VideoWriter>> opened =
        VideoWriter::Open(mp4_path_, width_, height_, fps, video_options);
    if (opened.ok()) {
      video_ = *std::move(opened);
    } else {
      mp4_problem_ = std::string(opened.status().message());
    }
  }

  // The writer thread: writes queued frames until StopWriter.
  void WriteQueued() {
    while (true) {
      std::unique_lock<std::mutex> lock(mutex_);
      ready_.wait(lock, [&] { return stopping_ || !queued_.empty(); });
      if (queued_.empty()) return;
      Queued frame = std::move(queued_.front());
      queued_.pop_front();
      room_.notify_one();
      lock.unlock();
      absl::Status written = Write(frame.image, frame.index);
      lock.lock();
      if (!written.ok() && write_error_.ok()) write_error_ = written;
    }
  }

  absl::Status Write(const RgbImage& image, int index) {
    if (index % every_ == 0) {
      const std::string path =
          (std::filesystem::path(dir_) / absl::StrFormat("frame_%05d.png", index)).string();
      RETURN_IF_ERROR(WritePng(image, path));
      if (pngs_++ == 0) first_png_ = path;
    }
    if (video_ != nullptr) {
      if (absl::Status appended = video_->Append(image); !appended.ok()) {
        mp4_problem_ = std::string(appended.message());
        video_.reset();
      }
    }
    return absl::OkStatus();
  }

  // Lets the writer finish the queued frames and joins it.
  void StopWriter() {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      stopping_ = true;
      ready_.notify_all();
    }
    if (writer_.joinable()) writer_.join();
  }

  std::string dir_;
  int every_ = 1;
  int width_ = 0;
  int height_ = 0;
  // Written by the writer thread until it is joined.
  int pngs_ = 0;
  std::string first_png_;
  std::string mp4_path_;
  std::string mp4_problem_;
  std::unique_ptr<VideoWriter> video_;
  // The queue.
  std::mutex mutex_;
  std::condition_variable ready_;
  std::condition_variable room_;
  std::deque<Queued> queued_;
  bool stopping_ = false;
  absl::Status write_error_;
  std::thread writer_;
};

class WindowSink : public FrameSink {
 public:
  static absl::StatusOr<std::unique_ptr<FrameSink>> Open(const CompositionOptions& composition) {
    ASSIGN_OR_RETURN(auto window, render::ImageWindow::Open("reenact-mirror", composition.width,
                                                            composition.height));
    return std::unique_ptr<FrameSink>(new WindowSink(std::move(window)));
  }

  absl::StatusOr<bool> Put(RgbImage image, int /*index*/) override {
    RETURN_IF_ERROR(window_->Show(image));
    const render::WindowInput input = window_->Poll();
    if (input.close_requested) return false;
    for (int key : input.keys_pressed) {
      if (key == render::kKeyEscape || key == 'Q') return false;
    }
    return true;
  }

  absl::Status Finish(MirrorAppSummary* /*summary*/) override { return absl::OkStatus(); }
  bool is_window() const override { return true; }

 private:
  explicit WindowSink(std::unique_ptr<render::ImageWindow> window) : window_(std::move(window)) {}
  std::unique_ptr<render::ImageWindow> window_;
};

// The teacher's point that is put on the learner: its first SpineBase.
Eigen::Vector3d TeacherAnchor(const std::vector<body::SkeletonPose>& teacher,
                              const TeacherFacing& facing) {
  for (const body::SkeletonPose& pose : teacher) {
    if (IsJointUsable(pose, body::KinectV2Joint::kSpineBase)) {
      return pose.position_m[body::Index(body::KinectV2Joint::kSpineBase)];
    }
  }
  return facing.pivot_in_world;
}

class MirrorLoop {
 public:
  MirrorLoop(const Reenactment& data, LearnerSource& learner, const MirrorAppOptions& options,
             const MirrorFrameObserver& observer)
      : data_(data), learner_(learner), options_(options), observer_(observer) {}

  absl::Status Init();
  absl::StatusOr<MirrorAppSummary> Run();

 private:
  // Handles one learner frame; false when the loop should stop.
  absl::StatusOr<bool> Step(const LearnerFrame& frame);
  absl::StatusOr<RgbImage> Compose(const LearnerFrame& frame, const MirrorFrame& mirror);
  render::RenderCamera TeacherCamera(const MirrorFrame& mirror) const;
  void FollowLearner(const LearnerFrame& frame);
  absl::StatusOr<CameraIntrinsics> IntrinsicsFor(const LearnerFrame& frame);
  void Record(const MirrorFrame& mirror);
  // Compares with the teacher as tracked from the locked facing.
  absl::Status UseTrackedTeacher();
  void Pace(int64_t stamp_ns) const;
  absl::Status Finish();

  const Reenactment& data_;
  LearnerSource& learner_;
  MirrorAppOptions options_;
  MirrorFrameObserver observer_;
  std::optional<MirrorSession> session_;
  std::unique_ptr<TeacherRenderer> teacher_;
  std::unique_ptr<FrameSink> sink_;
  Eigen::Vector3d teacher_anchor_in_world_ = Eigen::Vector3d::Zero();
  std::optional<Eigen::Vector3d> learner_anchor_in_color_;
  render::RenderCamera teacher_camera_;
  std::map<std::pair<int, int>, CameraIntrinsics> intrinsics_by_size_;
  StatusContext status_;
  MirrorAppSummary summary_;
  std::optional<int64_t> first_stamp_ns_;
  int64_t last_stamp_ns_ = 0;
  Clock::time_point start_;
  std::vector<double> latency_ms_;
  // --teacher-joints tracked: the teacher tracked per view (15-degree steps).
  MirrorState previous_state_ = MirrorState::kWaitingForLearner;
  std::map<int, std::vector<body::SkeletonPose>> tracked_teacher_by_view_;
  // Stamp of the last frame with a learner (the first frame's until one).
  std::optional<int64_t> last_seen_stamp_ns_;
  double render_s_ = 0.0;
  double compose_s_ = 0.0;
  double output_s_ = 0.0;
};

absl::Status MirrorLoop::Init() {
  RETURN_IF_ERROR(options_.Validate());
  if (!(data_.info.fps > 0.0)) {
    return absl::FailedPreconditionError(absl::StrCat("reenactment ", data_.info.reenactment_id,
                                                      " has no frame rate (ReenactmentInfo.fps)"));
  }
  ASSIGN_OR_RETURN(std::vector<body::SkeletonPose> teacher, TeacherSkeletons(data_));
  options_.session.up_in_sensor = learner_.sensor().up_in_color;
  ASSIGN_OR_RETURN(MirrorSession session,
                   MirrorSession::Create(teacher, data_.info.fps, options_.session));
  session_.emplace(std::move(session));
  teacher_anchor_in_world_ = TeacherAnchor(teacher, session_->teacher_facing());
  const PanelRect panel = TeacherPanel(options_.composition);
  ASSIGN_OR_RETURN(teacher_,
                   TeacherRenderer::Create(data_, panel.width, panel.height, options_.teacher));
  summary_.renderer = teacher_->Description();
  if (options_.render_to.empty()) {
    RETURN_IF_ERROR(teacher_->ReleaseCurrent());
    ASSIGN_OR_RETURN(sink_, WindowSink::Open(options_.composition));
  } else {
    ASSIGN_OR_RETURN(sink_, FolderSink::Open(options_, learner_.sensor().nominal_fps));
  }
  status_.hold_s = options_.session.facing.hold_s;
  status_.num_teacher_frames = session_->num_teacher_frames();
  status_.repetitions = options_.session.repetitions;
  status_.challenge = options_.session.challenge;
  summary_.teacher_facing = session_->teacher_facing();
  summary_.teacher_fps = session_->teacher_fps();
  summary_.teacher_frames = session_->num_teacher_frames();
  return absl::OkStatus();
}

absl::StatusOr<MirrorAppSummary> MirrorLoop::Run() {
  start_ = Clock::now();
  absl::Status failed;
  while (true) {
    absl::StatusOr<std::optional<LearnerFrame>> next = learner_.Next();
    if (!next.ok()) {
      failed = next.status();
      break;
    }
    if (!next->has_value()) {
      summary_.stopped = "learner ended";
      break;
    }
    absl::StatusOr<bool> go_on = Step(**next);
    if (!go_on.ok()) {
      failed = go_on.status();
      break;
    }
    if (!*go_on) break;
  }
  // A repetition cut short (the take ended, --seconds, the window closed)
  // still gets its report, marked incomplete.
  if (failed.ok()) {
    if (std::optional<MirrorFrame> ended = session_->EndEarly(last_stamp_ns_)) Record(*ended);
  }
  const absl::Status finished = Finish();
  if (!failed.ok()) return failed;
  if (!finished.ok()) return finished;
  return summary_;
}

absl::StatusOr<bool> MirrorLoop::Step(const LearnerFrame& frame) {
  if (!first_stamp_ns_) first_stamp_ns_ = frame.stamp_ns;
  last_stamp_ns_ = frame.stamp_ns;
  if (options_.run_seconds > 0 &&
      (frame.stamp_ns - *first_stamp_ns_) * 1e-9 >= options_.run_seconds) {
    summary_.stopped = "seconds";
    return false;
  }
  ASSIGN_OR_RETURN(const MirrorFrame mirror,
                   session_->Update(frame.stamp_ns, frame.skeleton_in_color, &frame.joint_seen,
                                    frame.people_in_view));
  Record(mirror);
  if (options_.teacher_joints != TeacherJoints::kStored && mirror.state == MirrorState::kPlaying &&
      previous_state_ != MirrorState::kPlaying) {
    RETURN_IF_ERROR(UseTrackedTeacher());
  }
  previous_state_ = mirror.state;
  status_.people_in_view = frame.people_in_view;
  if (frame.skeleton_in_color || !last_seen_stamp_ns_) last_seen_stamp_ns_ = frame.stamp_ns;
  status_.learner_missing_s = (frame.stamp_ns - *last_seen_stamp_ns_) * 1e-9;
  status_.teacher_frame_has_skeleton = mirror.state != MirrorState::kPlaying ||
                                       session_->TeacherFrameHasSkeleton(mirror.teacher_frame);
  if (mirror.state != MirrorState::kPlaying) FollowLearner(frame);
  ASSIGN_OR_RETURN(RgbImage image, Compose(frame, mirror));
  if (observer_) observer_({&frame, &mirror, &image, teacher_camera_});
  if (sink_->is_window()) {
    RETURN_IF_ERROR(teacher_->ReleaseCurrent());
    if (!learner_.sensor().live && options_.pace_recorded) Pace(frame.stamp_ns);
  }
  const Clock::time_point output_start = Clock::now();
  ASSIGN_OR_RETURN(const bool go_on, sink_->Put(std::move(image), summary_.frames));
  output_s_ += SecondsSince(output_start);
  if (learner_.sensor().live && frame.host_stamp_ns > 0) {
    latency_ms_.push_back(1e-6 * static_cast<double>(WallNowNs() - frame.host_stamp_ns));
  }
  ++summary_.frames;
  if (frame.skeleton_in_color) ++summary_.frames_with_learner;
  if (!go_on) {
    summary_.stopped = "window closed";
    return false;
  }
  if (mirror.state == MirrorState::kFinished) {
    summary_.stopped = "repetitions done";
    return false;
  }
  return true;
}

absl::Status MirrorLoop::UseTrackedTeacher() {
  // Views in steps of 15 degrees, each tracked once and kept.
  const double yaw_deg = session_->locked_learner_yaw_deg().value_or(0.0);
  const int view = static_cast<int>(std::lround(yaw_deg / 15.0)) * 15;
  auto found = tracked_teacher_by_view_.find(view);
  if (found == tracked_teacher_by_view_.end()) {
    const Clock::time_point start = Clock::now();
    TeacherTrackingOptions tracking = options_.teacher_tracking;
    tracking.view_yaw_deg = view;
    tracking.tracker.refine = options_.teacher_joints == TeacherJoints::kTrackedRefined;
    ASSIGN_OR_RETURN(std::vector<body::SkeletonPose> tracked,
                     TeacherSkeletonsAsTracked(data_, tracking));
    found = tracked_teacher_by_view_.emplace(view, std::move(tracked)).first;
    summary_.teacher_tracking_s += SecondsSince(start);
    ++summary_.teacher_views_tracked;
  }
  return session_->SetComparisonTeacher(found->second);
}

void MirrorLoop::Record(const MirrorFrame& mirror) {
  summary_.final_state = mirror.state;
  if (!mirror.finished_report) return;
  summary_.reports.push_back(*mirror.finished_report);
  status_.finished_mean_error_deg.push_back(mirror.finished_report->mean_error_deg);
  status_.last_corrections.clear();
  status_.last_not_graded.clear();
  if (const std::optional<Grade>& grade = mirror.finished_report->grade) {
    for (const Correction& c : grade->corrections) status_.last_corrections.push_back(c.text);
    // One line per reason: "left upper arm, left lower arm: hidden from the
    // sensor".
    std::map<std::string, std::string> by_reason;
    for (int p = 0; p < kNumBodyParts; ++p) {
      const PartGrade& part = grade->parts[p];
      if (part.graded) continue;
      std::string& parts = by_reason[part.not_graded_reason];
      absl::StrAppend(&parts, parts.empty() ? "" : ", ", PartWords(BodyPartAt(p)));
    }
    for (const auto& [reason, parts] : by_reason) {
      status_.last_not_graded.push_back(absl::StrCat(parts, ": ", reason));
    }
  }
  if (mirror.report_files) summary_.report_files.push_back(*mirror.report_files);
  if (!mirror.report_status.ok()) {
    summary_.report_problems.push_back(std::string(mirror.report_status.message()));
  }
}

void MirrorLoop::FollowLearner(const LearnerFrame& frame) {
  if (!frame.skeleton_in_color) return;
  if (!IsJointUsable(*frame.skeleton_in_color, body::KinectV2Joint::kSpineBase)) return;
  learner_anchor_in_color_ =
      frame.skeleton_in_color->position_m[body::Index(body::KinectV2Joint::kSpineBase)];
}

render::RenderCamera MirrorLoop::TeacherCamera(const MirrorFrame& mirror) const {
  Eigen::Isometry3d world_from_camera = session_->world_from_virtual_camera();
  if (options_.follow_learner_position && learner_anchor_in_color_) {
    world_from_camera = AnchoredVirtualCamera(
        world_from_camera, mirror.teacher_turn.turned_from_original * teacher_anchor_in_world_,
        *learner_anchor_in_color_);
  }
  const CameraIntrinsics& color = learner_.sensor().color_intrinsics;
  const PanelRect panel = TeacherPanel(options_.composition);
  const PanelMapping mapping =
      PanelMapping::Cover(color.width, color.height, panel.width, panel.height);
  return PanelRenderCamera(color, mapping,
                           TeacherRenderPose(world_from_camera, mirror.teacher_turn));
}

absl::StatusOr<CameraIntrinsics> MirrorLoop::IntrinsicsFor(const LearnerFrame& frame) {
  const CameraIntrinsics& calibrated = learner_.sensor().color_intrinsics;
  if (!frame.color ||
      (frame.color->width == calibrated.width && frame.color->height == calibrated.height)) {
    return calibrated;
  }
  const std::pair<int, int> size(frame.color->width, frame.color->height);
  auto found = intrinsics_by_size_.find(size);
  if (found != intrinsics_by_size_.end()) return found->second;
  ASSIGN_OR_RETURN(const CameraIntrinsics scaled,
                   ScaledIntrinsics(calibrated, size.first, size.second));
  intrinsics_by_size_[size] = scaled;
  return scaled;
}

absl::StatusOr<RgbImage> MirrorLoop::Compose(const LearnerFrame& frame, const MirrorFrame& mirror) {
  const Clock::time_point render_start = Clock::now();
  RgbImage teacher_color;
  MaskImage teacher_label;
  teacher_camera_ = TeacherCamera(mirror);
  RETURN_IF_ERROR(
      teacher_->Render(mirror.teacher_frame, teacher_camera_, &teacher_color, &teacher_label));
  render_s_ += SecondsSince(render_start);
  const Clock::time_point compose_start = Clock::now();
  CompositionInput input;
  input.learner_color = frame.color ? &*frame.color : nullptr;
  input.learner_in_color = frame.skeleton_in_color ? &*frame.skeleton_in_color : nullptr;
  ASSIGN_OR_RETURN(input.color_intrinsics, IntrinsicsFor(frame));
  input.teacher_color = &teacher_color;
  input.teacher_label = &teacher_label;
  input.frame = &mirror;
  input.status_lines = StatusLines(mirror, status_);
  input.timeline_fraction = TimelineFraction(mirror, status_);
  ASSIGN_OR_RETURN(RgbImage image, ComposeMirrorImage(input, options_.composition));
  compose_s_ += SecondsSince(compose_start);
  return image;
}

void MirrorLoop::Pace(int64_t stamp_ns) const {
  const double due_s = (stamp_ns - *first_stamp_ns_) * 1e-9;
  const double wait_s = due_s - SecondsSince(start_);
  if (wait_s > 0) std::this_thread::sleep_for(std::chrono::duration<double>(wait_s));
}

absl::Status MirrorLoop::Finish() {
  absl::Status finished;
  if (sink_ != nullptr) finished = sink_->Finish(&summary_);
  summary_.frames_dropped = learner_.frames_dropped();
  summary_.seconds = SecondsSince(start_);
  summary_.fps = summary_.seconds > 0 ? summary_.frames / summary_.seconds : 0.0;
  if (summary_.frames > 0) {
    summary_.render_ms_mean = 1e3 * render_s_ / summary_.frames;
    summary_.compose_ms_mean = 1e3 * compose_s_ / summary_.frames;
    summary_.output_ms_mean = 1e3 * output_s_ / summary_.frames;
  }
  const client::Distribution latency = client::Distribute(latency_ms_);
  summary_.latency_frames = static_cast<int>(latency.count);
  summary_.latency_ms_mean = latency.mean_ms;
  summary_.latency_ms_p50 = latency.p50_ms;
  summary_.latency_ms_p95 = latency.p95_ms;
  summary_.latency_ms_max = latency.max_ms;
  return finished;
}

}  // namespace

absl::Status MirrorAppOptions::Validate() const {
  RETURN_IF_ERROR(session.Validate());
  RETURN_IF_ERROR(composition.Validate());
  if (teacher.msaa_samples != 0 && teacher.msaa_samples != 2 && teacher.msaa_samples != 4 &&
      teacher.msaa_samples != 8) {
    return absl::InvalidArgumentError("teacher msaa_samples must be 0, 2, 4 or 8");
  }
  if (png_every < 1) return absl::InvalidArgumentError("--every must be >= 1");
  if (!(run_seconds >= 0.0) || !std::isfinite(run_seconds)) {
    return absl::InvalidArgumentError("--seconds must be >= 0");
  }
  return absl::OkStatus();
}

absl::StatusOr<MirrorAppSummary> RunMirrorApp(const Reenactment& teacher, LearnerSource& learner,
                                              const MirrorAppOptions& options,
                                              const MirrorFrameObserver& observer) {
  MirrorLoop loop(teacher, learner, options, observer);
  RETURN_IF_ERROR(loop.Init());
  return loop.Run();
}

}  // namespace reenact::mirror
