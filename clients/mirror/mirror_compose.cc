#include "clients/mirror/mirror_compose.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <optional>

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "clients/mirror/body_parts.h"
#include "clients/viewer/hud.h"

namespace reenact::mirror {
namespace {

cv::Mat Wrap(RgbImage* image) {
  return cv::Mat(image->height, image->width, CV_8UC3, image->data.data());
}

cv::Mat WrapConst(const RgbImage& image) {
  return cv::Mat(image.height, image.width, CV_8UC3, const_cast<uint8_t*>(image.data.data()));
}

// Our images are RGB, so OpenCV's scalars are given as (r, g, b).
cv::Scalar ToScalar(const Srgb8& colour) { return cv::Scalar(colour.r, colour.g, colour.b); }

cv::Rect ToRect(const PanelRect& rect) { return cv::Rect(rect.x, rect.y, rect.width, rect.height); }

// The learner's colour image into `panel`: scaled, cropped, flipped.
void DrawLearnerImage(const RgbImage& color, const PanelMapping& m, cv::Mat panel) {
  const double s = m.scale;
  // x_panel = (panel_width - 1) - (s (u + 0.5) - 0.5 - crop_x); y likewise unflipped.
  const cv::Mat affine =
      (cv::Mat_<double>(2, 3) << -s, 0.0, m.panel_width - 0.5 - 0.5 * s + m.crop_x_px, 0.0, s,
       0.5 * s - 0.5 - m.crop_y_px);
  cv::warpAffine(WrapConst(color), panel, affine, panel.size(), cv::INTER_LINEAR,
                 cv::BORDER_CONSTANT, cv::Scalar(0, 0, 0));
}

// The body part whose bone goes from `parent` to `child`, if any.
std::optional<BodyPart> PartOfBone(body::KinectV2Joint parent, body::KinectV2Joint child) {
  for (int p = 0; p < kNumBodyParts; ++p) {
    const PartBone bone = BodyPartBone(BodyPartAt(p));
    if (bone.from == parent && bone.to == child) return BodyPartAt(p);
  }
  return std::nullopt;
}

// Joint pixels in the output image (nullopt where not drawn).
std::array<std::optional<cv::Point2d>, body::kNumKinectV2Joints> JointPixels(
    const body::SkeletonPose& pose, const CameraIntrinsics& intrinsics, const PanelMapping& m,
    const PanelRect& panel) {
  std::array<std::optional<cv::Point2d>, body::kNumKinectV2Joints> pixels;
  for (int j = 0; j < body::kNumKinectV2Joints; ++j) {
    if (!IsJointUsable(pose, static_cast<body::KinectV2Joint>(j))) continue;
    const std::optional<Eigen::Vector2d> pixel = intrinsics.Project(pose.position_m[j]);
    if (!pixel) continue;
    const Eigen::Vector2d in_panel = m.ToPanel(*pixel);
    pixels[j] = cv::Point2d(in_panel.x() + panel.x, in_panel.y() + panel.y);
  }
  return pixels;
}

// Fixed-point coordinates for anti-aliased drawing at sub-pixel positions.
constexpr int kShift = 4;
cv::Point Fixed(const cv::Point2d& p) {
  return cv::Point(static_cast<int>(std::lround(p.x * (1 << kShift))),
                   static_cast<int>(std::lround(p.y * (1 << kShift))));
}

// `image` by value: a cv::Mat is a shared header, so drawing into the copy
// draws into the caller's pixels (and callers pass views such as image(roi)).
void DrawSkeleton(const CompositionInput& input, const CompositionOptions& options,
                  // NOLINTNEXTLINE(performance-unnecessary-value-param)
                  const PanelMapping& m, const PanelRect& panel, cv::Mat image) {
  const auto pixels = JointPixels(*input.learner_in_color, input.color_intrinsics, m, panel);
  const Srgb8 grey{128, 128, 128};
  auto joint_colour = [&](int j) { return input.frame ? input.frame->joint_color[j] : grey; };
  cv::Mat clipped = image(ToRect(panel));
  const cv::Point2d origin(panel.x, panel.y);
  for (int j = 0; j < body::kNumKinectV2Joints; ++j) {
    const auto child = static_cast<body::KinectV2Joint>(j);
    const std::optional<body::KinectV2Joint> parent = body::KinectV2Parent(child);
    if (!parent || !pixels[j] || !pixels[body::Index(*parent)]) continue;
    const std::optional<BodyPart> part = PartOfBone(*parent, child);
    const Srgb8 colour =
        part && input.frame ? input.frame->part_color[Index(*part)] : joint_colour(j);
    cv::line(clipped, Fixed(*pixels[body::Index(*parent)] - origin), Fixed(*pixels[j] - origin),
             ToScalar(colour), options.bone_width_px, cv::LINE_AA, kShift);
  }
  for (int j = 0; j < body::kNumKinectV2Joints; ++j) {
    if (!pixels[j]) continue;
    const cv::Point centre = Fixed(*pixels[j] - origin);
    cv::circle(clipped, centre, (options.joint_radius_px + 1) << kShift, cv::Scalar(20, 20, 20),
               cv::FILLED, cv::LINE_AA, kShift);
    cv::circle(clipped, centre, options.joint_radius_px << kShift, ToScalar(joint_colour(j)),
               cv::FILLED, cv::LINE_AA, kShift);
  }
}

absl::Status CheckTeacher(const CompositionInput& input, const PanelRect& panel) {
  if (input.teacher_color == nullptr) return absl::OkStatus();
  if (input.teacher_color->width != panel.width || input.teacher_color->height != panel.height) {
    return absl::InvalidArgumentError(absl::StrCat("teacher image is ", input.teacher_color->width,
                                                   "x", input.teacher_color->height, ", the panel ",
                                                   panel.width, "x", panel.height));
  }
  if (input.teacher_label != nullptr &&
      (input.teacher_label->width != panel.width || input.teacher_label->height != panel.height)) {
    return absl::InvalidArgumentError("teacher label image does not match the panel");
  }
  return absl::OkStatus();
}

// Side layout: the teacher's render, flipped, fills its panel.
// NOLINTNEXTLINE(performance-unnecessary-value-param): a shared header, as above.
void DrawTeacherPanel(const CompositionInput& input, const PanelRect& panel, cv::Mat image) {
  cv::Mat roi = image(ToRect(panel));
  cv::flip(WrapConst(*input.teacher_color), roi, 1);
}

// Ghost layout: the flipped teacher blended over the mirror where drawn.
void DrawTeacherGhost(const CompositionInput& input, double alpha, const PanelRect& panel,
                      RgbImage* image) {
  const RgbImage& teacher = *input.teacher_color;
  const MaskImage* label = input.teacher_label;
  const int a = static_cast<int>(std::lround(alpha * 256));
  for (int y = 0; y < panel.height; ++y) {
    for (int x = 0; x < panel.width; ++x) {
      const int source_x = panel.width - 1 - x;
      if (label != nullptr && label->at(source_x, y) == 0) continue;
      for (int c = 0; c < 3; ++c) {
        uint8_t& out = image->at(panel.x + x, panel.y + y, c);
        out = static_cast<uint8_t>((out * (256 - a) + teacher.at(source_x, y, c) * a) >> 8);
      }
    }
  }
}

// Whole degrees for the status line, without a "-0".
double WholeDeg(double angle_deg) {
  const double rounded = std::round(angle_deg);
  return rounded == 0.0 ? 0.0 : rounded;
}

void DrawHud(const CompositionInput& input, RgbImage* image) {
  for (size_t i = 0; i < input.status_lines.size(); ++i) {
    viewer::DrawStatusLine(input.status_lines[i], static_cast<int>(i), image);
  }
  if (input.timeline_fraction >= 0.0) viewer::DrawTimeline(input.timeline_fraction, image);
}

}  // namespace

absl::StatusOr<MirrorLayout> ParseMirrorLayout(const std::string& name) {
  if (name == "side") return MirrorLayout::kSide;
  if (name == "ghost") return MirrorLayout::kGhost;
  return absl::InvalidArgumentError(
      absl::StrCat("--layout: expected 'side' or 'ghost', got '", name, "'"));
}

std::string MirrorLayoutName(MirrorLayout layout) {
  return layout == MirrorLayout::kSide ? "side" : "ghost";
}

absl::Status CompositionOptions::Validate() const {
  if (width < 64 || height < 64 || width > 8192 || height > 8192 || width % 2 != 0 ||
      height % 2 != 0) {
    return absl::InvalidArgumentError("width and height must be even, 64..8192 pixels");
  }
  if (!(ghost_alpha > 0.0 && ghost_alpha <= 1.0)) {
    return absl::InvalidArgumentError("ghost alpha must be in (0, 1]");
  }
  if (joint_radius_px < 1 || bone_width_px < 1 || joint_radius_px > 64 || bone_width_px > 64) {
    return absl::InvalidArgumentError("joint radius and bone width must be 1..64 pixels");
  }
  return absl::OkStatus();
}

PanelRect MirrorPanel(const CompositionOptions& options) {
  if (options.layout == MirrorLayout::kGhost) return {0, 0, options.width, options.height};
  return {0, 0, options.width / 2, options.height};
}

PanelRect TeacherPanel(const CompositionOptions& options) {
  if (options.layout == MirrorLayout::kGhost) return {0, 0, options.width, options.height};
  return {options.width / 2, 0, options.width - options.width / 2, options.height};
}

PanelMapping PanelMapping::Cover(int image_width, int image_height, int panel_width,
                                 int panel_height) {
  PanelMapping m;
  m.image_width = image_width;
  m.image_height = image_height;
  m.panel_width = panel_width;
  m.panel_height = panel_height;
  m.scale = std::max(static_cast<double>(panel_width) / std::max(image_width, 1),
                     static_cast<double>(panel_height) / std::max(image_height, 1));
  m.crop_x_px = 0.5 * (m.scale * image_width - panel_width);
  m.crop_y_px = 0.5 * (m.scale * image_height - panel_height);
  return m;
}

Eigen::Vector2d PanelMapping::ToPanel(const Eigen::Vector2d& pixel_in_image) const {
  const double x = scale * (pixel_in_image.x() + 0.5) - 0.5 - crop_x_px;
  const double y = scale * (pixel_in_image.y() + 0.5) - 0.5 - crop_y_px;
  return Eigen::Vector2d(panel_width - 1 - x, y);
}

render::RenderCamera PanelRenderCamera(const CameraIntrinsics& color, const PanelMapping& mapping,
                                       const Eigen::Isometry3d& world_from_camera) {
  render::RenderCamera camera;
  camera.width = mapping.panel_width;
  camera.height = mapping.panel_height;
  camera.fx = mapping.scale * color.fx;
  camera.fy = mapping.scale * color.fy;
  // The renderer samples pixel u at u + 0.5 (render_types.h).
  camera.cx = mapping.scale * (color.cx + 0.5) - mapping.crop_x_px;
  camera.cy = mapping.scale * (color.cy + 0.5) - mapping.crop_y_px;
  camera.world_from_camera = world_from_camera;
  camera.near_m = 0.1;
  camera.far_m = 30.0;
  return camera;
}

absl::StatusOr<RgbImage> ComposeMirrorImage(const CompositionInput& input,
                                            const CompositionOptions& options) {
  if (absl::Status valid = options.Validate(); !valid.ok()) return valid;
  const PanelRect mirror = MirrorPanel(options);
  const PanelRect teacher = TeacherPanel(options);
  if (absl::Status fits = CheckTeacher(input, teacher); !fits.ok()) return fits;
  RgbImage image(options.width, options.height);
  cv::Mat mat = Wrap(&image);
  mat.setTo(ToScalar(options.learner_background));
  const int image_width =
      input.learner_color ? input.learner_color->width : input.color_intrinsics.width;
  const int image_height =
      input.learner_color ? input.learner_color->height : input.color_intrinsics.height;
  const PanelMapping mapping =
      PanelMapping::Cover(image_width, image_height, mirror.width, mirror.height);
  if (input.learner_color != nullptr && !input.learner_color->empty()) {
    DrawLearnerImage(*input.learner_color, mapping, mat(ToRect(mirror)));
  }
  if (input.teacher_color != nullptr) {
    if (options.layout == MirrorLayout::kSide) {
      DrawTeacherPanel(input, teacher, mat);
    } else {
      DrawTeacherGhost(input, options.ghost_alpha, teacher, &image);
    }
  } else if (options.layout == MirrorLayout::kSide) {
    mat(ToRect(teacher)).setTo(ToScalar(options.teacher_background));
  }
  if (input.learner_in_color != nullptr) DrawSkeleton(input, options, mapping, mirror, mat);
  if (options.hud) DrawHud(input, &image);
  return image;
}

std::vector<std::string> StatusLines(const MirrorFrame& frame, const StatusContext& context) {
  std::vector<std::string> lines;
  const std::string of_total =
      context.repetitions > 0 ? absl::StrCat("/", context.repetitions) : std::string();
  switch (frame.state) {
    case MirrorState::kWaitingForLearner:
      lines.push_back("waiting for the learner: step in front of the mirror");
      break;
    case MirrorState::kReadingFacing: {
      const double yaw_deg =
          frame.facing.mean_yaw_deg.value_or(frame.learner_facing_yaw_deg.value_or(0.0));
      lines.push_back(
          context.challenge == ChallengeMode::kOff
              ? absl::StrFormat("hold still: facing %+.0f deg  %.1f/%.1f s", WholeDeg(yaw_deg),
                                frame.facing.held_s, context.hold_s)
              : absl::StrFormat("hold still to start  %.1f/%.1f s  (challenge view %+.0f deg)",
                                frame.facing.held_s, context.hold_s,
                                WholeDeg(frame.teacher_turn.view_yaw_deg)));
      break;
    }
    case MirrorState::kPlaying: {
      const std::string error =
          frame.comparison.mean_error_deg
              ? absl::StrFormat("error %.1f deg", *frame.comparison.mean_error_deg)
              : std::string("error -");
      const std::string view = context.challenge == ChallengeMode::kOff
                                   ? absl::StrFormat("teacher turned %+.0f deg",
                                                     WholeDeg(frame.teacher_turn.turn_yaw_deg))
                                   : absl::StrFormat("challenge view %+.0f deg",
                                                     WholeDeg(frame.teacher_turn.view_yaw_deg));
      lines.push_back(absl::StrFormat("repetition %d%s  frame %d/%d  %s  %s", frame.repetition,
                                      of_total, frame.teacher_frame + 1, context.num_teacher_frames,
                                      error, view));
      break;
    }
    case MirrorState::kFinished:
      lines.push_back(absl::StrFormat("finished: %d repetition%s", frame.repetition,
                                      frame.repetition == 1 ? "" : "s"));
      break;
  }
  if (!context.finished_mean_error_deg.empty()) {
    const std::optional<double>& last = context.finished_mean_error_deg.back();
    lines.push_back(
        last ? absl::StrFormat("repetition %d: mean error %.1f deg",
                               static_cast<int>(context.finished_mean_error_deg.size()), *last)
             : absl::StrFormat("repetition %d: nothing compared",
                               static_cast<int>(context.finished_mean_error_deg.size())));
    for (const std::string& c : context.last_corrections) lines.push_back("fix: " + c);
    for (const std::string& n : context.last_not_graded) lines.push_back("not graded: " + n);
  }
  // What is wrong with the input now.
  if (context.people_in_view > 1) {
    lines.push_back(absl::StrFormat(
        "%d people in view: grading the one with the most joints tracked", context.people_in_view));
  }
  if (frame.state != MirrorState::kWaitingForLearner && frame.state != MirrorState::kFinished &&
      context.learner_missing_s >= 0.5) {
    lines.push_back(absl::StrFormat(
        "learner not seen for %.1f s (out of view, or no depth from the sensor): not graded",
        context.learner_missing_s));
  }
  if (frame.state == MirrorState::kPlaying && !context.teacher_frame_has_skeleton) {
    lines.push_back("the teacher has no skeleton in this frame: not graded");
  }
  return lines;
}

double TimelineFraction(const MirrorFrame& frame, const StatusContext& context) {
  switch (frame.state) {
    case MirrorState::kWaitingForLearner:
      return -1.0;
    case MirrorState::kReadingFacing:
      return context.hold_s > 0 ? std::clamp(frame.facing.held_s / context.hold_s, 0.0, 1.0) : 1.0;
    case MirrorState::kPlaying:
      return context.num_teacher_frames > 1
                 ? static_cast<double>(frame.teacher_frame) / (context.num_teacher_frames - 1)
                 : 1.0;
    case MirrorState::kFinished:
      return 1.0;
  }
  return -1.0;
}

}  // namespace reenact::mirror
