#include "clients/mirror/teacher_view.h"

#include "absl/strings/str_cat.h"
#include "common/base/status_macros.h"

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
