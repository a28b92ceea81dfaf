#include "capture_daemon/sensors/openni2_sensor.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <memory>
#include <optional>
#include <utility>

#include <OpenNI.h>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "capture_daemon/sensors/backends.h"
#include "capture_daemon/sensors/frame_pairing.h"
#include "capture_daemon/sensors/threaded_sensor.h"
#include "common/base/status_macros.h"
#include "common/base/time.h"
#include "common/geometry/camera.h"
#include "common/geometry/transforms.h"
#include "common/io/proto_convert.h"

namespace reenact::capture {
namespace {

constexpr int kPreferredWidth = 640;
constexpr int kPreferredHeight = 480;
constexpr int kPreferredFps = 30;
constexpr double kNominalBaselineM = 0.025;

std::string ExtendedError() {
  const char* text = openni::OpenNI::getExtendedError();
  std::string s = text != nullptr ? text : "";
  while (!s.empty() && (s.back() == '\n' || s.back() == ' ' || s.back() == '\t')) s.pop_back();
  while (!s.empty() && (s.front() == '\n' || s.front() == ' ' || s.front() == '\t')) s.erase(0, 1);
  return s;
}

// OpenNI::initialize() once per process; never shut down (see the header).
absl::Status EnsureInitialized() {
  static const absl::Status status = [] {
    if (openni::OpenNI::initialize() != openni::STATUS_OK) {
      return absl::UnavailableError(
          absl::StrCat("OpenNI2 failed to initialise: ", ExtendedError()));
    }
    return absl::OkStatus();
  }();
  return status;
}

std::string UsbId(const openni::DeviceInfo& info) {
  return absl::StrFormat("%04x:%04x", info.getUsbVendorId(), info.getUsbProductId());
}

// The supported mode of `format` closest to 640x480 @ 30 fps.
std::optional<openni::VideoMode> PickMode(const openni::SensorInfo& sensor,
                                          openni::PixelFormat format) {
  std::optional<openni::VideoMode> best;
  int best_cost = 0;
  const auto& modes = sensor.getSupportedVideoModes();
  for (int i = 0; i < modes.getSize(); ++i) {
    const openni::VideoMode& mode = modes[i];
    if (mode.getPixelFormat() != format) continue;
    const int cost = std::abs(mode.getResolutionX() - kPreferredWidth) +
                     std::abs(mode.getResolutionY() - kPreferredHeight) +
                     10 * std::abs(mode.getFps() - kPreferredFps);
    if (!best || cost < best_cost) {
      best = mode;
      best_cost = cost;
    }
  }
  return best;
}

CameraIntrinsics PinholeFromFov(int width, int height, double hfov_rad, double vfov_rad) {
  CameraIntrinsics k;
  k.width = width;
  k.height = height;
  k.fx = width / (2.0 * std::tan(hfov_rad / 2.0));
  k.fy = height / (2.0 * std::tan(vfov_rad / 2.0));
  k.cx = (width - 1) / 2.0;
  k.cy = (height - 1) / 2.0;
  return k;
}

class Openni2Sensor : public ThreadedSensor {
 public:
  Openni2Sensor(std::unique_ptr<openni::Device> device, std::unique_ptr<openni::VideoStream> depth,
                std::unique_ptr<openni::VideoStream> color, bool depth_in_100um,
                const v1::SensorInfo& info)
      : ThreadedSensor(info, {kOpenni2StallTimeoutS, "frame", "the device"}),
        device_(std::move(device)),
        depth_(std::move(depth)),
        color_(std::move(color)),
        depth_in_100um_(depth_in_100um),
        pairer_(SecondsToNs(0.5 / std::max(1.0, info.nominal_fps()))) {}

  ~Openni2Sensor() override {
    Stop();
    if (color_) color_->destroy();
    depth_->destroy();
    device_->close();
  }

 private:
  absl::Status StartStreams() override {
    if (depth_->start() != openni::STATUS_OK) {
      return absl::UnavailableError(
          absl::StrCat(sensor_id(), ": cannot start the depth stream: ", ExtendedError()));
    }
    if (color_ && color_->start() != openni::STATUS_OK) {
      depth_->stop();
      return absl::UnavailableError(
          absl::StrCat(sensor_id(), ": cannot start the colour stream: ", ExtendedError()));
    }
    return absl::OkStatus();
  }

  void StopStreams() override {
    if (color_) color_->stop();
    depth_->stop();
  }

  absl::StatusOr<GrabResult> Grab() override {
    openni::VideoStream* streams[2] = {depth_.get(), color_.get()};
    const int count = color_ ? 2 : 1;
    int ready = -1;
    const openni::Status rc = openni::OpenNI::waitForAnyStream(streams, count, &ready, 100);
    if (rc == openni::STATUS_TIME_OUT) return GrabResult::kNoFrame;
    openni::VideoFrameRef frame;
    if (rc != openni::STATUS_OK || ready < 0 || ready >= count ||
        streams[ready]->readFrame(&frame) != openni::STATUS_OK || !frame.isValid()) {
      return absl::UnavailableError(absl::StrCat(
          sensor_id(),
          ": OpenNI2 stopped delivering frames (device unplugged?): ", ExtendedError()));
    }
    NoteFrame();
    if (ready == 0) {
      OnDepth(frame);
    } else {
      OnColor(frame);
    }
    return GrabResult::kFrame;
  }

