// Kinect v2 through libfreenect2 (OpenKinect). Compiled only when CMake finds
// the freenect2 pkg-config module (REENACT_HAVE_FREENECT2).
//
// Streams: depth 512x424 (libfreenect2 delivers float millimetres; rounded to
// uint16, 0 where invalid) and colour 1920x1080 (BGRX, converted to RGB),
// taken together from a SyncMultiFrameListener so each depth frame comes with
// the colour frame of the same instant. Depth is not registered
// (provides_registration false): the FrameProcessor registers it with the
// device's own calibration.
//
// Calibration: the device's factory parameters as libfreenect2 reads them
// (getIrCameraParams: fx, fy, cx, cy, k1, k2, k3, p1, p2 of the IR camera;
// getColorCameraParams: fx, fy, cx, cy of the colour camera, no distortion);
// colour_from_depth is the nominal KinectV2ColorFromDepth (libfreenect2 keeps
// the extrinsics in a polynomial depth-to-colour mapping, not a rigid
// transform).
//
// Stamps: host stamps are WallNowNs() when the frame pair is handed over;
// device stamps are libfreenect2's 32-bit frame timestamp, measured at 0.125 ms
// per tick (libfreenect2 issue #849: consecutive frames 266-267 ticks apart at
// 30 fps), unwrapped like KinectV1Clock.
#include <cmath>
#include <memory>
#include <mutex>
#include <utility>
#include <vector>

#include <libfreenect2/frame_listener_impl.h>
#include <libfreenect2/logger.h>
#include <libfreenect2/packet_pipeline.h>
#include <libfreenect2/libfreenect2.hpp>

#include "absl/strings/str_cat.h"
#include "capture_daemon/sensors/backends.h"
#include "capture_daemon/sensors/frame_pairing.h"
#include "capture_daemon/sensors/threaded_sensor.h"
#include "common/base/status_macros.h"
#include "common/base/time.h"
#include "common/geometry/camera.h"
#include "common/io/proto_convert.h"

namespace reenact::capture {
namespace {

constexpr int64_t kNsPerTick = 125'000;
constexpr double kStallTimeoutS = 5.0;

// libfreenect2's Freenect2 object must outlive every device it opened; one
// per process, never destroyed.
libfreenect2::Freenect2& Context() {
  static libfreenect2::Freenect2* context = [] {
    libfreenect2::setGlobalLogger(nullptr);  // Library code prints nothing.
    return new libfreenect2::Freenect2;
  }();
  return *context;
}
std::mutex& ContextMutex() {
  static std::mutex* mutex = new std::mutex;
  return *mutex;
}

v1::SensorCalibration CalibrationOf(libfreenect2::Freenect2Device* device, const std::string& id,
                                    const std::string& serial) {
  const libfreenect2::Freenect2Device::IrCameraParams ir = device->getIrCameraParams();
  const libfreenect2::Freenect2Device::ColorCameraParams rgb = device->getColorCameraParams();
  CameraIntrinsics depth = KinectV2DepthIntrinsics();
  if (ir.fx > 0 && ir.fy > 0) {
    depth.fx = ir.fx;
    depth.fy = ir.fy;
    depth.cx = ir.cx;
    depth.cy = ir.cy;
    depth.k1 = ir.k1;
    depth.k2 = ir.k2;
    depth.k3 = ir.k3;
    depth.p1 = ir.p1;
    depth.p2 = ir.p2;
  }
  CameraIntrinsics color = KinectV2ColorIntrinsics();
  if (rgb.fx > 0 && rgb.fy > 0) {
    color.fx = rgb.fx;
    color.fy = rgb.fy;
    color.cx = rgb.cx;
    color.cy = rgb.cy;
  }
  v1::SensorCalibration c;
  c.set_sensor_id(id);
  c.set_model("kinect_v2");
  c.set_serial(serial);
  *c.mutable_depth_intrinsics() = ToProto(depth);
  *c.mutable_color_intrinsics() = ToProto(color);
  *c.mutable_color_from_depth() = ToProto(KinectV2ColorFromDepth());
  *c.mutable_world_from_depth() = ToProto(Rigid3d());
  c.set_depth_scale_m_per_unit(0.001);
  c.set_nominal_fps(30.0);
  return c;
}

class Freenect2Sensor : public ThreadedSensor {
 public:
  Freenect2Sensor(libfreenect2::Freenect2Device* device, v1::SensorInfo info)
      : ThreadedSensor(std::move(info), {kStallTimeoutS, "frame", "the Kinect v2"}),
        device_(device),
        listener_(libfreenect2::Frame::Color | libfreenect2::Frame::Depth) {}

  ~Freenect2Sensor() override {
    Stop();
    std::lock_guard<std::mutex> lock(ContextMutex());
    device_->close();
    delete device_;
  }

 private:
  absl::Status StartStreams() override {
    device_->setColorFrameListener(&listener_);
    device_->setIrAndDepthFrameListener(&listener_);
    if (!device_->start()) {
      return absl::UnavailableError(
          absl::StrCat(sensor_id(), ": libfreenect2 could not start streaming"));
    }
    // The factory parameters are read from the device when streaming starts.
    UpdateInfo([this](v1::SensorInfo& info) {
      *info.mutable_calibration() = CalibrationOf(device_, sensor_id(), info.serial());
    });
    return absl::OkStatus();
  }

