// End to end over loopback: the real `reenactd --source tum:DIR` plays a TUM
// RGB-D folder written here into the real `reenact-server`, and the take the
// server stores holds the folder's depth to the millimetre, its colour, and
// the calibration of the recording.
#include <signal.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <thread>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "common/base/subprocess.h"
#include "common/io/depth_codec.h"
#include "common/io/take.h"
#include "common/testing/test_data.h"
#include "tests/e2e_commands.h"

namespace reenact {
namespace {

namespace fs = std::filesystem;

using testing::Bin;
using testing::ReadText;

std::string WaitForLine(const std::string& path, double timeout_s, Subprocess* process) {
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
  while (std::chrono::steady_clock::now() < deadline) {
    const std::string text = ReadText(path);
    if (const auto nl = text.find('\n'); nl != std::string::npos) return text.substr(0, nl);
    if (process != nullptr && !process->Running()) return "";
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  return "";
}

TEST(RecordingSourceE2e, TumFolderStreamsThroughReenactdIntoTheServer) {
  const std::string dir = testing::MakeTempDir("recording_source_e2e");
  // Eight 80x60 frames at 30 Hz, depth 900 + 3 x + 2 y + i mm (0 on a grid),
  // colour 4 ms after each depth frame.
  const std::string tum = dir + "/tum";
  fs::create_directories(tum + "/depth");
  fs::create_directories(tum + "/rgb");
  std::ofstream depth_txt(tum + "/depth.txt"), rgb_txt(tum + "/rgb.txt");
  constexpr int kFrames = 8;
  for (int i = 0; i < kFrames; ++i) {
    cv::Mat depth(60, 80, CV_16UC1);
    for (int y = 0; y < 60; ++y) {
      for (int x = 0; x < 80; ++x) {
        depth.at<uint16_t>(y, x) =
            (x % 9 == 0) ? 0 : static_cast<uint16_t>((900 + 3 * x + 2 * y + i) * 5);
      }
    }
    cv::imwrite(tum + "/depth/" + std::to_string(i) + ".png", depth);
    cv::imwrite(tum + "/rgb/" + std::to_string(i) + ".png",
                cv::Mat(60, 80, CV_8UC3, cv::Scalar(30 * i, 90, 160)));
    const int64_t stamp_us = 1'000'000 + i * 33'333;
    depth_txt << stamp_us / 1'000'000 << "."
              << std::to_string(1'000'000 + stamp_us % 1'000'000).substr(1) << " depth/" << i
              << ".png\n";
    rgb_txt << (stamp_us + 4'000) / 1'000'000 << "."
            << std::to_string(1'000'000 + (stamp_us + 4'000) % 1'000'000).substr(1) << " rgb/" << i
            << ".png\n";
  }
  depth_txt.close();
  rgb_txt.close();

  SubprocessOptions server_options;
  server_options.stdout_path = server_options.stderr_path = dir + "/server.log";
  auto server = Subprocess::Start({Bin("reenact-server"), "--data", dir + "/data", "--listen",
                                   "127.0.0.1:0", "--port-file", dir + "/server.port"},
                                  server_options);
  ASSERT_TRUE(server.ok()) << server.status();
  const std::string address = WaitForLine(dir + "/server.port", 120, server->get());
  ASSERT_FALSE(address.empty()) << ReadText(dir + "/server.log");

  SubprocessOptions daemon_options;
  daemon_options.stdout_path = daemon_options.stderr_path = dir + "/daemon.log";
  auto daemon = Subprocess::Start(
      {Bin("reenactd"), "--control", "127.0.0.1:0", "--spool", dir + "/spool", "--server", address,
       "--source", "tum:" + tum, "--once", "--take-name", "tum", "--tracker", "off"},
      daemon_options);
  ASSERT_TRUE(daemon.ok()) << daemon.status();
  auto exit = (*daemon)->Wait(120);
  ASSERT_TRUE(exit.ok()) << exit.status() << "\n" << ReadText(dir + "/daemon.log");
  ASSERT_TRUE(exit->exited && exit->exit_code == 0) << exit->ToString() << "\n"
                                                    << ReadText(dir + "/daemon.log");

  std::string stored;
  for (const auto& entry : fs::directory_iterator(dir + "/data/takes")) {
    if (entry.path().extension() == ".mcap") stored = entry.path().string();
  }
  ASSERT_FALSE(stored.empty()) << ReadText(dir + "/server.log");
  auto take = TakeReader::Open(stored);
  ASSERT_TRUE(take.ok()) << take.status();
  EXPECT_EQ((*take)->info().name(), "tum");
  ASSERT_EQ((*take)->sensors().count("k0"), 1u);
  const v1::SensorCalibration& calibration = (*take)->sensors().at("k0");
  EXPECT_DOUBLE_EQ(calibration.depth_intrinsics().fx_px(), 525.0 * 80 / 640);
  EXPECT_EQ(calibration.depth_intrinsics().width_px(), 80);
  auto depths = (*take)->ReadAll<v1::DepthImage>(SensorTopic("k0", "depth"));
  ASSERT_TRUE(depths.ok()) << depths.status();
  ASSERT_EQ(depths->size(), static_cast<size_t>(kFrames));
  int worst = 0;
  for (const v1::DepthImage& d : *depths) {
    auto mm = DecodeDepth(d.data());
    ASSERT_TRUE(mm.ok()) << mm.status();
    const int i = static_cast<int>(d.frame_index());
    for (int y = 0; y < 60; ++y) {
      for (int x = 0; x < 80; ++x) {
        const int expected = (x % 9 == 0) ? 0 : 900 + 3 * x + 2 * y + i;
        worst = std::max(worst, std::abs(expected - int{mm->at(x, y)}));
      }
    }
  }
  EXPECT_EQ(worst, 0) << "largest depth difference, mm";
  std::printf("stored %zu frames; largest depth difference %d mm\n", depths->size(), worst);
  auto colors = (*take)->ReadAll<v1::ColorImage>(SensorTopic("k0", "color"));
  ASSERT_TRUE(colors.ok()) << colors.status();
  EXPECT_EQ(colors->size(), static_cast<size_t>(kFrames));

  ASSERT_TRUE((*server)->Signal(SIGTERM).ok());
  auto server_exit = (*server)->Wait(20);
  ASSERT_TRUE(server_exit.ok()) << server_exit.status();
}

}  // namespace
}  // namespace reenact
