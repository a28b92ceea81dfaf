// The magic mirror application's loop (thesis sec. 4.5.1): per learner frame,
// the MirrorSession's decision (facing, teacher turn, repetition, errors),
// the teacher drawn turned from the virtual camera, the composed picture
// (mirror_compose.h), and out to a window or to PNG files and an MP4.
//
// Departure from the session's fixed virtual camera (optional, on by
// default): the camera keeps its orientation but is moved so that the
// teacher's first-instant SpineBase appears where the learner's SpineBase is
// in the sensor (AnchoredVirtualCamera), following the learner while the
// facing is read and fixed while a repetition plays. The thesis overlays
// the teacher on the learner's image; without this the ghost would stand
// wherever the virtual camera happens to put it. Turning is unaffected: the
// facing relative to the optical axis does not depend on where the camera is.
#pragma once

#include <functional>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "clients/mirror/learner_source.h"
#include "clients/mirror/mirror_compose.h"
#include "clients/mirror/mirror_session.h"
#include "clients/mirror/teacher_view.h"
#include "common/model/reenactment.h"

namespace reenact::mirror {

struct MirrorAppOptions {
  // The session (repetitions, hold, tolerance, DTW, speed, challenge,
  // report_dir). up_in_sensor is replaced by the learner sensor's up.
  MirrorSessionOptions session;
  // Output size, layout, HUD.
  CompositionOptions composition;
  // Texturing and multisampling of the teacher.
  TeacherRendererOptions teacher;
  // kTracked, kTrackedRefined: compare the learner with the teacher's joints
  // as the learner's tracker finds them in the teacher drawn as depth
  // (TeacherSkeletonsAsTracked), seen from the learner's locked facing (in steps of 15 degrees;
  // each view is tracked when a repetition first needs it, which holds that frame up for about a
  // second), instead of the joints the reenactment stores: for a learner tracked from depth, so
  // that both go through the same joint definitions.
  TeacherJoints teacher_joints = TeacherJoints::kStored;
  TeacherTrackingOptions teacher_tracking;
  // Move the virtual camera so the teacher stands where the learner stands
  // (see the top); false: the session's camera as it is.
  bool follow_learner_position = true;
  // Empty: show the frames in a window. Else a folder (created) for
  // frame_NNNNN.png (NNNNN = frame number) and video.mp4.
  std::string render_to;
  // Write every png_every-th frame as a PNG (>= 1); the MP4 gets them all.
  int png_every = 1;
  bool mp4 = true;
  // Stop once this much learner time (seconds, from its first frame) has
  // passed; 0: no limit.
  double run_seconds = 0.0;
  // Window and a recorded learner: show frames at the pace of their stamps
  // (false: as fast as they are drawn).
  bool pace_recorded = true;

  // InvalidArgument naming the first bad field.
  absl::Status Validate() const;
};

struct MirrorAppSummary {
  // Frames drawn, and of them those with a tracked learner.
  int frames = 0;
  int frames_with_learner = 0;
  // Why it stopped: "learner ended", "repetitions done", "seconds",
  // "window closed".
  std::string stopped;
  MirrorState final_state = MirrorState::kWaitingForLearner;
  // The finished repetitions, in order, with the files written for them
  // (when report_dir is set) and problems writing them.
  std::vector<RepetitionReport> reports;
  std::vector<RepetitionFiles> report_files;
  std::vector<std::string> report_problems;
  // The teacher as the session measured it.
  TeacherFacing teacher_facing;
  double teacher_fps = 0.0;
  int teacher_frames = 0;
  // Folder output.
  int pngs = 0;
  std::string first_png;
  std::string mp4_path;     // Empty when none was written.
  std::string mp4_problem;  // Why not, when one was asked for.
  // Learner frames dropped by a live source that the app could not keep up with.
  int64_t frames_dropped = 0;
  // Wall time of the loop and frames per second; mean milliseconds per frame
  // drawing the teacher, composing, and handing the frame on (showing it, or
  // waiting for room in the writer's queue: PNG and MP4 are written on a
  // thread of their own while the next frames are drawn).
  double seconds = 0.0;
  double fps = 0.0;
  double render_ms_mean = 0.0;
  double compose_ms_mean = 0.0;
  double output_ms_mean = 0.0;
  std::string renderer;  // GL_VERSION / GL_RENDERER.
  // A live learner: milliseconds from each frame's arrival on the capture
  // host (LearnerFrame::host_stamp_ns) to its picture handed on (shown in
  // the window, or queued for the files), over the frames that carry the
  // stamp; the capture host's wall clock against this one's, so meaningful
  // when both are one machine or their clocks are synchronised. 0 without.
  int latency_frames = 0;
  // --teacher-joints tracked: views of the teacher tracked, and the seconds
  // it took (frames were held up meanwhile).
  int teacher_views_tracked = 0;
  double teacher_tracking_s = 0.0;
  double latency_ms_mean = 0.0;
  double latency_ms_p50 = 0.0;
  double latency_ms_p95 = 0.0;
  double latency_ms_max = 0.0;
};

// One drawn frame, for observers (tests, tools).
struct ObservedFrame {
  const LearnerFrame* learner = nullptr;
  const MirrorFrame* mirror = nullptr;
  // The composed image.
  const RgbImage* image = nullptr;
  // The camera the teacher was rendered with (unflipped, TeacherPanel's
  // size; its pose already holds the turn: TeacherRenderPose).
  render::RenderCamera teacher_camera;
};
using MirrorFrameObserver = std::function<void(const ObservedFrame&)>;

// Runs the mirror until the learner's stream ends, the repetitions are done,
// run_seconds pass or the window is closed (Esc or Q). InvalidArgument for
// bad options; FailedPrecondition for a teacher without a skeleton or frame
// rate; Unavailable without GL or (window) a display; the learner's stream
// error; PermissionDenied for an unwritable folder. A failed MP4 does not
// fail the run (mp4_problem says why); neither do failed report files
// (report_problems).
absl::StatusOr<MirrorAppSummary> RunMirrorApp(const Reenactment& teacher, LearnerSource& learner,
                                              const MirrorAppOptions& options,
                                              const MirrorFrameObserver& observer = {});

}  // namespace reenact::mirror
