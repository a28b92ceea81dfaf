// ValidateFrameSet on a reenact.v1.FrameSet parsed from arbitrary bytes, as
// the ingest service receives it, against a fixed take of three sensors:
// two with 32x24 px calibrations and one whose calibration gives no image
// sizes (so any size within the limits is checked further).
#include <cstddef>
#include <cstdint>

#include "reenact/v1/frame.pb.h"
#include "reenact/v1/sensor.pb.h"
#include "server/store/frame_set_validation.h"

namespace {

reenact::v1::SensorCalibration Sensor(const std::string& id, int width_px, int height_px) {
  reenact::v1::SensorCalibration sensor;
  sensor.set_sensor_id(id);
  for (reenact::v1::CameraIntrinsics* in :
       {sensor.mutable_depth_intrinsics(), sensor.mutable_color_intrinsics()}) {
    in->set_width_px(width_px);
    in->set_height_px(height_px);
    if (width_px > 0) {
      in->set_fx_px(30.0);
      in->set_fy_px(30.0);
      in->set_cx_px(0.5 * (width_px - 1));
      in->set_cy_px(0.5 * (height_px - 1));
    }
  }
  sensor.set_depth_scale_m_per_unit(0.001);
  sensor.set_nominal_fps(30.0);
  return sensor;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static const reenact::server::SensorMap* const sensors = new reenact::server::SensorMap{
      {"k0", Sensor("k0", 32, 24)}, {"k1", Sensor("k1", 32, 24)}, {"free", Sensor("free", 0, 0)}};
  reenact::v1::FrameSet set;
  if (!set.ParseFromArray(data, static_cast<int>(size))) return 0;
  reenact::server::FrameSetLimits limits;  // The server's defaults: a full decode of depth.
  (void)reenact::server::ValidateFrameSet(set, *sensors, limits);
  limits.depth_check = reenact::server::DepthCheck::kHeader;
  (void)reenact::server::ValidateFrameSet(set, *sensors, limits);
  return 0;
}
