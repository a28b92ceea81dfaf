#include "capture_daemon/sensors/freenect_sensor.h"

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "capture_daemon/sensors/backends.h"
#include "capture_daemon/sensors/fakenect_recording.h"
#include "common/base/image.h"
#include "common/base/subprocess.h"
#include "common/geometry/registration.h"
#include "common/io/proto_convert.h"
#include "common/testing/test_data.h"

namespace reenact::capture {
namespace {

using fakenect::ColorValue;
using fakenect::kFrames;
using fakenect::kH;
using fakenect::kW;
using fakenect::SceneMm;
using fakenect::ToleranceMm;
using fakenect::WriteRecording;

TEST(KinectV1RawToMm, FollowsThePublishedModel) {
  // z = 1 / (3.3309495161 - 0.0030711016 raw) m.
  EXPECT_NEAR(KinectV1RawToMm(700), 846.6, 1.0);
  EXPECT_NEAR(KinectV1RawToMm(1000), 3848.5, 1.0);
  EXPECT_EQ(KinectV1RawToMm(kKinectV1RawNoValue), 0);
  EXPECT_EQ(KinectV1RawToMm(1100), 0);  // Past the model's pole.
  uint16_t previous = 0;
  for (int raw = 0; raw < 1080; ++raw) {
    const uint16_t mm = KinectV1RawToMm(static_cast<uint16_t>(raw));
    if (mm == 0) continue;
    EXPECT_GE(mm, previous) << "raw " << raw;
    previous = mm;
  }
  EXPECT_GT(previous, 9000);
}

TEST(KinectV1Clock, UnwrapsThe60MHzCounter) {
  KinectV1Clock clock;
  // Start 3 frames before the 32-bit counter wraps; frames 2,000,000 ticks
  // (33.333 ms) apart.
  uint32_t ticks = 0xFFFFFFFFu - 5'000'000u;
  int64_t previous = clock.ToNs(ticks);
  for (int i = 0; i < 6; ++i) {
    ticks += 2'000'000u;  // Wraps on the third step.
    const int64_t now = clock.ToNs(ticks);
    EXPECT_NEAR(static_cast<double>(now - previous), 33'333'333.3, 1.0) << "step " << i;
    previous = now;
  }
}

TEST(KinectV1DefaultCalibration, IsAUsableRegistration) {
  const v1::SensorCalibration c = KinectV1DefaultCalibration("k0", "A00");
  EXPECT_EQ(c.model(), "kinect_v1");
  auto depth = FromProto(c.depth_intrinsics());
  auto color = FromProto(c.color_intrinsics());
  auto color_from_depth = FromProto(c.color_from_depth());
  ASSERT_TRUE(depth.ok() && color.ok() && color_from_depth.ok());
  EXPECT_TRUE(depth->Validate().ok());
  // Baseline of the published extrinsics: |T| = 22.8 mm.
  EXPECT_NEAR(color_from_depth->translation.norm() * 1000.0, 22.8, 0.1);
  EXPECT_LT(Eigen::AngleAxisd(color_from_depth->rotation).angle() * 180.0 / M_PI, 1.5);
  // Every depth pixel's ray undistorts (registration would fail otherwise).
  EXPECT_TRUE(DepthToColorRegistration::Create(*depth, *color, *color_from_depth).ok());
}

TEST(OpenFreenectSensors, WithoutAKinectFailsCleanly) {
  // This process uses the real libfreenect; without a Kinect (or without USB
  // at all) opening must fail with a status, not crash.
  auto sensors = OpenFreenectSensors("", {});
  if (sensors.ok()) GTEST_SKIP() << "a Kinect v1 is attached";
  EXPECT_TRUE(sensors.status().code() == absl::StatusCode::kNotFound ||
              sensors.status().code() == absl::StatusCode::kUnavailable)
      << sensors.status();
  EXPECT_NE(sensors.status().message().find("Kinect v1"), std::string_view::npos)
      << sensors.status();
}

// ---------------------------------------------------------------- fakenect

std::vector<char> ReadAll(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::vector<char>(std::istreambuf_iterator<char>(in), {});
}

TEST(FreenectSensor, PlaysAFakenectRecording) {
  const std::string fakenect_dir = FAKENECT_LIBRARY_DIR;
  if (!std::filesystem::exists(fakenect_dir + "/libfreenect.so.0.5")) {
    GTEST_SKIP() << "libfreenect's fakenect library is not installed in " << fakenect_dir;
  }
  const std::string root = testing::MakeTempDir("fakenect");
  const std::string recording = root + "/recording";
  const std::string out = root + "/out";
  std::filesystem::create_directories(recording);
  std::filesystem::create_directories(out);
  WriteRecording(recording);

  SubprocessOptions options;
  options.env["LD_LIBRARY_PATH"] = fakenect_dir;
  options.env["FAKENECT_PATH"] = recording;
  options.stdout_path = root + "/stdout.txt";
  options.stderr_path = root + "/stderr.txt";
  auto child = Subprocess::Start({FREENECT_PLAYBACK_CHECK, out}, options);
  ASSERT_TRUE(child.ok()) << child.status();
  auto exit = (*child)->Wait(90);
  ASSERT_TRUE(exit.ok()) << exit.status();
  const std::vector<char> err = ReadAll(options.stderr_path);
  ASSERT_TRUE(exit->exited && exit->exit_code == 0) << exit->ToString() << "\n"
                                                    << std::string(err.begin(), err.end());

  std::ifstream summary(out + "/summary.txt");
  std::string line, word;
  ASSERT_TRUE(std::getline(summary, line));
  EXPECT_EQ(line, "info k0 freenect kinect_v1 640 480 640 480");
  std::vector<int64_t> device_ns;
  int end_code = -1;
  std::string end_message;
  int with_color = 0;
  while (std::getline(summary, line)) {
    std::istringstream fields(line);
    fields >> word;
    if (word == "frame") {
      int64_t index = 0, device = 0, host = 0;
      int has_color = 0;
      fields >> index >> device >> host >> has_color;
      EXPECT_EQ(index, static_cast<int64_t>(device_ns.size()));
      EXPECT_GT(host, 0);
      device_ns.push_back(device);
      with_color += has_color;
    } else if (word == "end") {
      fields >> end_code;
      std::getline(fields, end_message);
    }
  }
  // Every recorded frame arrives, each with its colour, and the stream ends
  // as Unavailable when the recording runs out.
  ASSERT_EQ(device_ns.size(), static_cast<size_t>(kFrames));
  EXPECT_EQ(with_color, kFrames);
  EXPECT_EQ(end_code, static_cast<int>(absl::StatusCode::kUnavailable)) << end_message;
  // Device stamps: 33.333 ms apart across the counter wrap.
  for (int i = 1; i < kFrames; ++i) {
    EXPECT_NEAR(static_cast<double>(device_ns[i] - device_ns[i - 1]), 33'333'333.3, 1.0);
  }

  double worst_excess_mm = -1e9;  // Largest |error| - tolerance over valid pixels.
  for (int i = 0; i < kFrames; ++i) {
    const std::vector<char> depth_bytes = ReadAll(absl::StrCat(out, "/frame_", i, ".depth"));
    ASSERT_EQ(depth_bytes.size(), static_cast<size_t>(kW * kH * 2)) << "frame " << i;
    const auto* depth = reinterpret_cast<const uint16_t*>(depth_bytes.data());
    int bad = 0;
    for (int y = 0; y < kH; ++y) {
      for (int x = 0; x < kW; ++x) {
        const double expected = SceneMm(i, x, y);
        const uint16_t got = depth[y * kW + x];
        if (expected == 0) {
          bad += got != 0;
          continue;
        }
        const double excess = std::abs(got - expected) - ToleranceMm(expected);
        worst_excess_mm = std::max(worst_excess_mm, excess);
        bad += excess > 0;
      }
    }
    EXPECT_EQ(bad, 0) << "frame " << i;
    const std::vector<char> rgb = ReadAll(absl::StrCat(out, "/frame_", i, ".rgb"));
    ASSERT_EQ(rgb.size(), static_cast<size_t>(kW * kH * 3)) << "frame " << i;
    int mismatched = 0;
    for (int y = 0; y < kH; ++y) {
      for (int x = 0; x < kW; ++x) {
        for (int c = 0; c < 3; ++c) {
          mismatched += static_cast<uint8_t>(rgb[(y * kW + x) * 3 + c]) != ColorValue(i, x, y, c);
        }
      }
    }
    EXPECT_EQ(mismatched, 0) << "frame " << i << ": colour of another frame?";
  }
  std::printf(
      "fakenect playback: %d frames, depth error within half a raw step + 1 mm "
      "(worst margin left %.2f mm)\n",
      kFrames, -worst_excess_mm);
}

}  // namespace
}  // namespace reenact::capture
