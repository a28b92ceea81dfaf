#include "capture_daemon/sensors/threaded_sensor.h"

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <mutex>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

#include "absl/strings/str_cat.h"

namespace reenact::capture {
namespace {

// Generous: the waits below end as soon as what they wait for happens.
constexpr auto kTimeout = std::chrono::seconds(20);

v1::SensorInfo InfoOf(const std::string& id) {
  v1::SensorInfo info;
  info.set_sensor_id(id);
  info.set_state(v1::SENSOR_STATE_DETECTED);
  return info;
}

// A scripted device: each grab delivers one 2x1 depth frame (device stamps
// 1 ms apart) until `frames_before_error` frames went out, then fails with
// `error` (when set); with `deliver` false every grab waits 1 ms and brings
// nothing. FlushHeld delivers `held_frames` more.
class FakeSensor : public ThreadedSensor {
 public:
  struct Script {
    bool deliver = true;
    int frames_before_error = -1;  // -1: never fails.
    absl::Status error;
    int held_frames = 0;
    absl::Status start_error;
  };

  FakeSensor(const std::string& id, Script script, StallCheck stall = {})
      : ThreadedSensor(InfoOf(id), std::move(stall)), script_(std::move(script)) {}
  ~FakeSensor() override { Stop(); }

  int grabs() const { return grabs_; }
  int starts() const { return starts_; }
  int stops() const { return stops_; }
  int flushes() const { return flushes_; }
  bool in_grab() const { return in_grab_; }

 private:
  absl::Status StartStreams() override {
    if (!script_.start_error.ok()) return script_.start_error;
    ++starts_;
    return absl::OkStatus();
  }
  void StopStreams() override { ++stops_; }

  absl::StatusOr<GrabResult> Grab() override {
    in_grab_ = true;
    ++grabs_;
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
    if (!script_.deliver) {
      in_grab_ = false;
      return GrabResult::kNoFrame;
    }
    if (script_.frames_before_error >= 0 && delivered_ >= script_.frames_before_error) {
      in_grab_ = false;
      return script_.error;
    }
    NoteFrame();
    DeliverPaired(Frames(1));
    in_grab_ = false;
    return GrabResult::kFrame;
  }

  void FlushHeld() override {
    ++flushes_;
    DeliverPaired(Frames(script_.held_frames));
  }

  std::vector<PairedFrame> Frames(int count) {
    std::vector<PairedFrame> frames;
    for (int i = 0; i < count; ++i) {
      PairedFrame frame;
      frame.depth_mm = DepthImageMm(2, 1);
      frame.device_stamp_ns = 1'000'000 * ++delivered_;
      frame.host_stamp_ns = frame.device_stamp_ns + 500;
      frames.push_back(std::move(frame));
    }
    return frames;
  }

  const Script script_;
  std::atomic<int> grabs_{0};
  std::atomic<int> starts_{0};
  std::atomic<int> stops_{0};
  std::atomic<int> flushes_{0};
  std::atomic<bool> in_grab_{false};
  int delivered_ = 0;
};

// What the callbacks saw. Declared before the sensor in each test, so that
// the sensor (whose destructor stops it) goes first.
struct Recorder {
  std::mutex mutex;
  std::condition_variable changed;
  std::vector<int64_t> indices;
  std::vector<absl::Status> ends;

