// The thread skeleton the hardware backends share (libfreenect, OpenNI2,
// libfreenect2): Start() starts the device's streams and one capture thread,
// the thread grabs from the device until Stop() or until the source fails or
// stalls, and Stop() joins it. A backend supplies the device-specific steps
// as hooks (StartStreams, Grab, FlushHeld, StopStreams).
//
// A stream that ends by itself (a grab failed: the device was unplugged, a
// recording ran out; or no frame arrived for StallCheck::timeout_s) delivers
// what the backend still holds, turns the SensorInfo's state to GONE with the
// reason as its detail, and calls the EndCallback with the error. After
// Stop() nothing is reported (sensor.h).
//
// Playback (capture_daemon/sensors/playback_sensor.h) is not a ThreadedSensor: the
// sensors of one take share one player thread.
#pragma once

#include <atomic>
#include <cstdint>
#include <mutex>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "capture_daemon/sensors/frame_pairing.h"
#include "capture_daemon/sensors/sensor.h"

namespace reenact::capture {

class ThreadedSensor : public Sensor {
 public:
  // Subclasses call Stop() first thing in their own destructor: the capture
  // thread runs their hooks, so it must be joined before their members go.
  ~ThreadedSensor() override = default;

  v1::SensorInfo info() const final;
  // FailedPrecondition "<id> already started" when started; otherwise
  // StartStreams()' error, or OK with the capture thread running.
  absl::Status Start(FrameCallback on_frame, EndCallback on_end) final;
  // Joins the capture thread, then StopStreams(); idempotent. The sensor can
  // be started again afterwards.
  void Stop() final;

 protected:
  // When a stream counts as stalled: no NoteFrame() for timeout_s seconds
  // (0: never). It then ends with
  //   Unavailable("<id>: no <frame> for <timeout_s> s; <device> stopped streaming").
  struct StallCheck {
    double timeout_s = 0.0;
    std::string frame = "frame";
    std::string device = "the device";
  };

  // What one Grab() saw.
  enum class GrabResult {
    // A frame arrived (and the backend called NoteFrame()): no stall check.
    kFrame,
    // The wait ended without a frame, or the backend cannot tell: the stall
    // check runs.
    kNoFrame,
    // The source ended by itself without an error (the end of a recording):
    // the stream ends as on an error, but the EndCallback gets OK and the
    // state's detail says "end of recording".
    kEnd,
  };

  // `info`: as opened (state DETECTED); its sensor_id names the sensor in
  // errors and frames.
  ThreadedSensor(v1::SensorInfo info, StallCheck stall);

  const std::string& sensor_id() const { return sensor_id_; }

  // Starts the device's streams, before the capture thread starts (Start()
  // holds its lock). An error is what Start() returns; no thread is started
  // and StopStreams() is not called.
  virtual absl::Status StartStreams() = 0;
  // Stops the device's streams, after the capture thread was joined.
  virtual void StopStreams() = 0;
  // On the capture thread, called again and again until Stop() or an error:
  // waits for the device for at most about 100 ms (a Stop() waits that long
  // for the thread) and hands complete frames to DeliverPaired(). An error
  // ends the stream with that status.
  virtual absl::StatusOr<GrabResult> Grab() = 0;
  // On the capture thread once the stream ended by itself, before the
  // EndCallback: delivers frames still held back (e.g. a depth frame waiting
  // for its colour).
  virtual void FlushHeld() {}

  // For the hooks, on the capture thread. Restarts the stall clock.
  void NoteFrame();
  // Numbers each frame (0, 1, ... from the first Start), keeps the
  // SensorInfo's frame count and clock offset current (ToCapturedFrame) and
  // hands it to the FrameCallback.
  void DeliverPaired(std::vector<PairedFrame> frames);
  // Runs `update(v1::SensorInfo&)` under the lock info() reads with.
  template <typename F>
  void UpdateInfo(F&& update) {
    std::lock_guard<std::mutex> lock(info_mutex_);
    std::forward<F>(update)(info_);
  }

 private:
  // The capture thread: grabs until the end, then reports an end that was
  // not asked for.
  void Run();
  // OK when stopped; otherwise why the stream ended.
  absl::Status GrabUntilEnd();

  const std::string sensor_id_;
  const StallCheck stall_;

  mutable std::mutex info_mutex_;
  v1::SensorInfo info_;  // Guarded by info_mutex_.

  // Serialises Start() and Stop(); guards started_ and thread_.
  std::mutex control_mutex_;
  bool started_ = false;
  std::thread thread_;
  // Set by Stop(), read by the capture thread between grabs.
  std::atomic<bool> stop_requested_{false};

  // Set by Start() before the thread starts; read by the thread only.
  FrameCallback on_frame_;
  EndCallback on_end_;
  // Capture-thread state.
  int64_t next_index_ = 0;
  std::atomic<int64_t> last_frame_steady_ns_{0};
};

}  // namespace reenact::capture
