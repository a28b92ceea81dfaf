#include "capture_daemon/sensors/frame_pairing.h"

#include <cstdlib>
#include <utility>

namespace reenact::capture {

bool DepthColorPairer::Matches(int64_t a_ns, int64_t b_ns) const {
  return std::llabs(a_ns - b_ns) <= tolerance_ns_;
}

std::vector<PairedFrame> DepthColorPairer::AddDepth(DepthImageMm depth_mm, int64_t device_stamp_ns,
                                                    int64_t host_stamp_ns) {
  std::vector<PairedFrame> out = Flush();
  PairedFrame frame;
  frame.depth_mm = std::move(depth_mm);
  frame.device_stamp_ns = device_stamp_ns;
  frame.host_stamp_ns = host_stamp_ns;
  if (latest_color_.has_value() && Matches(latest_color_stamp_ns_, device_stamp_ns)) {
    frame.color = std::move(latest_color_);
    latest_color_.reset();
    out.push_back(std::move(frame));
  } else {
    pending_depth_ = std::move(frame);
  }
  return out;
}

std::vector<PairedFrame> DepthColorPairer::AddColor(RgbImage color, int64_t device_stamp_ns) {
  std::vector<PairedFrame> out;
  if (pending_depth_.has_value()) {
    if (Matches(pending_depth_->device_stamp_ns, device_stamp_ns)) {
      pending_depth_->color = std::move(color);
      out.push_back(std::move(*pending_depth_));
      pending_depth_.reset();
      return out;
    }
    // Colour of a later instant: the held depth frame's colour was lost.
    if (device_stamp_ns > pending_depth_->device_stamp_ns) out = Flush();
  }
  latest_color_ = std::move(color);
  latest_color_stamp_ns_ = device_stamp_ns;
  return out;
}

std::vector<PairedFrame> DepthColorPairer::Flush() {
  std::vector<PairedFrame> out;
  if (pending_depth_.has_value()) {
    out.push_back(std::move(*pending_depth_));
    pending_depth_.reset();
  }
  return out;
}

CapturedFrame ToCapturedFrame(PairedFrame paired, const std::string& sensor_id, int64_t* next_index,
                              v1::SensorInfo* info) {
  CapturedFrame frame;
  frame.frame.set_sensor_id(sensor_id);
  frame.frame.set_device_stamp_ns(paired.device_stamp_ns);
  frame.frame.set_host_stamp_ns(paired.host_stamp_ns);
  frame.frame.set_frame_index((*next_index)++);
  frame.depth_mm = std::move(paired.depth_mm);
  if (paired.color) frame.color = std::move(paired.color);
  const int64_t offset = paired.host_stamp_ns - paired.device_stamp_ns;
  auto* calibration = info->mutable_calibration();
  if (*next_index == 1 || offset < calibration->clock_offset_ns()) {
    calibration->set_clock_offset_ns(offset);
  }
  info->set_frames_delivered(*next_index);
  return frame;
}

}  // namespace reenact::capture
