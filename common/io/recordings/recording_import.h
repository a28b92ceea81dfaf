// A recording (recording.h) written as a take (common/io/take.h) with the
// streams the capture daemon writes: one sensor's SensorCalibration, then per
// frame a DepthImage (millimetres, RVL + zstd, common/io/depth_codec.h) and,
// when the frame has colour, a ColorImage (JPEG: the recording's own bytes
// when it stores JPEG, else encoded at ImportOptions::jpeg_quality).
//
// Stamps: device_stamp_ns is the recording's own clock; host_stamp_ns (the
// take's timeline) is the import's wall-clock time at the first frame plus
// the device time since the first frame, and clock_offset_ns says so.
#pragma once

#include <cstdint>
#include <functional>
#include <string>

#include "absl/status/statusor.h"
#include "common/io/recordings/recording.h"
#include "reenact/v1/sensor.pb.h"

namespace reenact::recordings {

struct ImportOptions {
  // Sensor id in the take; empty: "k0" for Kinect recordings (Azure Kinect,
  // TUM), "o0" for OpenNI2 ones.
  std::string sensor_id;
  // At most this many frames (0: all).
  int64_t max_frames = 0;
  // Quality of colour that has to be encoded (1..100).
  int jpeg_quality = 90;
  // Take name (TakeInfo.name); empty: the output file's stem.
  std::string take_name;
  // Called after each frame written with the count so far.
  std::function<void(int64_t frames)> progress;
};

struct ImportReport {
  std::string sensor_id;
  int64_t frames = 0;
  int64_t frames_with_color = 0;
  int64_t first_stamp_ns = 0, last_stamp_ns = 0;
  // Largest projection difference between the recording's lens model and
  // the five-coefficient one stored in the take (FitPolynomialLens), pixels.
  double depth_lens_fit_px = 0.0, color_lens_fit_px = 0.0;
};

// The take's SensorCalibration of a recording.
v1::SensorCalibration MakeCalibration(const RecordingInfo& info, const std::string& sensor_id,
                                      double* depth_fit_px = nullptr,
                                      double* color_fit_px = nullptr);

// Reads `reader` to its end (or max_frames) into a new take at `out_path`.
// The reader's errors, TakeWriter's, InvalidArgument for bad options, or
// FailedPrecondition when the recording holds no frame. A failed import
// leaves no file behind.
absl::StatusOr<ImportReport> ImportRecording(RecordingReader& reader, const std::string& out_path,
                                             const ImportOptions& options = {});

}  // namespace reenact::recordings
