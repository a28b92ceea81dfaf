// Per-sensor processing in reenactd, between the backend and the sync group:
// depth-to-colour registration where the source lacks it, actor segmentation
// where the source gives no mask, and encoding of raw pixels (depth to RVL,
// colour to JPEG). The source's skeleton is passed through.
#pragma once

#include <memory>
#include <string>

#include "absl/status/status.h"
#include "capture_daemon/sensors/sensor.h"
#include "reenact/v1/frame.pb.h"

namespace reenact::capture {

struct ProcessingOptions {
  enum class Mode { kAuto, kOn, kOff };
  // kAuto: register when the source delivers raw depth and colour that are
  // not registered (SensorInfo.provides_registration false).
  Mode registration = Mode::kAuto;
  // kAuto: segment when the source gives no mask.
  Mode segmentation = Mode::kAuto;
  // Length of the start of the stream that builds the background depth model.
  double background_seconds = 1.0;
  // JPEG quality for raw colour, 1..100.
  int jpeg_quality = 90;
  // Encoding of raw depth: "rvl" or "rvl+zstd".
  std::string depth_encoding = "rvl";

  // InvalidArgument naming the first bad field.
  absl::Status Validate() const;
};

class FrameProcessor {
 public:
  // `info` of the sensor whose frames this processor will see.
  static absl::StatusOr<std::unique_ptr<FrameProcessor>> Create(const v1::SensorInfo& info,
                                                                const ProcessingOptions& options);
  virtual ~FrameProcessor() = default;

  // Completes `frame` in place: afterwards frame.frame holds encoded depth,
  // colour when there is any, the mask when segmentation ran or the source
  // gave one, and the source's skeletons; the raw images are released.
  // InvalidArgument for a frame that does not fit the sensor (sizes, ids).
  virtual absl::Status Process(CapturedFrame& frame) = 0;

  // The calibration the processed frames follow (registration makes the
  // depth camera coincide with the colour camera).
  virtual const v1::SensorCalibration& calibration() const = 0;
};

}  // namespace reenact::capture
