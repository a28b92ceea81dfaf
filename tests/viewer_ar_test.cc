// reenact-viewer's AR mode end to end (thesis 3.4.2, Eq. 3.12): a handheld
// video of the printed board lying on the floor is rendered from a known
// camera path and encoded as MP4; a body-model reenactment whose sensors were
// anchored to that board ("board:SPEC") is drawn over it by the real
// reenact-viewer (--ar VIDEO --render-to DIR). The camera poses it reports
// (poses.csv) must be within 1 degree and 10 mm of the truth in every frame,
// and the teacher it draws must cover the pixels where the truth says the
// teacher stands (silhouette IoU against a render from the true camera).
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/videoio.hpp>

#include "absl/strings/str_format.h"
#include "absl/strings/str_split.h"
#include "clients/view/reenactment_renderer.h"
#include "common/board/board_detector.h"
#include "common/board/intrinsics_file.h"
#include "common/board/testing/board_scenes.h"
#include "common/io/reenactment_file.h"
#include "common/io/testing/small_reenactment.h"
#include "common/io/testing/small_take.h"
#include "common/io/video_writer.h"
#include "common/testing/test_data.h"
#include "tests/e2e_commands.h"

namespace reenact {
namespace {

constexpr int kFrames = 24;
constexpr double kFps = 30.0;
// The test body walks 5 cm per instant: 5 instants (looped) keep it on the board.
constexpr int kTeacherInstants = 5;

struct CsvPose {
  bool found = false;
  Eigen::Isometry3d camera_from_board = Eigen::Isometry3d::Identity();
};

std::vector<CsvPose> ReadPoses(const std::string& path) {
  std::ifstream in(path);
  std::string line;
  std::getline(in, line);  // Header.
  std::vector<CsvPose> poses;
  while (std::getline(in, line)) {
    const std::vector<std::string> f = absl::StrSplit(line, ',');
    CsvPose pose;
    if (f.size() == 12 && f[2] == "1") {
      pose.found = true;
      pose.camera_from_board.translation() =
          Eigen::Vector3d(std::stod(f[5]), std::stod(f[6]), std::stod(f[7]));
      pose.camera_from_board.linear() =
          Eigen::Quaterniond(std::stod(f[8]), std::stod(f[9]), std::stod(f[10]), std::stod(f[11]))
              .normalized()
              .toRotationMatrix();
    }
    poses.push_back(pose);
  }
  return poses;
}

// Pixels where the composited PNG differs from the video frame it was drawn
// over: the teacher the viewer drew.
cv::Mat DrawnMask(const cv::Mat& composite_bgr, const cv::Mat& video_bgr) {
  cv::Mat diff;
  cv::absdiff(composite_bgr, video_bgr, diff);
  cv::Mat mask(diff.rows, diff.cols, CV_8UC1);
  for (int y = 0; y < diff.rows; ++y) {
    for (int x = 0; x < diff.cols; ++x) {
      const cv::Vec3b d = diff.at<cv::Vec3b>(y, x);
      mask.at<uint8_t>(y, x) = (d[0] + d[1] + d[2]) > 0 ? 255 : 0;
    }
  }
  return mask;
}

TEST(ViewerAr, TracksTheBoardAndDrawsTheTeacherWhereTheyStood) {
  const std::string dir = testing::MakeTempDir("viewer_ar");
  const board::BoardSpec spec;
  const CameraIntrinsics intrinsics = board::testing::PhoneIntrinsics();
  const std::vector<Eigen::Isometry3d> path = board::testing::HandheldPath(kFrames);

  // The handheld video of the board (no teacher in it).
  const std::string video = dir + "/handheld.mp4";
  {
    auto scene = board::testing::BoardScene::Create(spec, intrinsics.width, intrinsics.height);
    ASSERT_NE(scene, nullptr);
    auto writer = VideoWriter::Open(video, intrinsics.width, intrinsics.height, kFps);
    ASSERT_TRUE(writer.ok()) << writer.status();
    for (int i = 0; i < kFrames; ++i) {
      ASSERT_TRUE(
          (*writer)
              ->Append(scene->Render(render::RenderCameraFromIntrinsics(intrinsics, path[i]), 2.0,
                                     static_cast<unsigned>(i)))
              .ok());
    }
    ASSERT_TRUE((*writer)->Close().ok());
  }
  std::ofstream(dir + "/phone.json") << board::FormatIntrinsicsJson(intrinsics);

  // A body reenactment captured by a sensor anchored to the board: its world
  // is the board's frame, the teacher stands on the board.
  ReenactmentData teacher = testing::MakeTestBodyReenactment(kTeacherInstants);
  v1::SensorCalibration* sensor = teacher.info.add_sensors();
  *sensor = testing::TestCalibration("k0", 1.5);
  sensor->set_world_anchor("board:" + board::FormatBoardSpec(spec));
  const std::string teacher_path = dir + "/teacher.reen";
  ASSERT_TRUE(WriteReenactmentFile(teacher, teacher_path).ok());

  const testing::CommandResult run = testing::RunCommand(
      dir, "viewer-ar",
      {testing::Bin("reenact-viewer"), "--in", teacher_path, "--ar", video, "--intrinsics",
       dir + "/phone.json", "--render-to", dir + "/ar", "--json"});
  ASSERT_EQ(run.exit_code, 0) << run.err;
  const auto summary = nlohmann::json::parse(run.out, nullptr, false);
  ASSERT_TRUE(summary.is_object()) << run.out;
  EXPECT_EQ(summary["frames"], kFrames);
  EXPECT_EQ(summary["frames_with_board"], kFrames);
  EXPECT_TRUE(summary["anchored"].get<bool>());
  EXPECT_FALSE(summary["mp4"].get<std::string>().empty()) << summary["mp4_problem"];

  // Camera poses against the truth.
  const std::vector<CsvPose> poses = ReadPoses(summary["poses_csv"].get<std::string>());
  ASSERT_EQ(poses.size(), static_cast<size_t>(kFrames));
  board::testing::PoseErrorStats stats;
  for (int i = 0; i < kFrames; ++i) {
    ASSERT_TRUE(poses[i].found) << "frame " << i;
    const board::testing::PoseError error =
        board::testing::ComparePose(poses[i].camera_from_board, path[i]);
    stats.Add(error);
    EXPECT_LE(error.rotation_deg, 1.0) << "frame " << i;
    EXPECT_LE(error.position_mm, 10.0) << "frame " << i;
  }
  std::printf(
      "[ AR       ] camera vs truth over %d frames: rotation mean %.3f max %.3f deg (floor 1), "
      "position mean %.2f max %.2f mm (floor 10); %.1f frames/s\n",
      stats.count, stats.mean.rotation_deg, stats.worst.rotation_deg, stats.mean.position_mm,
      stats.worst.position_mm, summary["fps"].get<double>());

  // The teacher where the truth puts them: what the viewer changed in each
  // frame against the teacher's silhouette seen from the true camera.
  render::RendererOptions options;
  options.max_width = intrinsics.width;
  options.max_height = intrinsics.height;
  auto renderer = render::OffscreenRenderer::Create(options);
  ASSERT_TRUE(renderer.ok()) << renderer.status();
  const Reenactment plain_teacher = testing::ToPlain(teacher);
  auto view = view::ReenactmentRenderer::Create(plain_teacher, renderer->get());
  ASSERT_TRUE(view.ok()) << view.status();
  cv::VideoCapture capture(video);
  ASSERT_TRUE(capture.isOpened());
  double iou_min = 1.0, iou_sum = 0.0;
  for (int i = 0; i < kFrames; ++i) {
    cv::Mat video_bgr;
    ASSERT_TRUE(capture.read(video_bgr));
    const cv::Mat composite =
        cv::imread(absl::StrFormat("%s/ar/frame_%05d.png", dir, i), cv::IMREAD_COLOR);
    ASSERT_FALSE(composite.empty()) << "frame " << i;
    const cv::Mat drawn = DrawnMask(composite, video_bgr);
    const int instant =
        static_cast<int>(std::floor(i / kFps * teacher.info.fps())) % kTeacherInstants;
    render::RenderOutputs truth;
    truth.requested = render::kRenderLabel;
    ASSERT_TRUE(
        (*view)
            ->Render(instant, render::RenderCameraFromIntrinsics(intrinsics, path[i]), &truth)
            .ok());
    int64_t both = 0, either = 0;
    for (int y = 0; y < drawn.rows; ++y) {
      for (int x = 0; x < drawn.cols; ++x) {
        const bool a = drawn.at<uint8_t>(y, x) > 0, b = truth.label.at(x, y) > 0;
        both += a && b;
        either += a || b;
      }
    }
    ASSERT_GT(either, 0) << "frame " << i << ": no teacher drawn or in view";
    const double iou = static_cast<double>(both) / either;
    iou_min = std::min(iou_min, iou);
    iou_sum += iou;
  }
  std::printf("[ AR       ] teacher silhouette IoU vs the true camera: mean %.3f min %.3f\n",
              iou_sum / kFrames, iou_min);
  EXPECT_GE(iou_min, 0.9);
}

}  // namespace
}  // namespace reenact
