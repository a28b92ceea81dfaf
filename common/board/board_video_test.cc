// The AR viewer's measurement end to end (thesis 3.4.2, Eq. 3.12: the viewer
// needs C*, its camera's pose against the board, in every frame): a handheld
// video of the board is rendered from a known camera path, encoded as MP4 by
// VideoWriter, decoded by OpenCV's FFmpeg reader, and tracked frame by frame.
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>
#include <opencv2/videoio.hpp>

#include "common/board/board_detector.h"
#include "common/board/testing/board_scenes.h"
#include "common/io/video_writer.h"
#include "common/testing/test_data.h"

namespace reenact::board {
namespace {

constexpr int kFrames = 60;
constexpr double kFps = 30.0;

RgbImage FromBgr(const cv::Mat& bgr) {
  RgbImage image(bgr.cols, bgr.rows);
  for (int y = 0; y < bgr.rows; ++y) {
    const cv::Vec3b* row = bgr.ptr<cv::Vec3b>(y);
    for (int x = 0; x < bgr.cols; ++x) {
      for (int c = 0; c < 3; ++c) image.at(x, y, c) = row[x][2 - c];
    }
  }
  return image;
}

// Renders the path and writes it to `path`; returns the codec's name.
std::string WriteVideo(const std::string& path, const BoardSpec& spec,
                       const CameraIntrinsics& intrinsics,
                       const std::vector<Eigen::Isometry3d>& world_from_camera) {
  auto scene = testing::BoardScene::Create(spec, intrinsics.width, intrinsics.height);
  EXPECT_NE(scene, nullptr);
  auto writer = VideoWriter::Open(path, intrinsics.width, intrinsics.height, kFps);
  EXPECT_TRUE(writer.ok()) << writer.status();
  if (scene == nullptr || !writer.ok()) return "";
  for (size_t i = 0; i < world_from_camera.size(); ++i) {
    const RgbImage frame =
        scene->Render(render::RenderCameraFromIntrinsics(intrinsics, world_from_camera[i]), 2.0,
                      static_cast<unsigned>(i));
    EXPECT_TRUE((*writer)->Append(frame).ok());
  }
  EXPECT_TRUE((*writer)->Close().ok());
  return (*writer)->codec_name();
}

TEST(BoardTracker, TracksAnMp4HandheldVideoWithinOneDegreeAndTenMillimetres) {
  const BoardSpec spec;
  const CameraIntrinsics intrinsics = testing::PhoneIntrinsics();
  const std::vector<Eigen::Isometry3d> path = testing::HandheldPath(kFrames);
  const std::string dir = reenact::testing::MakeTempDir("board_video");
  const std::string video = dir + "/handheld.mp4";
  const std::string codec = WriteVideo(video, spec, intrinsics, path);
  ASSERT_FALSE(codec.empty());

  cv::VideoCapture capture(video, cv::CAP_FFMPEG);
  ASSERT_TRUE(capture.isOpened());
  auto tracker = BoardTracker::Create(spec, intrinsics);
  ASSERT_TRUE(tracker.ok()) << tracker.status();
  testing::PoseErrorStats stats;
  int frames = 0;
  double track_s = 0.0;
  cv::Mat bgr;
  while (capture.read(bgr) && frames < kFrames) {
    const RgbImage frame = FromBgr(bgr);
    const auto start = std::chrono::steady_clock::now();
    auto found = tracker->Track(frame);
    track_s += std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    ASSERT_TRUE(found.ok()) << "frame " << frames << ": " << found.status();
    const testing::PoseError error = testing::ComparePose(found->camera_from_board, path[frames]);
    EXPECT_LT(error.rotation_deg, 1.0) << "frame " << frames;
    EXPECT_LT(error.position_mm, 10.0) << "frame " << frames;
    stats.Add(error);
    ++frames;
  }
  EXPECT_EQ(frames, kFrames);
  std::printf(
      "MP4 (%s, crf 18, %ju bytes) of %d frames 1280x720 tracked: rotation error mean %.3f deg, "
      "max %.3f deg; position error mean %.2f mm, max %.2f mm; %.1f ms per frame\n",
      codec.c_str(), std::filesystem::file_size(video), frames, stats.mean.rotation_deg,
      stats.worst.rotation_deg, stats.mean.position_mm, stats.worst.position_mm,
      1e3 * track_s / std::max(frames, 1));
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace reenact::board
