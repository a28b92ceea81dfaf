// Recordings as live sensors: a TUM folder written here plays through
// OpenRecordingSensors with its depth unchanged, its colour paired, and an
// OK end; the real Azure Kinect recording of the shared data plays too.
#include <atomic>
#include <condition_variable>
#include <filesystem>
#include <fstream>
#include <mutex>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "capture_daemon/sensors/backends.h"
#include "common/testing/test_data.h"

namespace reenact::capture {
namespace {

namespace fs = std::filesystem;

// Three 32x24 frames 100 ms apart; depth 800 + i mm, colour 3 ms later.
std::string WriteTum(const std::string& name) {
  const std::string dir = testing::MakeTempDir(name);
  fs::create_directories(dir + "/d");
  fs::create_directories(dir + "/c");
  std::ofstream depth_txt(dir + "/depth.txt"), rgb_txt(dir + "/rgb.txt");
  for (int i = 0; i < 3; ++i) {
    cv::imwrite(dir + "/d/" + std::to_string(i) + ".png",
                cv::Mat(24, 32, CV_16UC1, cv::Scalar((800 + i) * 5)));
    cv::imwrite(dir + "/c/" + std::to_string(i) + ".png",
                cv::Mat(24, 32, CV_8UC3, cv::Scalar(0, 0, 200)));
    depth_txt << "7." << i << "00000 d/" << i << ".png\n";
    rgb_txt << "7." << i << "03000 c/" << i << ".png\n";
  }
  return dir;
}

struct Collected {
  std::mutex mutex;
  std::condition_variable cv;
  std::vector<CapturedFrame> frames;
  bool ended = false;
  absl::Status why;
};

absl::Status PlayToEnd(Sensor& sensor, Collected* c) {
  absl::Status started = sensor.Start(
      [c](CapturedFrame frame) {
        std::lock_guard<std::mutex> lock(c->mutex);
        c->frames.push_back(std::move(frame));
      },
      [c](const absl::Status& why) {
        std::lock_guard<std::mutex> lock(c->mutex);
        c->ended = true;
        c->why = why;
        c->cv.notify_all();
      });
  if (!started.ok()) return started;
  std::unique_lock<std::mutex> lock(c->mutex);
  if (!c->cv.wait_for(lock, std::chrono::seconds(20), [c] { return c->ended; })) {
    return absl::DeadlineExceededError("the recording did not end");
  }
  return absl::OkStatus();
}

TEST(RecordingSensor, TumFolderPlaysAtItsPaceAndEnds) {
  const std::string dir = WriteTum("rec_sensor_tum");
  SourceOptions options;
  options.first_index = 2;
  auto sensors = OpenRecordingSensors("tum", dir, options);
  ASSERT_TRUE(sensors.ok()) << sensors.status();
  ASSERT_EQ(sensors->size(), 1u);
  Sensor& sensor = *sensors->front();
  const v1::SensorInfo info = sensor.info();
  EXPECT_EQ(info.sensor_id(), "k2");
  EXPECT_EQ(info.backend(), "tum");
  EXPECT_EQ(info.depth_width_px(), 32);
  EXPECT_EQ(info.color_width_px(), 32);
  EXPECT_TRUE(info.provides_registration());
  EXPECT_DOUBLE_EQ(info.calibration().depth_intrinsics().fx_px(), 525.0 * 32 / 640);
  EXPECT_EQ(info.calibration().sensor_id(), "k2");

  Collected c;
  const auto start = std::chrono::steady_clock::now();
  ASSERT_TRUE(PlayToEnd(sensor, &c).ok());
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  sensor.Stop();
  EXPECT_TRUE(c.why.ok()) << c.why;
  EXPECT_EQ(sensor.info().state(), v1::SENSOR_STATE_GONE);
  EXPECT_EQ(sensor.info().detail(), "end of recording");
  ASSERT_EQ(c.frames.size(), 3u);
  EXPECT_GE(seconds, 0.19);  // Recorded pace: 3 frames 100 ms apart.
  for (int i = 0; i < 3; ++i) {
    const CapturedFrame& f = c.frames[i];
    EXPECT_EQ(f.frame.sensor_id(), "k2");
    EXPECT_EQ(f.frame.frame_index(), i);
    EXPECT_EQ(f.frame.device_stamp_ns(), 7'000'000'000 + i * 100'000'000);
    ASSERT_TRUE(f.depth_mm.has_value());
    EXPECT_EQ(f.depth_mm->at(10, 10), 800 + i);
    ASSERT_TRUE(f.color.has_value());
    EXPECT_EQ(f.color->at(3, 3, 0), 200);  // Red (BGR 0, 0, 200 written).
  }
}

TEST(RecordingSensor, LoopKeepsStampsIncreasing) {
  const std::string dir = WriteTum("rec_sensor_loop");
  SourceOptions options;
  options.fast = true;
  options.loop = true;
  auto sensors = OpenRecordingSensors("tum", dir, options);
  ASSERT_TRUE(sensors.ok()) << sensors.status();
  Collected c;
  ASSERT_TRUE(sensors->front()
                  ->Start(
                      [&c](CapturedFrame frame) {
                        std::lock_guard<std::mutex> lock(c.mutex);
                        c.frames.push_back(std::move(frame));
                        c.cv.notify_all();
                      },
                      [](const absl::Status&) {})
                  .ok());
  {
    std::unique_lock<std::mutex> lock(c.mutex);
    ASSERT_TRUE(
        c.cv.wait_for(lock, std::chrono::seconds(20), [&c] { return c.frames.size() >= 7; }));
  }
  sensors->front()->Stop();
  for (size_t i = 1; i < 7; ++i) {
    EXPECT_GT(c.frames[i].frame.device_stamp_ns(), c.frames[i - 1].frame.device_stamp_ns());
  }
  EXPECT_EQ(c.frames[3].frame.device_stamp_ns(), 7'000'000'000 + 300'000'000);
}

TEST(RecordingSensor, AzureKinectRecordingPlays) {
  const std::string mkv = testing::TestDataPath("rgbd/azure-kinect-mkv/recording.mkv");
  if (!fs::exists(mkv)) {
    GTEST_SKIP() << "\n*** SKIPPED: the real Azure Kinect recording " << mkv << " is missing ***";
  }
  SourceOptions options;
  options.fast = true;
  auto sensors = OpenRecordingSensors("azure-mkv", mkv, options);
  ASSERT_TRUE(sensors.ok()) << sensors.status();
  EXPECT_EQ(sensors->front()->info().sensor_id(), "k0");
  EXPECT_EQ(sensors->front()->info().color_width_px(), 1280);
  Collected c;
  ASSERT_TRUE(PlayToEnd(*sensors->front(), &c).ok());
  sensors->front()->Stop();
  EXPECT_TRUE(c.why.ok()) << c.why;
  ASSERT_GE(c.frames.size(), 1u);
  ASSERT_TRUE(c.frames[0].color.has_value());
  EXPECT_EQ(c.frames[0].color->width, 1280);
  EXPECT_EQ(c.frames[0].depth_mm->width, 640);
}

TEST(RecordingSensor, BadSourcesAreErrors) {
  EXPECT_EQ(OpenRecordingSensors("tum", "/no/such/dir", {}).status().code(),
            absl::StatusCode::kNotFound);
  EXPECT_EQ(OpenRecordingSensors("bag", "/tmp", {}).status().code(),
            absl::StatusCode::kInvalidArgument);
  const std::string dir = testing::MakeTempDir("rec_sensor_bad");
  std::ofstream(dir + "/depth.txt") << "1.0 missing.png\n";
  auto sensors = OpenRecordingSensors("tum", dir, {});
  EXPECT_FALSE(sensors.ok());
  EXPECT_NE(sensors.status().message().find("missing.png"), std::string::npos) << sensors.status();
}

}  // namespace
}  // namespace reenact::capture
