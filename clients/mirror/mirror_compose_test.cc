#include "clients/mirror/mirror_compose.h"

#include <cmath>
#include <iostream>

#include <gtest/gtest.h>

namespace reenact::mirror {
namespace {

CameraIntrinsics Kinect1080() {
  CameraIntrinsics k;
  k.width = 1920;
  k.height = 1080;
  k.fx = k.fy = 1050.0;
  k.cx = 959.5;
  k.cy = 539.5;
  return k;
}

TEST(PanelMapping, CoversThePanelAndFlipsLeftRight) {
  const PanelMapping m = PanelMapping::Cover(1920, 1080, 640, 720);
  EXPECT_NEAR(m.scale, 720.0 / 1080.0, 1e-12);
  EXPECT_NEAR(m.crop_x_px, 320.0, 1e-9);  // px cropped on each side
  EXPECT_NEAR(m.crop_y_px, 0.0, 1e-9);
  // The image centre stays the panel centre.
  const Eigen::Vector2d centre = m.ToPanel(Eigen::Vector2d(959.5, 539.5));
  EXPECT_NEAR(centre.x(), 319.5, 1e-9);
  EXPECT_NEAR(centre.y(), 359.5, 1e-9);
  // Left of the image centre lands right of the panel centre (mirror).
  EXPECT_GT(m.ToPanel(Eigen::Vector2d(800, 540)).x(), 319.5);
  EXPECT_LT(m.ToPanel(Eigen::Vector2d(1100, 540)).x(), 319.5);
}

// The render camera of a panel puts a point where the colour camera's
// projection, mapped into the panel and unflipped, puts it.
TEST(PanelRenderCamera, AgreesWithTheMappedColourCamera) {
  const CameraIntrinsics k = Kinect1080();
  const PanelMapping m = PanelMapping::Cover(k.width, k.height, 640, 720);
  const render::RenderCamera camera = PanelRenderCamera(k, m, Eigen::Isometry3d::Identity());
  double worst_px = 0.0;
  for (const Eigen::Vector3d& p : {Eigen::Vector3d(0.3, -0.4, 2.5), Eigen::Vector3d(-0.2, 0.7, 3.1),
                                   Eigen::Vector3d(0.0, 0.0, 1.0)}) {
    const Eigen::Vector2d mapped = m.ToPanel(*k.Project(p));
    // Renderer: continuous (fx X/Z + cx), pixel centres at +0.5; then flipped.
    const double u = camera.fx * p.x() / p.z() + camera.cx - 0.5;
    const double v = camera.fy * p.y() / p.z() + camera.cy - 0.5;
    const Eigen::Vector2d rendered(camera.width - 1 - u, v);
    worst_px = std::max(worst_px, (mapped - rendered).norm());
  }
  std::cout << "panel render camera vs mapped colour camera: worst " << worst_px << " px\n";
  EXPECT_LT(worst_px, 1e-9);
}

CompositionOptions SmallSide() {
  CompositionOptions options;
  options.width = 320;
  options.height = 180;
  options.hud = false;
  return options;
}

// A learner image whose left half is red and right half blue.
RgbImage HalfAndHalf(int width, int height) {
  RgbImage image(width, height);
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) image.at(x, y, x < width / 2 ? 0 : 2) = 255;
  }
  return image;
}

TEST(ComposeMirrorImage, FlipsTheLearnerAndTheTeacher) {
  const CompositionOptions options = SmallSide();
  const RgbImage learner = HalfAndHalf(320, 180);
  CompositionInput input;
  input.learner_color = &learner;
  input.color_intrinsics = Kinect1080();
  const PanelRect teacher_panel = TeacherPanel(options);
  RgbImage teacher(teacher_panel.width, teacher_panel.height);
  MaskImage label(teacher_panel.width, teacher_panel.height);
  for (int y = 0; y < teacher.height; ++y) {
    for (int x = 0; x < 10; ++x) teacher.at(x, y, 1) = 255, label.at(x, y) = 1;  // Left edge.
  }
  input.teacher_color = &teacher;
  input.teacher_label = &label;
  absl::StatusOr<RgbImage> image = ComposeMirrorImage(input, options);
  ASSERT_TRUE(image.ok()) << image.status();
  // Mirror panel (left half of the output): the learner's red left shows on the right.
  EXPECT_EQ(image->at(150, 90, 0), 255);
  EXPECT_EQ(image->at(150, 90, 2), 0);
  EXPECT_EQ(image->at(10, 90, 2), 255);
  // Teacher panel (right half): its left edge shows at the output's right edge.
  EXPECT_EQ(image->at(319, 90, 1), 255);
  EXPECT_EQ(image->at(161, 90, 1), 0);
}

