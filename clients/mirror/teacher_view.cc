#include "clients/mirror/teacher_view.h"

#include <cmath>

#include "absl/strings/str_cat.h"
#include "common/base/status_macros.h"
#include "common/geometry/camera.h"
#include "common/render/intrinsics_camera.h"

namespace reenact::mirror {

absl::StatusOr<std::vector<body::SkeletonPose>> TeacherSkeletons(const Reenactment& data) {
  std::vector<body::SkeletonPose> poses;
  poses.reserve(data.frames.size());
  int joints = 0;
  for (const ReenactmentFrame& frame : data.frames) {
    body::SkeletonPose pose;
    for (int j = 0; j < body::kNumKinectV2Joints; ++j) {
      pose.position_m[j] = Eigen::Vector3d::Zero();
      if (j >= static_cast<int>(frame.joints_in_world_m.size())) continue;
      const Eigen::Vector3d& p = frame.joints_in_world_m[j];
      if (!p.allFinite()) continue;
      pose.position_m[j] = p;
      pose.valid[j] = true;
      ++joints;
    }
    poses.push_back(pose);
  }
  if (poses.empty()) {
    return absl::FailedPreconditionError(
        absl::StrCat("reenactment ", data.info.reenactment_id, " has no instant"));
  }
  if (joints == 0) {
    return absl::FailedPreconditionError(
        absl::StrCat("reenactment ", data.info.reenactment_id,
                     " carries no skeleton (joints_in_world_m) to compare the learner with"));
  }
  return poses;
}

absl::StatusOr<TeacherJoints> ParseTeacherJoints(std::string_view name) {
  if (name == "stored") return TeacherJoints::kStored;
  if (name == "tracked") return TeacherJoints::kTracked;
  if (name == "tracked-refined") return TeacherJoints::kTrackedRefined;
  return absl::InvalidArgumentError(
      absl::StrCat("--teacher-joints: expected 'stored', 'tracked' or 'tracked-refined', got '",
                   std::string(name), "'"));
}

absl::StatusOr<std::vector<body::SkeletonPose>> TeacherSkeletonsAsTracked(
    const Reenactment& data, const TeacherTrackingOptions& options) {
  if (!(options.distance_m > 0.5 && options.distance_m < 10.0) ||
      !(options.height_m > 0.0 && options.height_m < 3.0)) {
    return absl::InvalidArgumentError("the virtual sensor must stand 0.5-10 m away, 0-3 m high");
  }
  ASSIGN_OR_RETURN(const std::vector<body::SkeletonPose> stored_in_world, TeacherSkeletons(data));
  // Up is the teacher's own mean spine direction, not world +Y: the world of
  // an imported recording is its depth camera's frame (y down).
  Eigen::Vector3d spine_sum = Eigen::Vector3d::Zero();
  for (const body::SkeletonPose& pose : stored_in_world) {
    const int base = body::Index(body::KinectV2Joint::kSpineBase);
    const int top = body::Index(body::KinectV2Joint::kSpineShoulder);
    if (!pose.valid[base] || !pose.valid[top]) continue;
    const Eigen::Vector3d spine = pose.position_m[top] - pose.position_m[base];
    if (spine.allFinite() && spine.norm() > 0.05) spine_sum += spine.normalized();
  }
  if (spine_sum.norm() < 1e-6) {
    return absl::FailedPreconditionError("the teacher has no frame with a spine to stand upright");
  }
  const Eigen::Quaterniond upright_from_world =
      Eigen::Quaterniond::FromTwoVectors(spine_sum.normalized(), Eigen::Vector3d::UnitY());
  std::vector<body::SkeletonPose> stored = stored_in_world;
  for (body::SkeletonPose& pose : stored) {
    for (auto& p : pose.position_m) p = upright_from_world * p;
  }
  const double fps = data.info.fps > 0.0 && std::isfinite(data.info.fps) ? data.info.fps : 30.0;
  ASSIGN_OR_RETURN(const TeacherFacing facing, MeasureTeacherFacing(stored, fps, 0.5));
  if (!std::isfinite(options.view_yaw_deg)) {
    return absl::InvalidArgumentError("the view yaw must be finite");
  }
  // The bearing that shows the teacher's start pose at view_yaw_deg: of the
  // two mirror-image bearings, the one whose measured facing is nearer.
  const body::SkeletonPose* start = nullptr;
  for (const body::SkeletonPose& pose : stored) {
    if (FacingYawInWorldDeg(pose)) {
      start = &pose;
      break;
    }
  }
  Eigen::Isometry3d world_from_camera = Eigen::Isometry3d::Identity();
  double best_miss_deg = 1e9;
  for (const double sign : {1.0, -1.0}) {
    // The lens height_m above a floor taken 1 m below the pivot.
    ASSIGN_OR_RETURN(
        const Eigen::Isometry3d candidate,
        PlaceVirtualCamera(facing.pivot_in_world,
                           facing.facing_yaw_world_deg + sign * options.view_yaw_deg,
                           options.distance_m, facing.pivot_in_world.y() - 1.0 + options.height_m));
    double miss_deg = 0.0;
    if (start != nullptr) {
      const Eigen::Isometry3d camera_from_world = candidate.inverse();
      body::SkeletonPose in_camera = *start;
      for (auto& p : in_camera.position_m) p = camera_from_world * p;
      const std::optional<double> yaw =
          FacingYawInSensorDeg(in_camera, camera_from_world.linear() * Eigen::Vector3d::UnitY());
      miss_deg = yaw ? std::abs(std::remainder(*yaw - options.view_yaw_deg, 360.0)) : 1e6;
    }
    if (miss_deg < best_miss_deg) best_miss_deg = miss_deg, world_from_camera = candidate;
  }
  // From the upright frame back to the reenactment's world.
  world_from_camera = Eigen::Isometry3d(upright_from_world.inverse()) * world_from_camera;
  const CameraIntrinsics intrinsics = KinectV2DepthIntrinsics();
  const render::RenderCamera camera =
      render::RenderCameraFromIntrinsics(intrinsics, world_from_camera);
  render::RendererOptions renderer_options;
  renderer_options.max_width = intrinsics.width;
  renderer_options.max_height = intrinsics.height;
  renderer_options.msaa_samples = 0;  // Depth and labels as a sensor sees them.
  ASSIGN_OR_RETURN(std::unique_ptr<render::OffscreenRenderer> renderer,
                   render::OffscreenRenderer::Create(renderer_options));
  ASSIGN_OR_RETURN(std::unique_ptr<view::ReenactmentRenderer> view,
                   view::ReenactmentRenderer::Create(data, renderer.get()));
  ASSIGN_OR_RETURN(std::unique_ptr<tracking::BodyTracker> tracker,
                   tracking::BodyTracker::Create(options.tracker));

  std::vector<body::SkeletonPose> poses;
  poses.reserve(data.frames.size());
  for (const ReenactmentFrame& frame : data.frames) {
    render::RenderOutputs out;
    out.requested = render::kRenderDepth | render::kRenderLabel;
    RETURN_IF_ERROR(view->Render(frame.frame_index, camera, &out));
    DepthImageMm depth(out.depth_m.width, out.depth_m.height);
    MaskImage labels(out.label.width, out.label.height);
    for (size_t i = 0; i < depth.data.size(); ++i) {
      const float z = out.depth_m.data[i];
      const bool actor = out.label.data[i] != 0 && z > 0.0f && z < 65.0f;
      depth.data[i] = actor ? static_cast<uint16_t>(std::lround(z * 1000.0f)) : 0;
      labels.data[i] = actor ? 1 : 0;  // One person, whatever part drew it.
    }
    ASSIGN_OR_RETURN(const std::vector<tracking::TrackedPerson> people,
                     tracker->Track(depth, intrinsics, &labels));
    body::SkeletonPose pose;
    for (auto& p : pose.position_m) p = Eigen::Vector3d::Zero();
    const tracking::TrackedPerson* best = nullptr;
    for (const tracking::TrackedPerson& person : people) {
      if (best == nullptr || person.num_pixels > best->num_pixels) best = &person;
    }
    if (best != nullptr) {
      for (int j = 0; j < body::kNumKinectV2Joints; ++j) {
        const tracking::TrackedJoint& joint = best->joints[j];
        if (joint.state == tracking::JointState::kNotTracked ||
            !joint.position_in_camera_m.allFinite()) {
          continue;
        }
        pose.position_m[j] = world_from_camera * joint.position_in_camera_m;
        pose.valid[j] = true;
      }
    }
    poses.push_back(pose);
  }
  return poses;
}

Eigen::Isometry3d TeacherRenderPose(const Eigen::Isometry3d& world_from_virtual_camera,
                                    const TeacherTurn& turn) {
  return turn.turned_from_original.inverse() * world_from_virtual_camera;
}

Eigen::Isometry3d AnchoredVirtualCamera(const Eigen::Isometry3d& world_from_virtual_camera,
                                        const Eigen::Vector3d& teacher_point_in_world,
                                        const Eigen::Vector3d& learner_point_in_color) {
  // camera_from_world * teacher = learner with the rotation R kept:
  // R^T (teacher - c) = learner  =>  c = teacher - R learner.
  Eigen::Isometry3d moved = world_from_virtual_camera;
  moved.translation() =
      teacher_point_in_world - world_from_virtual_camera.linear() * learner_point_in_color;
  return moved;
}

absl::StatusOr<std::unique_ptr<TeacherRenderer>> TeacherRenderer::Create(
    const Reenactment& data, int max_width, int max_height, const TeacherRendererOptions& options) {
  std::unique_ptr<TeacherRenderer> teacher(new TeacherRenderer(data));
  render::RendererOptions renderer_options;
  renderer_options.max_width = max_width;
  renderer_options.max_height = max_height;
  renderer_options.msaa_samples = options.msaa_samples;
  ASSIGN_OR_RETURN(teacher->renderer_, render::OffscreenRenderer::Create(renderer_options));
  render::ShadingOptions shading;
  shading.background_srgb = options.background_srgb;
  RETURN_IF_ERROR(teacher->renderer_->SetShading(shading));
  view::ReenactmentRendererOptions view_options;
  view_options.mode = options.mode;
  ASSIGN_OR_RETURN(teacher->view_,
                   view::ReenactmentRenderer::Create(data, teacher->renderer_.get(), view_options));
  return teacher;
}

absl::Status TeacherRenderer::Render(int index, const render::RenderCamera& camera,
                                     RgbImage* colour, MaskImage* label) {
  if (index < 0 || index >= static_cast<int>(data_.frames.size())) {
    return absl::OutOfRangeError(
        absl::StrCat("teacher instant ", index, " of ", data_.frames.size()));
  }
  render::RenderOutputs out;
  out.requested = render::kRenderColour | render::kRenderLabel;
  RETURN_IF_ERROR(view_->Render(data_.frames[index].frame_index, camera, &out));
  *colour = std::move(out.colour);
  *label = std::move(out.label);
  return absl::OkStatus();
}

}  // namespace reenact::mirror