  FrameCallback OnFrame() {
    return [this](const CapturedFrame& frame) {
      std::lock_guard<std::mutex> lock(mutex);
      indices.push_back(frame.frame.frame_index());
      changed.notify_all();
    };
  }
  EndCallback OnEnd() {
    return [this](const absl::Status& why) {
      std::lock_guard<std::mutex> lock(mutex);
      ends.push_back(why);
      changed.notify_all();
    };
  }
  bool WaitForFrames(size_t count) {
    std::unique_lock<std::mutex> lock(mutex);
    return changed.wait_for(lock, kTimeout, [&] { return indices.size() >= count; });
  }
  bool WaitForEnd() {
    std::unique_lock<std::mutex> lock(mutex);
    return changed.wait_for(lock, kTimeout, [&] { return !ends.empty(); });
  }
  size_t frame_count() {
    std::lock_guard<std::mutex> lock(mutex);
    return indices.size();
  }
};

TEST(ThreadedSensor, StartDeliversNumberedFramesAndStopJoins) {
  Recorder seen;
  FakeSensor sensor("f0", {});
  ASSERT_TRUE(sensor.Start(seen.OnFrame(), seen.OnEnd()).ok());
  EXPECT_EQ(sensor.starts(), 1);
  EXPECT_EQ(sensor.info().state(), v1::SENSOR_STATE_STREAMING);
  ASSERT_TRUE(seen.WaitForFrames(5));
  sensor.Stop();
  // Joined: no grab runs or starts once Stop returned.
  EXPECT_FALSE(sensor.in_grab());
  const int grabs = sensor.grabs();
  const size_t frames = seen.frame_count();
  std::this_thread::sleep_for(std::chrono::milliseconds(20));
  EXPECT_EQ(sensor.grabs(), grabs);
  EXPECT_EQ(seen.frame_count(), frames);
  EXPECT_EQ(sensor.stops(), 1);
  // A stop is not an end: no EndCallback, no flush, the state stays.
  EXPECT_TRUE(seen.ends.empty());
  EXPECT_EQ(sensor.flushes(), 0);
  EXPECT_EQ(sensor.info().state(), v1::SENSOR_STATE_STREAMING);
  for (size_t i = 0; i < seen.indices.size(); ++i) {
    EXPECT_EQ(seen.indices[i], static_cast<int64_t>(i));
  }
  EXPECT_EQ(sensor.info().frames_delivered(), static_cast<int64_t>(frames));
  EXPECT_EQ(sensor.info().calibration().clock_offset_ns(), 500);
}

TEST(ThreadedSensor, SecondStartIsFailedPrecondition) {
  Recorder seen;
  FakeSensor sensor("f1", {});
  ASSERT_TRUE(sensor.Start(seen.OnFrame(), seen.OnEnd()).ok());
  const absl::Status again = sensor.Start(seen.OnFrame(), seen.OnEnd());
  EXPECT_EQ(again.code(), absl::StatusCode::kFailedPrecondition);
  EXPECT_EQ(again.message(), "f1 already started");
  EXPECT_EQ(sensor.starts(), 1);
}

TEST(ThreadedSensor, FailingGrabEndsTheStreamWithItsError) {
  FakeSensor::Script script;
  script.frames_before_error = 3;
  script.error = absl::UnavailableError("f2: device unplugged");
  script.held_frames = 1;
  Recorder seen;
  FakeSensor sensor("f2", script);
  ASSERT_TRUE(sensor.Start(seen.OnFrame(), seen.OnEnd()).ok());
  ASSERT_TRUE(seen.WaitForEnd());
  {
    std::lock_guard<std::mutex> lock(seen.mutex);
    ASSERT_EQ(seen.ends.size(), 1u);
    EXPECT_EQ(seen.ends[0], script.error);
    // Three grabbed and the held one, flushed before the end.
    EXPECT_EQ(seen.indices, (std::vector<int64_t>{0, 1, 2, 3}));
  }
  EXPECT_EQ(sensor.flushes(), 1);
  const v1::SensorInfo info = sensor.info();
  EXPECT_EQ(info.state(), v1::SENSOR_STATE_GONE);
  EXPECT_EQ(info.detail(), "f2: device unplugged");
  EXPECT_EQ(info.frames_delivered(), 4);
  // The thread has ended by itself; Stop joins it and stops the streams once.
  sensor.Stop();
  EXPECT_EQ(sensor.stops(), 1);
  EXPECT_EQ(seen.ends.size(), 1u);
}

TEST(ThreadedSensor, StallEndsTheStreamAsUnavailable) {
  FakeSensor::Script script;
  script.deliver = false;
  Recorder seen;
  FakeSensor sensor("f3", script, {0.05, "depth frame", "the Kinect"});
  ASSERT_TRUE(sensor.Start(seen.OnFrame(), seen.OnEnd()).ok());
  ASSERT_TRUE(seen.WaitForEnd());
  std::lock_guard<std::mutex> lock(seen.mutex);
  ASSERT_EQ(seen.ends.size(), 1u);
  EXPECT_EQ(seen.ends[0],
            absl::UnavailableError("f3: no depth frame for 0.05 s; the Kinect stopped streaming"));
  EXPECT_TRUE(seen.indices.empty());
  EXPECT_EQ(sensor.info().state(), v1::SENSOR_STATE_GONE);
}

TEST(ThreadedSensor, WithoutAStallCheckAQuietStreamRunsUntilStopped) {
  FakeSensor::Script script;
  script.deliver = false;
  Recorder seen;
  FakeSensor sensor("f4", script);
  ASSERT_TRUE(sensor.Start(seen.OnFrame(), seen.OnEnd()).ok());
  std::this_thread::sleep_for(std::chrono::milliseconds(50));
  sensor.Stop();
  EXPECT_GT(sensor.grabs(), 0);
  EXPECT_TRUE(seen.ends.empty());
}

TEST(ThreadedSensor, FailedStartStartsNoThread) {
  FakeSensor::Script script;
  script.start_error = absl::UnavailableError("f5: cannot start the depth stream");
  Recorder seen;
  FakeSensor sensor("f5", script);
  EXPECT_EQ(sensor.Start(seen.OnFrame(), seen.OnEnd()), script.start_error);
  EXPECT_EQ(sensor.grabs(), 0);
  EXPECT_EQ(sensor.info().state(), v1::SENSOR_STATE_DETECTED);
  sensor.Stop();  // Nothing was started: nothing to stop.
  EXPECT_EQ(sensor.stops(), 0);
}

TEST(ThreadedSensor, StopTwiceAndStopBeforeStartAreHarmless) {
  Recorder seen;
  FakeSensor sensor("f6", {});
  sensor.Stop();
  EXPECT_EQ(sensor.stops(), 0);
  ASSERT_TRUE(sensor.Start(seen.OnFrame(), seen.OnEnd()).ok());
  ASSERT_TRUE(seen.WaitForFrames(1));
  sensor.Stop();
  sensor.Stop();
  EXPECT_EQ(sensor.stops(), 1);
  EXPECT_TRUE(seen.ends.empty());
}

TEST(ThreadedSensor, RestartsAfterStopAndKeepsCounting) {
  Recorder first;
  Recorder second;
  FakeSensor sensor("f7", {});
  ASSERT_TRUE(sensor.Start(first.OnFrame(), first.OnEnd()).ok());
  ASSERT_TRUE(first.WaitForFrames(2));
  sensor.Stop();
  const int64_t before = sensor.info().frames_delivered();
  ASSERT_TRUE(sensor.Start(second.OnFrame(), second.OnEnd()).ok());
  ASSERT_TRUE(second.WaitForFrames(2));
  sensor.Stop();
  EXPECT_EQ(sensor.starts(), 2);
  EXPECT_EQ(sensor.stops(), 2);
  std::lock_guard<std::mutex> lock(second.mutex);
  EXPECT_EQ(second.indices.front(), before);
}

}  // namespace
}  // namespace reenact::capture