TEST(ComposeMirrorImage, GhostBlendsTheTeacherWhereItIsDrawn) {
  CompositionOptions options = SmallSide();
  options.layout = MirrorLayout::kGhost;
  options.ghost_alpha = 0.5;
  RgbImage learner(320, 180);
  for (auto& value : learner.data) value = 200;
  RgbImage teacher(320, 180);
  MaskImage label(320, 180);
  for (int y = 0; y < 180; ++y) {
    for (int x = 0; x < 100; ++x) label.at(x, y) = 1;  // Teacher (black) on the left.
  }
  CompositionInput input;
  input.learner_color = &learner;
  input.color_intrinsics = Kinect1080();
  input.teacher_color = &teacher;
  input.teacher_label = &label;
  absl::StatusOr<RgbImage> image = ComposeMirrorImage(input, options);
  ASSERT_TRUE(image.ok()) << image.status();
  EXPECT_NEAR(image->at(300, 90, 0), 100, 1);  // Blended, on the flipped side.
  EXPECT_EQ(image->at(20, 90, 0), 200);        // No teacher there: the mirror alone.
}

TEST(ComposeMirrorImage, DrawsJointsInTheirErrorColourWhereTheFlippedImageShowsThem) {
  const CompositionOptions options = SmallSide();
  const CameraIntrinsics k = Kinect1080();
  body::SkeletonPose pose;
  for (auto& p : pose.position_m) p = Eigen::Vector3d::Zero();
  const int base = body::Index(body::KinectV2Joint::kSpineBase);
  pose.position_m[base] = Eigen::Vector3d(-0.5, 0.0, 2.5);  // Left of the optical axis.
  pose.valid[base] = true;
  MirrorFrame frame;
  frame.joint_color[base] = Srgb8{220, 40, 40};
  CompositionInput input;
  input.learner_in_color = &pose;
  input.color_intrinsics = k;
  input.frame = &frame;
  absl::StatusOr<RgbImage> image = ComposeMirrorImage(input, options);
  ASSERT_TRUE(image.ok()) << image.status();
  const PanelRect mirror = MirrorPanel(options);
  const Eigen::Vector2d at = PanelMapping::Cover(k.width, k.height, mirror.width, mirror.height)
                                 .ToPanel(*k.Project(pose.position_m[base]));
  EXPECT_GT(at.x(), mirror.width / 2.0);  // Left in the image, right in the mirror.
  const int x = static_cast<int>(std::lround(at.x())), y = static_cast<int>(std::lround(at.y()));
  EXPECT_EQ(image->at(x, y, 0), 220);
  EXPECT_EQ(image->at(x, y, 1), 40);
  EXPECT_EQ(image->at(x, y, 2), 40);
  // No colour image: the learner's panel is the dark background elsewhere.
  EXPECT_EQ(image->at(5, 5, 0), options.learner_background.r);
}

TEST(ComposeMirrorImage, RejectsBadSizes) {
  CompositionOptions options = SmallSide();
  options.width = 321;
  EXPECT_EQ(ComposeMirrorImage({}, options).status().code(), absl::StatusCode::kInvalidArgument);
  options = SmallSide();
  RgbImage teacher(10, 10);
  CompositionInput input;
  input.color_intrinsics = Kinect1080();
  input.teacher_color = &teacher;
  EXPECT_EQ(ComposeMirrorImage(input, options).status().code(), absl::StatusCode::kInvalidArgument);
}

