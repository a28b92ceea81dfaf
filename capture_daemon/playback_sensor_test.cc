#include "capture_daemon/sensors/playback_sensor.h"

#include <algorithm>
#include <condition_variable>
#include <iostream>
#include <map>
#include <mutex>

#include <gtest/gtest.h>

#include "capture_daemon/testing/synthetic_take.h"
#include "common/base/sample_stats.h"
#include "common/base/time.h"
#include "common/io/take.h"
#include "common/testing/test_data.h"

namespace reenact::capture {
namespace {

// Collects what the sensors of one take deliver.
struct Collector {
  std::mutex mutex;
  std::condition_variable cv;
  std::map<std::string, std::vector<v1::Frame>> frames;
  std::map<std::string, std::vector<int64_t>> arrival_wall_ns;
  std::map<std::string, absl::Status> ended;
  std::map<std::string, size_t> frames_at_end;
  size_t total = 0;

  absl::Status Start(SensorList& sensors) {
    for (auto& sensor : sensors) {
      const std::string id = sensor->info().sensor_id();
      absl::Status s = sensor->Start(
          [this, id](CapturedFrame f) {
            const int64_t now = WallNowNs();
            std::lock_guard<std::mutex> lock(mutex);
            frames[id].push_back(std::move(f.frame));
            arrival_wall_ns[id].push_back(now);
            ++total;
            cv.notify_all();
          },
          [this, id](const absl::Status& why) {
            std::lock_guard<std::mutex> lock(mutex);
            ended[id] = why;
            size_t all = 0;
            for (const auto& [k, v] : frames) all += v.size();
            frames_at_end[id] = all;
            cv.notify_all();
          });
      if (!s.ok()) return s;
    }
    return absl::OkStatus();
  }
  bool WaitEnded(size_t n, double seconds) {
    std::unique_lock<std::mutex> lock(mutex);
    return cv.wait_for(lock, std::chrono::duration<double>(seconds),
                       [&] { return ended.size() >= n; });
  }
  bool WaitFrames(size_t n, double seconds) {
    std::unique_lock<std::mutex> lock(mutex);
    return cv.wait_for(lock, std::chrono::duration<double>(seconds), [&] { return total >= n; });
  }
};

TEST(PlaybackSensor, FastPlaysEveryFrameBitIdentical) {
  const std::string& path = testing::SyntheticTakePath();
  const auto source = testing::ReadDepth(path);
  ASSERT_EQ(source.size(), 2u);
  SourceOptions options;
  options.fast = true;
  auto sensors = OpenPlaybackSensors(path, options);
  ASSERT_TRUE(sensors.ok()) << sensors.status();
  ASSERT_EQ(sensors->size(), 2u);
  Collector collector;
  ASSERT_TRUE(collector.Start(*sensors).ok());
  ASSERT_TRUE(collector.WaitEnded(2, 30.0));
  for (const auto& [id, depth] : source) {
    const auto& got = collector.frames[id];
    ASSERT_EQ(got.size(), depth.size()) << id;
    EXPECT_TRUE(collector.ended[id].ok()) << collector.ended[id];
    const int64_t shift = got[0].host_stamp_ns() - depth[0].host_stamp_ns();
    for (size_t i = 0; i < got.size(); ++i) {
      EXPECT_EQ(got[i].depth().data(), depth[i].data()) << id << " frame " << i;
      EXPECT_EQ(got[i].depth().encoding(), depth[i].encoding());
      EXPECT_EQ(got[i].frame_index(), depth[i].frame_index());
      EXPECT_EQ(got[i].device_stamp_ns(), depth[i].device_stamp_ns());
      // Host stamps keep the recorded spacing, shifted to now.
      EXPECT_EQ(got[i].host_stamp_ns() - depth[i].host_stamp_ns(), shift);
      EXPECT_EQ(got[i].depth().host_stamp_ns(), got[i].host_stamp_ns());
      EXPECT_TRUE(got[i].has_color());
      EXPECT_FALSE(got[i].color().data().empty());
      EXPECT_EQ(got[i].color().host_stamp_ns(), got[i].host_stamp_ns());
      EXPECT_EQ(got[i].skeletons_size(), 1);
    }
    EXPECT_NEAR(NsToSeconds(std::abs(shift - (WallNowNs() - depth[0].host_stamp_ns()))), 0.0, 60.0);
  }
  for (auto& s : *sensors) EXPECT_EQ(s->info().state(), v1::SENSOR_STATE_GONE);
}

TEST(PlaybackSensor, RealTimePacingFollowsHostStamps) {
  auto sensors = OpenPlaybackSensors(testing::SyntheticTakePath(), {});
  ASSERT_TRUE(sensors.ok());
  Collector collector;
  const int64_t begin = SteadyNowNs();
  ASSERT_TRUE(collector.Start(*sensors).ok());
  ASSERT_TRUE(collector.WaitEnded(2, 30.0));
  const double elapsed_s = NsToSeconds(SteadyNowNs() - begin);
  std::vector<int64_t> lateness_ns;
  int64_t earliest_ns = INT64_MAX;
  int64_t first_host = INT64_MAX;
  int64_t last_host = 0;
  for (const auto& [id, frames] : collector.frames) {
    for (size_t i = 0; i < frames.size(); ++i) {
      const int64_t late = collector.arrival_wall_ns[id][i] - frames[i].host_stamp_ns();
      lateness_ns.push_back(late);
      earliest_ns = std::min(earliest_ns, late);
      first_host = std::min(first_host, frames[i].host_stamp_ns());
      last_host = std::max(last_host, frames[i].host_stamp_ns());
    }
  }
  const double p50_ms = Percentile(lateness_ns, 0.5) / 1e6;
  const double p90_ms = Percentile(lateness_ns, 0.9) / 1e6;
  std::cout << "real-time playback: " << elapsed_s << " s for a take spanning "
            << NsToSeconds(last_host - first_host) << " s; handed over late by p50 " << p50_ms
            << " ms, p90 " << p90_ms << " ms, earliest " << earliest_ns / 1e6 << " ms\n";
  // Frames are never handed over before their stamp, and not much after.
  EXPECT_GE(earliest_ns, -2'000'000);
  EXPECT_LT(p90_ms, 50.0);
  EXPECT_GE(elapsed_s, NsToSeconds(last_host - first_host) - 0.01);
}

TEST(PlaybackSensor, LoopRepeatsWithIncreasingStamps) {
  const std::string& path = testing::SyntheticTakePath();
  const auto source = testing::ReadDepth(path);
  SourceOptions options;
  options.fast = true;
  options.loop = true;
  auto sensors = OpenPlaybackSensors(path, options);
  ASSERT_TRUE(sensors.ok());
  Collector collector;
  ASSERT_TRUE(collector.Start(*sensors).ok());
  const size_t per_pass = source.at("k0").size() + source.at("k1").size();
  ASSERT_TRUE(collector.WaitFrames(per_pass * 5 / 2, 30.0));
  for (auto& s : *sensors) s->Stop();
  EXPECT_TRUE(collector.ended.empty()) << "a looping take does not end";
  for (const auto& [id, frames] : collector.frames) {
    const size_t n = source.at(id).size();
    ASSERT_GT(frames.size(), n + 1);
    for (size_t i = 1; i < frames.size(); ++i) {
      EXPECT_EQ(frames[i].frame_index(), static_cast<int64_t>(i)) << id;
      EXPECT_GT(frames[i].host_stamp_ns(), frames[i - 1].host_stamp_ns()) << id << " " << i;
      EXPECT_GT(frames[i].device_stamp_ns(), frames[i - 1].device_stamp_ns()) << id << " " << i;
      EXPECT_EQ(frames[i].depth().data(), source.at(id)[i % n].data());
    }
    // One pass later: the same spacing, shifted by one period of the take.
    const int64_t period = frames[n].host_stamp_ns() - frames[0].host_stamp_ns();
    EXPECT_EQ(frames[n + 1].host_stamp_ns() - frames[1].host_stamp_ns(), period);
  }
  // Nothing arrives after Stop().
  const size_t after_stop = collector.total;
  std::this_thread::sleep_for(std::chrono::milliseconds(50));
  EXPECT_EQ(collector.total, after_stop);
}

// A take whose sensor "b" has fewer frames than "a".
std::string WriteUnevenTake(const std::string& dir) {
  const std::string path = dir + "/uneven.mcap";
  v1::TakeInfo info;
  info.set_fps(30.0);
  info.set_start_stamp_ns(1'000'000'000);
  auto writer = TakeWriter::Open(path, info);
  EXPECT_TRUE(writer.ok());
  for (const std::string id : {"a", "b"}) {
    v1::SensorCalibration calibration;
    calibration.set_sensor_id(id);
    calibration.set_nominal_fps(30.0);
    EXPECT_TRUE((*writer)->AddSensor(calibration).ok());
  }
  for (int f = 0; f < 10; ++f) {
    for (const std::string id : {"a", "b"}) {
      if (id == "b" && f >= 4) continue;
      v1::DepthImage depth;
      depth.set_sensor_id(id);
      depth.set_frame_index(f);
      depth.set_device_stamp_ns(f * 33'333'333);
      depth.set_host_stamp_ns(1'000'000'000 + f * 33'333'333);
      depth.set_encoding("rvl");
      depth.set_data(std::string(10, static_cast<char>(f)));
      EXPECT_TRUE((*writer)->WriteDepth(depth).ok());
    }
  }
  EXPECT_TRUE((*writer)->Close().ok());
  return path;
}

TEST(PlaybackSensor, SensorWithShorterStreamEndsEarlier) {
  const std::string path = WriteUnevenTake(reenact::testing::MakeTempDir("playback_uneven"));
  SourceOptions options;
  options.fast = true;
  auto sensors = OpenPlaybackSensors(path, options);
  ASSERT_TRUE(sensors.ok()) << sensors.status();
  Collector collector;
  ASSERT_TRUE(collector.Start(*sensors).ok());
  ASSERT_TRUE(collector.WaitEnded(2, 10.0));
  EXPECT_EQ(collector.frames["a"].size(), 10u);
  EXPECT_EQ(collector.frames["b"].size(), 4u);
  EXPECT_TRUE(collector.ended["b"].ok());
  // "b" ended two frame periods after its 4th frame (when its stream had
  // gone quiet), while "a" had 6 of its 10.
  EXPECT_LE(collector.frames_at_end["b"], 11u);
  EXPECT_EQ(collector.frames_at_end["a"], 14u);
  EXPECT_FALSE(collector.frames["a"][0].has_color());
}

TEST(PlaybackSensor, BadFilesGiveClearErrors) {
  EXPECT_TRUE(absl::IsNotFound(OpenPlaybackSensors("/no/such.mcap", {}).status()));
  auto sensors = OpenPlaybackSensors(testing::SyntheticTakePath(), {});
  ASSERT_TRUE(sensors.ok());
  auto nop = [](CapturedFrame) {};
  auto end = [](const absl::Status&) {};
  ASSERT_TRUE((*sensors)[0]->Start(nop, end).ok());
  EXPECT_TRUE(absl::IsFailedPrecondition((*sensors)[0]->Start(nop, end)));
}

}  // namespace
}  // namespace reenact::capture
