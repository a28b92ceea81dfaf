// Pairs the depth and colour frames of one sensor that belong to the same
// instant. Depth and colour arrive as separate streams from libfreenect and
// OpenNI2, in either order; each depth frame is matched with the colour frame
// whose device stamp lies within a tolerance of its own, and is released
// without colour when none arrives in time (the colour frame was dropped).
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "capture_daemon/sensors/sensor.h"
#include "common/base/image.h"
#include "reenact/v1/frame.pb.h"

namespace reenact::capture {

// A depth frame with the colour of the same instant, when there was one.
struct PairedFrame {
  DepthImageMm depth_mm;
  std::optional<RgbImage> color;
  // Device stamp of the depth frame, nanoseconds on the sensor's clock.
  int64_t device_stamp_ns = 0;
  // Host stamp of the depth frame's arrival, nanoseconds.
  int64_t host_stamp_ns = 0;
};

// A frame of `sensor_id` as the Sensor interface delivers it, numbered
// *next_index (which is then incremented). Also keeps `info` current: its
// frame count, and its clock offset as the smallest host - device offset
// seen so far (the frame with the least transfer latency in it).
CapturedFrame ToCapturedFrame(PairedFrame paired, const std::string& sensor_id, int64_t* next_index,
                              v1::SensorInfo* info);

// Not thread-safe; one per sensor, fed from its event thread.
class DepthColorPairer {
 public:
  // `tolerance_ns`: the largest |depth stamp - colour stamp| that still pairs
  // (half a frame period is the natural choice).
  explicit DepthColorPairer(int64_t tolerance_ns) : tolerance_ns_(tolerance_ns) {}

  // Adds a depth frame; returns the frames that are complete now, oldest
  // first (a depth frame still waiting for colour is held back).
  std::vector<PairedFrame> AddDepth(DepthImageMm depth_mm, int64_t device_stamp_ns,
                                    int64_t host_stamp_ns);
  // Adds a colour frame; returns the frames that are complete now.
  std::vector<PairedFrame> AddColor(RgbImage color, int64_t device_stamp_ns);
  // Releases a held depth frame without colour (end of stream).
  std::vector<PairedFrame> Flush();

 private:
  bool Matches(int64_t a_ns, int64_t b_ns) const;

  int64_t tolerance_ns_;
  std::optional<PairedFrame> pending_depth_;
  std::optional<RgbImage> latest_color_;
  int64_t latest_color_stamp_ns_ = 0;
};

}  // namespace reenact::capture
