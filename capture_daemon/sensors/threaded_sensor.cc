#include "capture_daemon/sensors/threaded_sensor.h"

#include "absl/strings/str_cat.h"
#include "common/base/status_macros.h"
#include "common/base/time.h"

namespace reenact::capture {

ThreadedSensor::ThreadedSensor(v1::SensorInfo info, StallCheck stall)
    : sensor_id_(info.sensor_id()), stall_(std::move(stall)), info_(std::move(info)) {}

v1::SensorInfo ThreadedSensor::info() const {
  std::lock_guard<std::mutex> lock(info_mutex_);
  return info_;
}

absl::Status ThreadedSensor::Start(FrameCallback on_frame, EndCallback on_end) {
  std::lock_guard<std::mutex> lock(control_mutex_);
  if (started_) return absl::FailedPreconditionError(absl::StrCat(sensor_id_, " already started"));
  RETURN_IF_ERROR(StartStreams());
  on_frame_ = std::move(on_frame);
  on_end_ = std::move(on_end);
  stop_requested_ = false;
  started_ = true;
  UpdateInfo([](v1::SensorInfo& info) { info.set_state(v1::SENSOR_STATE_STREAMING); });
  thread_ = std::thread([this] { Run(); });
  return absl::OkStatus();
}

void ThreadedSensor::Stop() {
  std::lock_guard<std::mutex> lock(control_mutex_);
  if (!started_) return;
  stop_requested_ = true;
  if (thread_.joinable()) thread_.join();
  StopStreams();
  started_ = false;
}

void ThreadedSensor::NoteFrame() { last_frame_steady_ns_ = SteadyNowNs(); }

void ThreadedSensor::DeliverPaired(std::vector<PairedFrame> frames) {
  for (PairedFrame& paired : frames) {
    CapturedFrame frame;
    UpdateInfo([&](v1::SensorInfo& info) {
      frame = ToCapturedFrame(std::move(paired), sensor_id_, &next_index_, &info);
    });
    if (on_frame_) on_frame_(std::move(frame));
  }
}

void ThreadedSensor::Run() {
  const absl::Status why = GrabUntilEnd();
  if (stop_requested_) return;
  FlushHeld();
  UpdateInfo([&why](v1::SensorInfo& info) {
    info.set_state(v1::SENSOR_STATE_GONE);
    info.set_detail(why.ok() ? "end of recording" : std::string(why.message()));
  });
  if (on_end_) on_end_(why);
}

absl::Status ThreadedSensor::GrabUntilEnd() {
  NoteFrame();
  while (!stop_requested_) {
    absl::StatusOr<GrabResult> grabbed = Grab();
    if (!grabbed.ok()) return grabbed.status();
    if (*grabbed == GrabResult::kEnd) return absl::OkStatus();
    if (*grabbed == GrabResult::kFrame || stall_.timeout_s <= 0) continue;
    if (SteadyNowNs() - last_frame_steady_ns_ > SecondsToNs(stall_.timeout_s)) {
      return absl::UnavailableError(absl::StrCat(sensor_id_, ": no ", stall_.frame, " for ",
                                                 stall_.timeout_s, " s; ", stall_.device,
                                                 " stopped streaming"));
    }
  }
  return absl::OkStatus();
}

}  // namespace reenact::capture
