// The teacher of the mirror: its skeleton per instant (what the session
// compares against) and its reenactment drawn turned and seen from the
// virtual camera (what the learner sees).
//
// Turning without touching the renderer: the session asks for every teacher
// point p to be drawn at T p (T = TeacherTurn::turned_from_original) seen
// from the virtual camera V (world_from_camera). A camera at T^-1 V sees the
// untouched world exactly as V sees the turned one (camera_from_world
// V^-1 T), so the reenactment is drawn as stored with world_from_camera =
// T^-1 V. Body-model reenactments use their atlas, rigid ones VDTM
// (view::ReenactmentRenderer).
#pragma once

#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "clients/mirror/facing.h"
#include "clients/view/reenactment_renderer.h"
#include "common/base/image.h"
#include "common/body/joint_set.h"
#include "common/model/reenactment.h"
#include "common/render/offscreen_renderer.h"
#include "common/tracking/body_tracker.h"

namespace reenact::mirror {

// The teacher's skeleton per instant, world (+Y up, metres), from
// PartFrame.joints_in_world_m in Kinect v2 order; a missing or non-finite
// joint is invalid. FailedPrecondition when the reenactment has no instant
// or no instant has a joint (it carries no skeleton to compare with).
absl::StatusOr<std::vector<body::SkeletonPose>> TeacherSkeletons(const Reenactment& data);

// Which teacher joints the learner is compared with: the reenactment's
// stored joints, or its joints as our tracker finds them in it drawn as
// depth (TeacherSkeletonsAsTracked), without or with the tracker's model
// refinement (BodyTrackerOptions::refine). Pick the tracker settings that
// found the learner, so that both go through the same pipeline.
enum class TeacherJoints { kStored, kTracked, kTrackedRefined };
// "stored", "tracked", "tracked-refined"; InvalidArgument otherwise.
absl::StatusOr<TeacherJoints> ParseTeacherJoints(std::string_view name);

// Options of TeacherSkeletonsAsTracked.
struct TeacherTrackingOptions {
  // The virtual depth sensor (Kinect v2 depth intrinsics, 512x424):
  // `distance_m` from the teacher's pivot, the lens `height_m` above a floor
  // taken 1 m below the pivot, up being the teacher's mean spine direction
  // (the world of an imported recording need not have +Y up).
  double distance_m = 2.5;
  double height_m = 1.0;
  // The teacher's facing relative to the virtual sensor (degrees, the
  // convention of FacingYawInSensorDeg): the learner's facing relative to
  // theirs, so that the tracker sees both from the same side.
  double view_yaw_deg = 0.0;
  // The tracker: the learner's (the shipped network by default).
  tracking::BodyTrackerOptions tracker;
};

// The teacher's skeleton per instant as the learner's tracker reports it, so
// that the mirror compares the two through the same joint definitions and
// the same pipeline: each instant is drawn as depth (and its actor mask)
// from a virtual depth sensor that sees the teacher's start facing at
// options.view_yaw_deg, and tracked
// as reenactd tracks a sensor (tracking::BodyTracker, with history). The
// joints go back to the world; a joint the tracker did not track is invalid,
// and an instant where it found nobody has none. Needed because a fitted
// body's joints and a tracker's are not the same points: on the built-in
// kick the stored joints of a body reenactment read 14 degrees against the
// same body tracked from depth facing the sensor, where two tracked takes
// read under 2. The errors of TeacherSkeletons, Unavailable without EGL, and
// the tracker's.
absl::StatusOr<std::vector<body::SkeletonPose>> TeacherSkeletonsAsTracked(
    const Reenactment& data, const TeacherTrackingOptions& options = {});

// world_from_camera of the render camera: T^-1 V (see the top).
Eigen::Isometry3d TeacherRenderPose(const Eigen::Isometry3d& world_from_virtual_camera,
                                    const TeacherTurn& turn);

// The virtual camera moved, keeping its orientation, so that the turned
// teacher's `teacher_point_in_world` (already turned) appears where the
// learner's `learner_point_in_color` is in the sensor's colour camera: the
// teacher then stands to the camera as the learner stands to the sensor, in
// place as well as in facing, and a ghost falls on the learner.
Eigen::Isometry3d AnchoredVirtualCamera(const Eigen::Isometry3d& world_from_virtual_camera,
                                        const Eigen::Vector3d& teacher_point_in_world,
                                        const Eigen::Vector3d& learner_point_in_color);

struct TeacherRendererOptions {
  // Texturing of rigid-part reenactments (body reenactments use their atlas).
  view::TextureMode mode = view::TextureMode::kVdtm;
  // Multisampling: 0, 2, 4 or 8.
  int msaa_samples = 4;
  // Where nothing is drawn, sRGB in [0,1].
  Eigen::Vector3f background_srgb{0.12f, 0.12f, 0.14f};
};

// Draws the teacher headless (EGL). One thread at a time.
class TeacherRenderer {
 public:
  // `data` must outlive the renderer. Unavailable without an EGL/GL 3.3
  // context; InvalidArgument for a reenactment the renderer cannot draw.
  static absl::StatusOr<std::unique_ptr<TeacherRenderer>> Create(
      const Reenactment& data, int max_width, int max_height,
      const TeacherRendererOptions& options = {});

  // Draws teacher instant `index` (into data.frames) seen by `camera`:
  // colour and label (non-zero where the teacher is).
  absl::Status Render(int index, const render::RenderCamera& camera, RgbImage* colour,
                      MaskImage* label);
  // Frees the GL context for another thread or a window (ImageWindow).
  absl::Status ReleaseCurrent() { return renderer_->ReleaseCurrent(); }
  std::string Description() const { return renderer_->Description(); }

 private:
  explicit TeacherRenderer(const Reenactment& data) : data_(data) {}
  const Reenactment& data_;
  std::unique_ptr<render::OffscreenRenderer> renderer_;
  std::unique_ptr<view::ReenactmentRenderer> view_;
};

}  // namespace reenact::mirror
