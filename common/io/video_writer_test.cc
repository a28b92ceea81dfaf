#include "common/io/video_writer.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <numbers>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>
#include <opencv2/videoio.hpp>

#include "common/testing/test_data.h"

namespace reenact {
namespace {

constexpr int kWidth = 640;
constexpr int kHeight = 360;
constexpr int kFrames = 30;
constexpr double kFps = 30.0;

uint8_t Wave(double phase) {
  return static_cast<uint8_t>(
      std::lround(128.0 + 100.0 * std::sin(2.0 * std::numbers::pi * phase)));
}

// Frame t of a moving pattern: drifting colour waves and a white square
// crossing the image at 6 px per frame.
RgbImage PatternFrame(int t) {
  RgbImage image(kWidth, kHeight);
  const int square_x = 20 + 6 * t;
  for (int y = 0; y < kHeight; ++y) {
    for (int x = 0; x < kWidth; ++x) {
      const bool in_square = x >= square_x && x < square_x + 48 && y >= 150 && y < 198;
      image.at(x, y, 0) = in_square ? 255 : Wave((x + 5.0 * t) / 160.0);
      image.at(x, y, 1) = in_square ? 255 : Wave((y - 3.0 * t) / 120.0);
      image.at(x, y, 2) = in_square ? 255 : Wave((x + y) / 200.0 + t / 30.0);
    }
  }
  return image;
}

// PSNR of a decoded BGR frame against the RGB original, all channels, dB.
double Psnr(const RgbImage& original, const cv::Mat& decoded_bgr) {
  double sum_sq = 0.0;
  for (int y = 0; y < original.height; ++y) {
    const cv::Vec3b* row = decoded_bgr.ptr<cv::Vec3b>(y);
    for (int x = 0; x < original.width; ++x) {
      for (int c = 0; c < 3; ++c) {
        const double d = static_cast<double>(original.at(x, y, c)) - row[x][2 - c];
        sum_sq += d * d;
      }
    }
  }
  const double mse = sum_sq / (3.0 * original.num_pixels());
  return 10.0 * std::log10(255.0 * 255.0 / std::max(mse, 1e-12));
}

struct RoundTrip {
  std::string codec;
  int frames_read = 0;
  double mean_psnr_db = 0.0;
  double min_psnr_db = 1e9;
  uintmax_t bytes = 0;
};

// Writes the pattern with `options`, reads it back with OpenCV and compares.
RoundTrip WriteAndReadBack(const std::string& path, const VideoWriterOptions& options) {
  RoundTrip result;
  auto writer = VideoWriter::Open(path, kWidth, kHeight, kFps, options);
  EXPECT_TRUE(writer.ok()) << writer.status();
  if (!writer.ok()) return result;
  for (int t = 0; t < kFrames; ++t) EXPECT_TRUE((*writer)->Append(PatternFrame(t)).ok());
  EXPECT_EQ((*writer)->frames_written(), kFrames);
  EXPECT_TRUE((*writer)->Close().ok());
  result.codec = (*writer)->codec_name();
  result.bytes = std::filesystem::file_size(path);
  cv::VideoCapture capture(path, cv::CAP_FFMPEG);
  EXPECT_TRUE(capture.isOpened()) << path;
  EXPECT_NEAR(capture.get(cv::CAP_PROP_FPS), kFps, 1e-3);
  cv::Mat frame;
  while (capture.read(frame)) {
    EXPECT_EQ(frame.cols, kWidth);
    EXPECT_EQ(frame.rows, kHeight);
    if (frame.cols != kWidth || frame.rows != kHeight || result.frames_read >= kFrames) break;
    const double psnr_db = Psnr(PatternFrame(result.frames_read), frame);
    result.mean_psnr_db += psnr_db / kFrames;
    result.min_psnr_db = std::min(result.min_psnr_db, psnr_db);
    ++result.frames_read;
  }
  return result;
}

TEST(VideoWriter, H264RoundTripThroughOpenCv) {
  const std::string dir = testing::MakeTempDir("video_h264");
  const RoundTrip trip = WriteAndReadBack(dir + "/pattern.mp4", VideoWriterOptions{});
  EXPECT_EQ(trip.codec, "libx264");
  EXPECT_EQ(trip.frames_read, kFrames);
  std::printf("%s crf 18: %d frames %dx%d, %ju bytes, PSNR mean %.2f dB, min %.2f dB\n",
              trip.codec.c_str(), trip.frames_read, kWidth, kHeight, trip.bytes, trip.mean_psnr_db,
              trip.min_psnr_db);
  EXPECT_GT(trip.mean_psnr_db, 38.0);
  EXPECT_GT(trip.min_psnr_db, 35.0);
  std::filesystem::remove_all(dir);
}

TEST(VideoWriter, Mpeg4RoundTripThroughOpenCv) {
  const std::string dir = testing::MakeTempDir("video_mpeg4");
  VideoWriterOptions options;
  options.codec = VideoCodec::kMpeg4;
  const RoundTrip trip = WriteAndReadBack(dir + "/pattern.mp4", options);
  EXPECT_EQ(trip.codec, "mpeg4");
  EXPECT_EQ(trip.frames_read, kFrames);
  std::printf("%s qscale 2: %d frames %dx%d, %ju bytes, PSNR mean %.2f dB, min %.2f dB\n",
              trip.codec.c_str(), trip.frames_read, kWidth, kHeight, trip.bytes, trip.mean_psnr_db,
              trip.min_psnr_db);
  EXPECT_GT(trip.mean_psnr_db, 33.0);
  EXPECT_GT(trip.min_psnr_db, 30.0);
  std::filesystem::remove_all(dir);
}

TEST(VideoWriter, RejectsOddSizesAndBadOptions) {
  const std::string dir = testing::MakeTempDir("video_bad_size");
  EXPECT_TRUE(absl::IsInvalidArgument(VideoWriter::Open(dir + "/a.mp4", 641, 360, kFps).status()));
  EXPECT_TRUE(absl::IsInvalidArgument(VideoWriter::Open(dir + "/a.mp4", 640, 0, kFps).status()));
  EXPECT_TRUE(absl::IsInvalidArgument(VideoWriter::Open(dir + "/a.mp4", 640, 360, 0.0).status()));
  VideoWriterOptions options;
  options.crf = 60;
  EXPECT_TRUE(
      absl::IsInvalidArgument(VideoWriter::Open(dir + "/a.mp4", 640, 360, kFps, options).status()));
  options = {};
  options.preset = "warp";
  EXPECT_TRUE(
      absl::IsInvalidArgument(VideoWriter::Open(dir + "/a.mp4", 640, 360, kFps, options).status()));
  EXPECT_FALSE(std::filesystem::exists(dir + "/a.mp4"));
  std::filesystem::remove_all(dir);
}

TEST(VideoWriter, UnwritablePathFails) {
  auto writer = VideoWriter::Open("/nonexistent_folder_for_reenact/x.mp4", 640, 360, kFps);
  ASSERT_FALSE(writer.ok());
  EXPECT_TRUE(absl::IsNotFound(writer.status())) << writer.status();
  EXPECT_NE(writer.status().message().find("nonexistent_folder_for_reenact"), std::string::npos);
}

TEST(VideoWriter, WrongFrameSizeAndAppendAfterClose) {
  const std::string dir = testing::MakeTempDir("video_wrong_frame");
  auto writer = VideoWriter::Open(dir + "/b.mp4", kWidth, kHeight, kFps);
  ASSERT_TRUE(writer.ok()) << writer.status();
  EXPECT_TRUE(absl::IsInvalidArgument((*writer)->Append(RgbImage(320, 240))));
  RgbImage truncated(kWidth, kHeight);
  truncated.data.resize(10);
  EXPECT_TRUE(absl::IsInvalidArgument((*writer)->Append(truncated)));
  EXPECT_TRUE((*writer)->Append(PatternFrame(0)).ok());
  EXPECT_TRUE((*writer)->Close().ok());
  EXPECT_TRUE((*writer)->Close().ok());  // A second Close does nothing.
  EXPECT_TRUE(absl::IsFailedPrecondition((*writer)->Append(PatternFrame(1))));
  cv::VideoCapture capture(dir + "/b.mp4", cv::CAP_FFMPEG);
  cv::Mat frame;
  int frames = 0;
  while (capture.read(frame)) ++frames;
  EXPECT_EQ(frames, 1);
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace reenact