  void FlushHeld() override { DeliverPaired(pairer_.Flush()); }

  void OnDepth(const openni::VideoFrameRef& frame) {
    const int64_t host_ns = WallNowNs();
    DepthImageMm depth(frame.getWidth(), frame.getHeight());
    const auto* base = static_cast<const uint8_t*>(frame.getData());
    for (int y = 0; y < depth.height; ++y) {
      const auto* row = reinterpret_cast<const uint16_t*>(base + static_cast<size_t>(y) *
                                                                     frame.getStrideInBytes());
      for (int x = 0; x < depth.width; ++x) {
        depth.at(x, y) = depth_in_100um_ ? static_cast<uint16_t>((row[x] + 5) / 10) : row[x];
      }
    }
    const int64_t device_ns = static_cast<int64_t>(frame.getTimestamp()) * 1000;
    DeliverPaired(pairer_.AddDepth(std::move(depth), device_ns, host_ns));
  }

  void OnColor(const openni::VideoFrameRef& frame) {
    RgbImage color(frame.getWidth(), frame.getHeight());
    const auto* base = static_cast<const uint8_t*>(frame.getData());
    const size_t row_bytes = static_cast<size_t>(color.width) * 3;
    for (int y = 0; y < color.height; ++y) {
      std::memcpy(&color.data[y * row_bytes],
                  base + static_cast<size_t>(y) * frame.getStrideInBytes(), row_bytes);
    }
    const int64_t device_ns = static_cast<int64_t>(frame.getTimestamp()) * 1000;
    DeliverPaired(pairer_.AddColor(std::move(color), device_ns));
  }

