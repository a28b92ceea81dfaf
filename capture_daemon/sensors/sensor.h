// The sensor interface of reenactd: a Sensor streams CapturedFrames from its
// own thread until it is stopped or its source ends. Backends: playback of
// MCAP takes (capture_daemon/sensors/playback_sensor.h), Kinect v1 through
// libfreenect, OpenNI2 devices, Kinect v2 through libfreenect2 when it was
// found at build time (capture_daemon/sensors/backends.h).
#pragma once

#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "common/base/image.h"
#include "reenact/v1/frame.pb.h"

namespace reenact::capture {

// One depth frame of one sensor with what came with it.
struct CapturedFrame {
  // Always set: sensor_id, device_stamp_ns, host_stamp_ns (capture time on
  // the host clock), frame_index. Sources that deliver encoded data fill the
  // nested messages (playback passes a take's JPEG/RVL bytes through
  // unchanged); sources that deliver pixels leave them empty and set the raw
  // images below, which the FrameProcessor encodes.
  v1::Frame frame;
  // Depth in millimetres along z in the depth camera (0: no measurement).
  std::optional<DepthImageMm> depth_mm;
  // Colour pixels (RGB).
  std::optional<RgbImage> color;
};

// Called on the backend's thread for every frame.
using FrameCallback = std::function<void(CapturedFrame frame)>;
// Called once when the stream ends by itself: OK at the end of a recording,
// an error (e.g. Unavailable "device unplugged") when the device went away or
// failed. Not called after Stop().
using EndCallback = std::function<void(const absl::Status& why)>;

class Sensor {
 public:
  virtual ~Sensor() = default;
  // Id, backend, model, sizes, calibration and what the source provides.
  virtual v1::SensorInfo info() const = 0;
  // Starts streaming. FailedPrecondition when already started.
  virtual absl::Status Start(FrameCallback on_frame, EndCallback on_end) = 0;
  // Stops streaming and joins the backend's thread; idempotent.
  virtual void Stop() = 0;
};

// Options shared by the backends.
struct SourceOptions {
  // Playback: deliver frames as fast as they are consumed instead of at the
  // recorded pace.
  bool fast = false;
  // Playback: start over at the end of the take (stamps keep increasing).
  bool loop = false;
  // Prefix of the sensor ids a backend assigns ("k" gives k0, k1, ...);
  // playback keeps the take's ids when empty.
  std::string id_prefix;
  // First index used with id_prefix.
  int first_index = 0;
};

}  // namespace reenact::capture
