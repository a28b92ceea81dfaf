// The mirror's picture (thesis sec. 4.5.1): the learner's colour image
// flipped left-right like a mirror, the learner's joints drawn on it in the
// colour of their live error, and the teacher rendered from the virtual
// camera and flipped the same way (facing.h explains why both flips and an
// unnegated turn make the two face the same way), either beside the mirror
// (layout kSide: two panels, mirror left, teacher right) or over it as a
// semi-transparent ghost (kGhost). A status line and a timeline on top.
//
// Both panels map a sensor image into the panel the same way (PanelMapping):
// scaled to cover the panel, centred, the overflow cropped, then flipped. The
// teacher is rendered with the learner sensor's colour intrinsics mapped the
// same way (PanelRenderCamera), so the two appear at the same scale.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "clients/mirror/mirror_session.h"
#include "common/base/image.h"
#include "common/body/joint_set.h"
#include "common/geometry/camera.h"
#include "common/render/render_types.h"

namespace reenact::mirror {

enum class MirrorLayout { kSide, kGhost };

// "side" / "ghost"; InvalidArgument otherwise.
absl::StatusOr<MirrorLayout> ParseMirrorLayout(const std::string& name);
std::string MirrorLayoutName(MirrorLayout layout);

struct CompositionOptions {
  // Output image, pixels; even (video) and at least 64.
  int width = 1280;
  int height = 720;
  MirrorLayout layout = MirrorLayout::kSide;
  // Ghost: weight of the teacher where it is drawn, in (0, 1].
  double ghost_alpha = 0.5;
  // Learner skeleton: joint dot radius and bone width, pixels (>= 1).
  int joint_radius_px = 6;
  int bone_width_px = 4;
  // Behind a learner without a colour image, and behind the teacher.
  Srgb8 learner_background{24, 24, 30};
  Srgb8 teacher_background{31, 31, 36};
  // Draw the status lines and the timeline.
  bool hud = true;

  // InvalidArgument naming the first bad field.
  absl::Status Validate() const;
};

// A rectangle of the output image, pixels.
struct PanelRect {
  int x = 0;
  int y = 0;
  int width = 0;
  int height = 0;
};

// Where the mirror and the teacher go: side by side (mirror left), or both
// the whole image (ghost).
PanelRect MirrorPanel(const CompositionOptions& options);
PanelRect TeacherPanel(const CompositionOptions& options);

// How an image of a sensor (image_width x image_height, pixel centres at
// integers) is shown in a panel: scaled by `scale` to cover it, centred, then
// flipped left-right.
struct PanelMapping {
  int image_width = 0;
  int image_height = 0;
  int panel_width = 0;
  int panel_height = 0;
  double scale = 1.0;
  // Cropped from the scaled image on the left and on top, panel pixels.
  double crop_x_px = 0.0;
  double crop_y_px = 0.0;

  static PanelMapping Cover(int image_width, int image_height, int panel_width, int panel_height);
  // Image pixel -> panel pixel (flipped), both with centres at integers.
  Eigen::Vector2d ToPanel(const Eigen::Vector2d& pixel_in_image) const;
};

// The render camera of a panel, unflipped: `color` (pixel centres at
// integers, at the size it was calibrated for) mapped by `mapping`, posed at
// world_from_camera. Flip its render left-right to show it (distortion is
// not rendered).
render::RenderCamera PanelRenderCamera(const CameraIntrinsics& color, const PanelMapping& mapping,
                                       const Eigen::Isometry3d& world_from_camera);

// What one output image shows.
struct CompositionInput {
  // The learner's colour image (sRGB), or nullptr: a dark background.
  const RgbImage* learner_color = nullptr;
  // The learner in the colour camera frame, or nullptr when not tracked.
  const body::SkeletonPose* learner_in_color = nullptr;
  // Intrinsics of the learner's colour image at its size (at the calibrated
  // size when there is no image).
  CameraIntrinsics color_intrinsics;
  // The teacher rendered with PanelRenderCamera at TeacherPanel's size,
  // unflipped; its label is non-zero where the teacher is drawn. Empty: no
  // teacher.
  const RgbImage* teacher_color = nullptr;
  const MaskImage* teacher_label = nullptr;
  // The session's frame: joint and part colours, state.
  const MirrorFrame* frame = nullptr;
  // Status text (one entry per line) and timeline position in [0, 1]
  // (negative: none).
  std::vector<std::string> status_lines;
  double timeline_fraction = -1.0;
};

// Draws the output image. InvalidArgument for bad options or images whose
// sizes do not match the panels.
absl::StatusOr<RgbImage> ComposeMirrorImage(const CompositionInput& input,
                                            const CompositionOptions& options);

// What the status lines say (the app fills it from the session).
struct StatusContext {
  double hold_s = 2.0;
  int num_teacher_frames = 0;
  int repetitions = 0;  // 0: forever.
  ChallengeMode challenge = ChallengeMode::kOff;
  // Mean errors of the finished repetitions, in order.
  std::vector<std::optional<double>> finished_mean_error_deg;
  // The last finished repetition's corrections in words and its parts not
  // graded ("left lower arm: hidden from the sensor"), shown until the next
  // one finishes.
  std::vector<std::string> last_corrections;
  std::vector<std::string> last_not_graded;
  // This frame: people the tracker found; seconds since the learner was
  // last seen (0 while seen); whether the teacher frame on screen has a
  // skeleton to grade against.
  int people_in_view = 1;
  double learner_missing_s = 0.0;
  bool teacher_frame_has_skeleton = true;
};

// The state in words, e.g. "hold still: facing +32 deg  1.2/2.0 s",
// "repetition 2/3  frame 41/60  error 7.5 deg", a line per recent result
// with its corrections, and what is wrong with the input right now ("2
// people in view ...", "learner not seen for 1.5 s ...", "the teacher has no
// skeleton in this frame ...").
std::vector<std::string> StatusLines(const MirrorFrame& frame, const StatusContext& context);

// Timeline position: the hold's progress while reading the facing, the
// teacher's while playing, full when finished, none while waiting.
double TimelineFraction(const MirrorFrame& frame, const StatusContext& context);

}  // namespace reenact::mirror