  std::unique_ptr<openni::Device> device_;
  std::unique_ptr<openni::VideoStream> depth_;
  std::unique_ptr<openni::VideoStream> color_;
  const bool depth_in_100um_;
  // Capture-thread state.
  DepthColorPairer pairer_;
};

// Creates and configures one stream; nullptr when the device lacks the sensor.
absl::StatusOr<std::unique_ptr<openni::VideoStream>> CreateStream(openni::Device& device,
                                                                  openni::SensorType type,
                                                                  const openni::VideoMode& mode) {
  auto stream = std::make_unique<openni::VideoStream>();
  if (stream->create(device, type) != openni::STATUS_OK) {
    return absl::UnavailableError(
        absl::StrCat("cannot create an OpenNI2 stream: ", ExtendedError()));
  }
  if (stream->setVideoMode(mode) != openni::STATUS_OK) {
    stream->destroy();
    return absl::UnavailableError(
        absl::StrCat("cannot set the OpenNI2 video mode: ", ExtendedError()));
  }
  stream->setMirroringEnabled(false);
  return stream;
}

}  // namespace

absl::StatusOr<std::vector<Openni2DeviceEntry>> ListOpenni2Devices() {
  RETURN_IF_ERROR(EnsureInitialized());
  openni::Array<openni::DeviceInfo> list;
  openni::OpenNI::enumerateDevices(&list);
  std::vector<Openni2DeviceEntry> out;
  out.reserve(std::max(0, list.getSize()));
  for (int i = 0; i < list.getSize(); ++i) {
    out.push_back({list[i].getUri(), list[i].getVendor(), list[i].getName(), UsbId(list[i])});
  }
  return out;
}

absl::StatusOr<SensorList> OpenOpenni2Sensors(const std::string& uri,
                                              const SourceOptions& options) {
  ASSIGN_OR_RETURN(std::vector<Openni2DeviceEntry> devices, ListOpenni2Devices());
  const bool any = uri.empty() || uri == "any";
  const std::string looked_for = any ? "any" : uri;
  if (any && devices.empty()) {
    return absl::NotFoundError("no OpenNI2 device found (looked for: any)");
  }
  std::string open_uri = any ? devices.front().uri : uri;
  std::string usb_id;
  for (const auto& d : devices) {
    if (d.uri == open_uri) usb_id = d.usb_id;
  }
  auto device = std::make_unique<openni::Device>();
  // A URI that is not enumerated may still open (an .oni recording).
  if (device->open(open_uri.c_str()) != openni::STATUS_OK) {
    return absl::NotFoundError(
        absl::StrCat("no OpenNI2 device found (looked for: ", looked_for, "): ", ExtendedError()));
  }
  const openni::SensorInfo* depth_info = device->getSensorInfo(openni::SENSOR_DEPTH);
  if (depth_info == nullptr) {
    device->close();
    return absl::FailedPreconditionError(absl::StrCat(open_uri, " has no depth sensor"));
  }
  std::optional<openni::VideoMode> depth_mode =
      PickMode(*depth_info, openni::PIXEL_FORMAT_DEPTH_1_MM);
  const bool depth_in_100um = !depth_mode.has_value();
  if (!depth_mode) depth_mode = PickMode(*depth_info, openni::PIXEL_FORMAT_DEPTH_100_UM);
  if (!depth_mode) {
    device->close();
    return absl::FailedPreconditionError(
        absl::StrCat(open_uri, " offers no millimetre or 100-micrometre depth mode"));
  }
  auto depth_or = CreateStream(*device, openni::SENSOR_DEPTH, *depth_mode);
  if (!depth_or.ok()) {
    device->close();
    return depth_or.status();
  }
  std::unique_ptr<openni::VideoStream> depth = *std::move(depth_or);
  std::unique_ptr<openni::VideoStream> color;
  std::optional<openni::VideoMode> color_mode;
  if (const openni::SensorInfo* color_info = device->getSensorInfo(openni::SENSOR_COLOR)) {
    color_mode = PickMode(*color_info, openni::PIXEL_FORMAT_RGB888);
    if (color_mode) {
      auto color_or = CreateStream(*device, openni::SENSOR_COLOR, *color_mode);
      if (color_or.ok()) color = *std::move(color_or);
    }
  }
  bool registered = false;
  if (color &&
      device->isImageRegistrationModeSupported(openni::IMAGE_REGISTRATION_DEPTH_TO_COLOR)) {
    device->setImageRegistrationMode(openni::IMAGE_REGISTRATION_DEPTH_TO_COLOR);
    registered = device->getImageRegistrationMode() == openni::IMAGE_REGISTRATION_DEPTH_TO_COLOR;
  }
  if (color) device->setDepthColorSyncEnabled(true);

  char serial[256] = {0};
  int serial_size = sizeof(serial) - 1;
  if (device->getProperty(openni::DEVICE_PROPERTY_SERIAL_NUMBER, serial, &serial_size) !=
      openni::STATUS_OK) {
    serial[0] = '\0';
  }
  const openni::DeviceInfo& device_info = device->getDeviceInfo();
  const std::string id =
      absl::StrCat(options.id_prefix.empty() ? "o" : options.id_prefix, options.first_index);
  const int depth_w = depth_mode->getResolutionX(), depth_h = depth_mode->getResolutionY();
  CameraIntrinsics depth_k = PinholeFromFov(depth_w, depth_h, depth->getHorizontalFieldOfView(),
                                            depth->getVerticalFieldOfView());
  CameraIntrinsics color_k = depth_k;
  if (color) {
    color_k = PinholeFromFov(color_mode->getResolutionX(), color_mode->getResolutionY(),
                             color->getHorizontalFieldOfView(), color->getVerticalFieldOfView());
  }
  Rigid3d color_from_depth;
  if (registered) {
    // Registered depth lies in the colour camera's pixel grid (scaled to the
    // depth resolution).
    depth_k = ScaledIntrinsics(color_k, depth_w, depth_h).value_or(depth_k);
  } else if (color) {
    color_from_depth.translation = Eigen::Vector3d(-kNominalBaselineM, 0, 0);
  }

  v1::SensorInfo info;
  info.set_sensor_id(id);
  info.set_backend("openni2");
  info.set_model(absl::StrCat("openni2:", device_info.getVendor(), " ", device_info.getName()));
  info.set_serial(serial);
  info.set_uri(open_uri);
  info.set_state(v1::SENSOR_STATE_DETECTED);
  info.set_depth_width_px(depth_w);
  info.set_depth_height_px(depth_h);
  if (color) {
    info.set_color_width_px(color_mode->getResolutionX());
    info.set_color_height_px(color_mode->getResolutionY());
  }
  info.set_nominal_fps(depth_mode->getFps());
  info.set_provides_registration(registered);
  info.set_usb_id(usb_id.empty() ? UsbId(device_info) : usb_id);
  v1::SensorCalibration* c = info.mutable_calibration();
  c->set_sensor_id(id);
  c->set_model(info.model());
  c->set_serial(serial);
  *c->mutable_depth_intrinsics() = ToProto(depth_k);
  if (color) *c->mutable_color_intrinsics() = ToProto(color_k);
  *c->mutable_color_from_depth() = ToProto(color_from_depth);
  *c->mutable_world_from_depth() = ToProto(Rigid3d());
  c->set_depth_scale_m_per_unit(0.001);
  c->set_nominal_fps(depth_mode->getFps());

  SensorList sensors;
  sensors.push_back(std::make_unique<Openni2Sensor>(
      std::move(device), std::move(depth), std::move(color), depth_in_100um, std::move(info)));
  return sensors;
}

}  // namespace reenact::capture