TEST(StatusLines, SayWhatTheSessionIsDoing) {
  StatusContext context;
  context.hold_s = 2.0;
  context.num_teacher_frames = 60;
  context.repetitions = 3;
  MirrorFrame frame;
  EXPECT_EQ(StatusLines(frame, context).front(),
            "waiting for the learner: step in front of the mirror");
  EXPECT_LT(TimelineFraction(frame, context), 0.0);
  frame.state = MirrorState::kReadingFacing;
  frame.facing.held_s = 1.2;
  frame.facing.mean_yaw_deg = 32.0;
  EXPECT_EQ(StatusLines(frame, context).front(), "hold still: facing +32 deg  1.2/2.0 s");
  EXPECT_NEAR(TimelineFraction(frame, context), 0.6, 1e-12);
  frame.state = MirrorState::kPlaying;
  frame.repetition = 2;
  frame.teacher_frame = 40;
  frame.comparison.mean_error_deg = 7.54;
  frame.teacher_turn.turn_yaw_deg = 32.0;
  context.finished_mean_error_deg = {std::optional<double>(6.24)};
  const std::vector<std::string> lines = StatusLines(frame, context);
  ASSERT_EQ(lines.size(), 2u);
  EXPECT_EQ(lines[0], "repetition 2/3  frame 41/60  error 7.5 deg  teacher turned +32 deg");
  EXPECT_EQ(lines[1], "repetition 1: mean error 6.2 deg");
  frame.teacher_turn.turn_yaw_deg = -0.3;  // No "-0".
  EXPECT_EQ(StatusLines(frame, context)[0],
            "repetition 2/3  frame 41/60  error 7.5 deg  teacher turned +0 deg");
  context.challenge = ChallengeMode::kCycle;
  frame.teacher_turn.view_yaw_deg = 180.0;
  EXPECT_EQ(StatusLines(frame, context)[0],
            "repetition 2/3  frame 41/60  error 7.5 deg  challenge view +180 deg");
}

TEST(StatusLines, SayWhatToFixAndWhatIsWrongWithTheInput) {
  StatusContext context;
  context.num_teacher_frames = 60;
  MirrorFrame frame;
  frame.state = MirrorState::kPlaying;
  frame.teacher_frame = 10;
  context.finished_mean_error_deg = {std::optional<double>(12.0)};
  context.last_corrections = {"right elbow: straighten about 30 degrees at 1.8 s"};
  context.last_not_graded = {"left upper arm, left lower arm: hidden from the sensor"};
  context.people_in_view = 2;
  context.learner_missing_s = 1.5;
  context.teacher_frame_has_skeleton = false;
  const std::vector<std::string> lines = StatusLines(frame, context);
  ASSERT_EQ(lines.size(), 7u);
  EXPECT_EQ(lines[2], "fix: right elbow: straighten about 30 degrees at 1.8 s");
  EXPECT_EQ(lines[3], "not graded: left upper arm, left lower arm: hidden from the sensor");
  EXPECT_EQ(lines[4], "2 people in view: grading the one with the most joints tracked");
  EXPECT_EQ(lines[5],
            "learner not seen for 1.5 s (out of view, or no depth from the sensor): not graded");
  EXPECT_EQ(lines[6], "the teacher has no skeleton in this frame: not graded");
  // A short gap says nothing; nor does a missing teacher frame while waiting.
  context.learner_missing_s = 0.2;
  context.people_in_view = 1;
  frame.state = MirrorState::kReadingFacing;
  EXPECT_EQ(StatusLines(frame, context).size(), 4u);
}

TEST(ParseMirrorLayout, KnowsSideAndGhost) {
  EXPECT_EQ(*ParseMirrorLayout("side"), MirrorLayout::kSide);
  EXPECT_EQ(*ParseMirrorLayout("ghost"), MirrorLayout::kGhost);
  EXPECT_EQ(ParseMirrorLayout("overlay").status().code(), absl::StatusCode::kInvalidArgument);
}

}  // namespace
}  // namespace reenact::mirror
