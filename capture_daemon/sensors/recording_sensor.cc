// Recordings made by other tools as live sensors (`--source azure-mkv:FILE`,
// `tum:DIR`, `oni:FILE`): a ThreadedSensor whose Grab() reads the next frame
// of a common/io/recordings reader and hands it over at its recorded pace
// (SourceOptions.fast: as fast as consumed). Depth and colour leave as raw
// pixels (an MJPG frame is decoded), so the FrameProcessor encodes them as
// for any device. At the end the stream ends with OK ("end of recording"),
// or, with SourceOptions.loop, the recording starts over with stamps that
// keep increasing by its length plus one frame period. As with playback of
// takes, the first frame comes 200 ms after Start(), so that a take started
// together with the sensors (reenactd --once) holds it.
#include <algorithm>
#include <chrono>
#include <optional>
#include <thread>

#include "absl/strings/str_cat.h"
#include "capture_daemon/sensors/backends.h"
#include "capture_daemon/sensors/threaded_sensor.h"
#include "common/base/status_macros.h"
#include "common/base/time.h"
#include "common/io/jpeg.h"
#include "common/io/recordings/recording.h"
#include "common/io/recordings/recording_import.h"

namespace reenact::capture {
namespace {

constexpr int64_t kFirstFrameDelayNs = 200'000'000;

using recordings::RecordedFrame;
using recordings::RecordingFormat;
using recordings::RecordingReader;

class RecordingSensor : public ThreadedSensor {
 public:
  RecordingSensor(std::string path, RecordingFormat format, std::unique_ptr<RecordingReader> reader,
                  v1::SensorInfo info, const SourceOptions& options)
      : ThreadedSensor(std::move(info), {0.0, "frame", "the recording"}),
        path_(std::move(path)),
        format_(format),
        reader_(std::move(reader)),
        options_(options),
        // `info` now lives in the base: read the rate back from there.
        period_ns_(static_cast<int64_t>(1e9 / std::max(1.0, this->info().nominal_fps()))) {}

  ~RecordingSensor() override { Stop(); }

 private:
  absl::Status StartStreams() override {
    pace_anchor_steady_ns_ = -1;
    return absl::OkStatus();
  }
  void StopStreams() override {}

  absl::StatusOr<GrabResult> Grab() override {
    if (!pending_) {
      ASSIGN_OR_RETURN(std::optional<RecordedFrame> frame, reader_->Next());
      if (!frame) {
        if (!options_.loop || frames_this_pass_ == 0) return GrabResult::kEnd;
        // Start over: the next pass continues the stamps.
        loop_offset_ns_ += last_stamp_ns_ - first_stamp_ns_ + period_ns_;
        frames_this_pass_ = 0;
        ASSIGN_OR_RETURN(reader_, recordings::OpenRecording(path_, format_));
        return GrabResult::kNoFrame;
      }
      if (frames_this_pass_ == 0 && loop_offset_ns_ == 0) first_stamp_ns_ = frame->stamp_ns;
      ++frames_this_pass_;
      last_stamp_ns_ = frame->stamp_ns;
      pending_ = std::move(frame);
    }
    const int64_t stamp_ns = pending_->stamp_ns + loop_offset_ns_;
    const int64_t now = SteadyNowNs();
    if (pace_anchor_steady_ns_ < 0) pace_anchor_steady_ns_ = now + kFirstFrameDelayNs;
    // Recorded pace; --fast: only the first frame waits.
    const int64_t due = pace_anchor_steady_ns_ + (options_.fast ? 0 : stamp_ns - first_stamp_ns_);
    if (due > now) {
      // Wait at most 100 ms per call, so that Stop() is not held up.
      std::this_thread::sleep_for(
          std::chrono::nanoseconds(std::min<int64_t>(due - now, 100'000'000)));
      if (SteadyNowNs() < due) return GrabResult::kNoFrame;
    }
    PairedFrame paired;
    paired.depth_mm = std::move(pending_->depth_mm);
    paired.device_stamp_ns = stamp_ns;
    paired.host_stamp_ns = WallNowNs();
    if (pending_->color_rgb) {
      paired.color = std::move(*pending_->color_rgb);
    } else if (!pending_->color_jpeg.empty()) {
      absl::StatusOr<RgbImage> rgb = DecodeJpeg(pending_->color_jpeg);
      if (!rgb.ok()) {
        return absl::DataLossError(absl::StrCat(sensor_id(), ": colour of frame ", pending_->index,
                                                " of ", path_, ": ", rgb.status().message()));
      }
      paired.color = *std::move(rgb);
    }
    pending_.reset();
    NoteFrame();
    std::vector<PairedFrame> frames;
    frames.push_back(std::move(paired));
    DeliverPaired(std::move(frames));
    return GrabResult::kFrame;
  }

  const std::string path_;
  const RecordingFormat format_;
  std::unique_ptr<RecordingReader> reader_;
  const SourceOptions options_;
  const int64_t period_ns_;
  // Capture-thread state.
  std::optional<RecordedFrame> pending_;
  int64_t pace_anchor_steady_ns_ = -1;
  int64_t first_stamp_ns_ = 0, last_stamp_ns_ = 0, loop_offset_ns_ = 0;
  int64_t frames_this_pass_ = 0;
};

}  // namespace

absl::StatusOr<SensorList> OpenRecordingSensors(const std::string& format_name,
                                                const std::string& path,
                                                const SourceOptions& options) {
  ASSIGN_OR_RETURN(const RecordingFormat format, recordings::ParseFormat(format_name));
  ASSIGN_OR_RETURN(std::unique_ptr<RecordingReader> reader,
                   recordings::OpenRecording(path, format));
  const recordings::RecordingInfo& recording = reader->info();
  const std::string prefix = !options.id_prefix.empty()
                                 ? options.id_prefix
                                 : (format == RecordingFormat::kOni ? "o" : "k");
  const std::string id = absl::StrCat(prefix, options.first_index);
  v1::SensorInfo info;
  info.set_sensor_id(id);
  info.set_backend(format_name);
  info.set_model(recording.model);
  info.set_serial(recording.serial);
  info.set_uri(path);
  info.set_state(v1::SENSOR_STATE_DETECTED);
  info.set_depth_width_px(recording.depth_lens.pinhole.width);
  info.set_depth_height_px(recording.depth_lens.pinhole.height);
  if (recording.has_color) {
    info.set_color_width_px(recording.color_lens.pinhole.width);
    info.set_color_height_px(recording.color_lens.pinhole.height);
  }
  info.set_nominal_fps(recording.nominal_fps);
  // TUM depth was registered to colour when it was recorded.
  info.set_provides_registration(format == RecordingFormat::kTum);
  *info.mutable_calibration() = recordings::MakeCalibration(recording, id);
  SensorList sensors;
  sensors.push_back(
      std::make_unique<RecordingSensor>(path, format, std::move(reader), std::move(info), options));
  return sensors;
}

}  // namespace reenact::capture