  void StopStreams() override { device_->stop(); }

  absl::StatusOr<GrabResult> Grab() override {
    libfreenect2::FrameMap frames;
    if (!listener_.waitForNewFrame(frames, 100)) return GrabResult::kNoFrame;
    NoteFrame();
    Deliver(frames);
    listener_.release(frames);
    return GrabResult::kFrame;
  }

  int64_t DeviceNs(uint32_t ticks) {
    if (!clock_started_) {
      clock_started_ = true;
      unwrapped_ticks_ = ticks;
    } else {
      unwrapped_ticks_ += static_cast<int32_t>(ticks - last_ticks_);
    }
    last_ticks_ = ticks;
    return unwrapped_ticks_ * kNsPerTick;
  }

  // The listener hands depth and colour over together, so no pairing is
  // needed: the pair goes out as one PairedFrame.
  void Deliver(libfreenect2::FrameMap& frames) {
    const int64_t host_ns = WallNowNs();
    libfreenect2::Frame* depth = frames[libfreenect2::Frame::Depth];
    libfreenect2::Frame* color = frames[libfreenect2::Frame::Color];
    if (depth == nullptr) return;
    PairedFrame paired;
    paired.device_stamp_ns = DeviceNs(depth->timestamp);
    paired.host_stamp_ns = host_ns;
    DepthImageMm depth_mm(static_cast<int>(depth->width), static_cast<int>(depth->height));
    const auto* values = reinterpret_cast<const float*>(depth->data);
    for (size_t i = 0; i < depth_mm.data.size(); ++i) {
      const float v = values[i];
      depth_mm.data[i] =
          (std::isfinite(v) && v > 0 && v < 65535) ? static_cast<uint16_t>(std::lround(v)) : 0;
    }
    paired.depth_mm = std::move(depth_mm);
    if (color != nullptr && color->bytes_per_pixel == 4) {
      RgbImage rgb(static_cast<int>(color->width), static_cast<int>(color->height));
      const uint8_t* src = color->data;
      for (size_t i = 0; i < rgb.num_pixels(); ++i) {
        rgb.data[3 * i + 0] = src[4 * i + 2];
        rgb.data[3 * i + 1] = src[4 * i + 1];
        rgb.data[3 * i + 2] = src[4 * i + 0];
      }
      paired.color = std::move(rgb);
    }
    std::vector<PairedFrame> out;
    out.push_back(std::move(paired));
    DeliverPaired(std::move(out));
  }

  libfreenect2::Freenect2Device* device_;
  libfreenect2::SyncMultiFrameListener listener_;
  // Capture-thread state.
  bool clock_started_ = false;
  uint32_t last_ticks_ = 0;
  int64_t unwrapped_ticks_ = 0;
};

}  // namespace

bool Freenect2Built() { return true; }

absl::StatusOr<SensorList> OpenFreenect2Sensors(const std::string& serial,
                                                const SourceOptions& options) {
  std::lock_guard<std::mutex> lock(ContextMutex());
  libfreenect2::Freenect2& context = Context();
  const int count = context.enumerateDevices();
  const bool any = serial.empty() || serial == "any";
  if (count <= 0) {
    return absl::NotFoundError(
        absl::StrCat("no Kinect v2 found (looked for: ", any ? "any" : serial, ")"));
  }
  std::string wanted = any ? context.getDefaultDeviceSerialNumber() : serial;
  bool known = false;
  for (int i = 0; i < count; ++i) known = known || context.getDeviceSerialNumber(i) == wanted;
  if (!known)
    return absl::NotFoundError(absl::StrCat("no Kinect v2 found (looked for: ", serial, ")"));
  libfreenect2::Freenect2Device* device =
      context.openDevice(wanted, new libfreenect2::CpuPacketPipeline());
  if (device == nullptr) {
    return absl::UnavailableError(absl::StrCat("libfreenect2 could not open Kinect v2 ", wanted));
  }
  const std::string id =
      absl::StrCat(options.id_prefix.empty() ? "k" : options.id_prefix, options.first_index);
  v1::SensorInfo info;
  info.set_sensor_id(id);
  info.set_backend("freenect2");
  info.set_model("kinect_v2");
  info.set_serial(wanted);
  info.set_uri(absl::StrCat("freenect2:", wanted));
  info.set_state(v1::SENSOR_STATE_DETECTED);
  info.set_depth_width_px(512);
  info.set_depth_height_px(424);
  info.set_color_width_px(1920);
  info.set_color_height_px(1080);
  info.set_nominal_fps(30.0);
  info.set_provides_registration(false);
  *info.mutable_calibration() = CalibrationOf(device, id, wanted);
  SensorList sensors;
  sensors.push_back(std::make_unique<Freenect2Sensor>(device, std::move(info)));
  return sensors;
}

}  // namespace reenact::capture
