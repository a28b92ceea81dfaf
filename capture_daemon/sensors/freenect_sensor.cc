#include "capture_daemon/sensors/freenect_sensor.h"

#include <dlfcn.h>
#include <sys/time.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstring>
#include <limits>
#include <memory>
#include <mutex>
#include <utility>
#include <vector>

#include <libfreenect.h>
#include <Eigen/Core>

#include "absl/strings/str_cat.h"
#include "capture_daemon/sensors/backends.h"
#include "capture_daemon/sensors/frame_pairing.h"
#include "capture_daemon/sensors/threaded_sensor.h"
#include "common/base/status_macros.h"
#include "common/base/time.h"
#include "common/geometry/camera.h"
#include "common/geometry/transforms.h"
#include "common/io/proto_convert.h"

namespace reenact::capture {

uint16_t KinectV1RawToMm(uint16_t raw) {
  if (raw >= kKinectV1RawNoValue) return 0;
  const double denominator = 3.3309495161 - 0.0030711016 * raw;
  if (denominator <= 0) return 0;
  const double z_mm = 1000.0 / denominator;
  if (z_mm < 300.0 || z_mm > 10000.0) return 0;
  return static_cast<uint16_t>(std::lround(z_mm));
}

int64_t KinectV1Clock::ToNs(uint32_t ticks) {
  if (!started_) {
    started_ = true;
    unwrapped_ticks_ = ticks;
  } else {
    // Modular difference: a wrap shows up as a small positive step.
    const int32_t step = static_cast<int32_t>(ticks - last_ticks_);
    unwrapped_ticks_ += step;
  }
  last_ticks_ = ticks;
  // 1e9 / 60e6 = 50 / 3 ns per tick.
  return unwrapped_ticks_ * 50 / 3;
}

v1::SensorCalibration KinectV1DefaultCalibration(const std::string& sensor_id,
                                                 const std::string& serial) {
  CameraIntrinsics depth;
  depth.width = 640;
  depth.height = 480;
  depth.fx = 5.9421434211923247e+02;
  depth.fy = 5.9104053696870778e+02;
  depth.cx = 3.3930780975300314e+02;
  depth.cy = 2.4273913761751615e+02;
  depth.k1 = -2.6386489753128833e-01;
  depth.k2 = 9.9966832163729757e-01;
  depth.p1 = -7.6275862143610667e-04;
  depth.p2 = 5.0350940090814270e-03;
  depth.k3 = -1.3053628089976321e+00;
  CameraIntrinsics color;
  color.width = 640;
  color.height = 480;
  color.fx = 5.2921508098293293e+02;
  color.fy = 5.2556393630057437e+02;
  color.cx = 3.2894272028759258e+02;
  color.cy = 2.6748068171871557e+02;
  color.k1 = 2.6451622333009589e-01;
  color.k2 = -8.3990749424620825e-01;
  color.p1 = -1.9922302173693159e-03;
  color.p2 = 1.4371995932897616e-03;
  color.k3 = 9.1192465078713847e-01;
  Eigen::Matrix<double, 3, 4> color_from_depth;
  color_from_depth << 9.9984628826577793e-01, 1.2635359098409581e-03, -1.7487233004436643e-02,
      1.9985242312092553e-02,  //
      -1.4779096108364480e-03, 9.9992385683542895e-01, -1.2251380107679535e-02,
      -7.4423738761617583e-04,  //
      1.7470421412464927e-02, 1.2275341476520762e-02, 9.9977202419716948e-01,
      -1.0916736334336222e-02;
  // The published matrix is orthonormal to ~1e-8; re-orthonormalise so the
  // quaternion is exact.
  Rigid3d transform = Rigid3d::FromMatrix(color_from_depth);
  transform.rotation.normalize();

  v1::SensorCalibration c;
  c.set_sensor_id(sensor_id);
  c.set_model("kinect_v1");
  c.set_serial(serial);
  *c.mutable_depth_intrinsics() = ToProto(depth);
  *c.mutable_color_intrinsics() = ToProto(color);
  *c.mutable_color_from_depth() = ToProto(transform);
  *c.mutable_world_from_depth() = ToProto(Rigid3d());
  c.set_clock_offset_ns(0);
  c.set_depth_scale_m_per_unit(0.001);
  c.set_nominal_fps(30.0);
  return c;
}

namespace {

constexpr int kWidth = 640;
constexpr int kHeight = 480;
constexpr double kFps = 30.0;

// libfreenect's log messages go here instead of stderr (library code prints
// nothing); the last error is quoted in error messages.
std::mutex log_mutex;
std::string& LastLogMessage() {
  static std::string* message = new std::string;
  return *message;
}
void RecordLog(freenect_context*, freenect_loglevel level, const char* msg) {
  if (level > FREENECT_LOG_ERROR || msg == nullptr) return;
  std::lock_guard<std::mutex> lock(log_mutex);
  std::string text(msg);
  while (!text.empty() && std::isspace(static_cast<unsigned char>(text.back()))) text.pop_back();
  LastLogMessage() = text;
}
std::string LogSuffix() {
  std::lock_guard<std::mutex> lock(log_mutex);
  return LastLogMessage().empty() ? "" : absl::StrCat(" (libfreenect: ", LastLogMessage(), ")");
}

// A freenect context with our logging; shut down on destruction.
struct ContextDeleter {
  void operator()(freenect_context* ctx) const {
    if (ctx != nullptr) freenect_shutdown(ctx);
  }
};
using ContextPtr = std::unique_ptr<freenect_context, ContextDeleter>;

absl::StatusOr<ContextPtr> InitContext() {
  freenect_context* ctx = nullptr;
  if (const int rc = freenect_init(&ctx, nullptr); rc < 0 || ctx == nullptr) {
    return absl::UnavailableError(
        absl::StrCat("libfreenect could not initialise USB access (error ", rc, ")", LogSuffix()));
  }
  freenect_set_log_callback(ctx, &RecordLog);
  freenect_set_log_level(ctx, FREENECT_LOG_ERROR);
  // Only the cameras: the motor and audio are not needed, and the Kinect for
  // Windows and model 1473 expose no separate motor device.
  freenect_select_subdevices(ctx, FREENECT_DEVICE_CAMERA);
  return ContextPtr(ctx);
}

// Serials of the connected devices in index order. The device-attribute
// functions are looked up at run time: fakenect's stand-in library does not
// have them, and a missing symbol must not stop playback.
std::vector<std::string> ListSerials(freenect_context* ctx) {
  using ListFn = int (*)(freenect_context*, freenect_device_attributes**);
  using FreeFn = void (*)(freenect_device_attributes*);
  auto list = reinterpret_cast<ListFn>(dlsym(RTLD_DEFAULT, "freenect_list_device_attributes"));
  auto release = reinterpret_cast<FreeFn>(dlsym(RTLD_DEFAULT, "freenect_free_device_attributes"));
  std::vector<std::string> serials;
  if (list == nullptr || release == nullptr) return serials;
  freenect_device_attributes* attributes = nullptr;
  if (list(ctx, &attributes) < 0) return serials;
  for (auto* a = attributes; a != nullptr; a = a->next) {
    serials.emplace_back(a->camera_serial != nullptr ? a->camera_serial : "");
  }
  release(attributes);
  return serials;
}

// Finds a medium-resolution mode by enumeration (asking fakenect for a mode
// it does not have trips an assertion inside it).
std::optional<freenect_frame_mode> FindDepthMode(freenect_depth_format format) {
  for (int i = 0; i < freenect_get_depth_mode_count(); ++i) {
    const freenect_frame_mode mode = freenect_get_depth_mode(i);
    if (mode.is_valid && mode.resolution == FREENECT_RESOLUTION_MEDIUM &&
        mode.depth_format == format && mode.width == kWidth && mode.height == kHeight) {
      return mode;
    }
  }
  return std::nullopt;
}
std::optional<freenect_frame_mode> FindVideoMode(freenect_video_format format) {
  for (int i = 0; i < freenect_get_video_mode_count(); ++i) {
    const freenect_frame_mode mode = freenect_get_video_mode(i);
    if (mode.is_valid && mode.resolution == FREENECT_RESOLUTION_MEDIUM &&
        mode.video_format == format && mode.width == kWidth && mode.height == kHeight) {
      return mode;
    }
  }
  return std::nullopt;
}

class FreenectSensor : public ThreadedSensor {
 public:
  FreenectSensor(ContextPtr ctx, freenect_device* device, v1::SensorInfo info)
      : ThreadedSensor(std::move(info), {kFreenectStallTimeoutS, "depth frame", "the Kinect"}),
        ctx_(std::move(ctx)),
        device_(device),
        pairer_(SecondsToNs(0.5 / kFps)) {}

  ~FreenectSensor() override {
    Stop();
    if (device_ != nullptr) freenect_close_device(device_);
  }

 private:
  absl::Status StartStreams() override {
    RETURN_IF_ERROR(ConfigureModes());
    freenect_set_user(device_, this);
    freenect_set_depth_callback(device_, &FreenectSensor::DepthThunk);
    freenect_set_video_callback(device_, &FreenectSensor::VideoThunk);
    if (freenect_start_depth(device_) < 0) {
      return absl::UnavailableError(
          absl::StrCat(sensor_id(), ": cannot start the depth stream", LogSuffix()));
    }
    if (freenect_start_video(device_) < 0) {
      freenect_stop_depth(device_);
      return absl::UnavailableError(
          absl::StrCat(sensor_id(), ": cannot start the colour stream", LogSuffix()));
    }
    return absl::OkStatus();
  }

  void StopStreams() override {
    freenect_stop_video(device_);
    freenect_stop_depth(device_);
  }

  // libfreenect calls OnDepth and OnVideo from inside
  // freenect_process_events_timeout, on this thread. It does not say whether
  // a frame came, so the stall check runs after every call; OnDepth restarts
  // its clock (colour alone does not keep a stream alive).
  absl::StatusOr<GrabResult> Grab() override {
    timeval timeout{0, 100'000};
    const int rc = freenect_process_events_timeout(ctx_.get(), &timeout);
    if (rc < 0) {
      return absl::UnavailableError(
          absl::StrCat(sensor_id(), ": libfreenect stopped delivering events (error ", rc,
                       "): the Kinect was unplugged or the recording ended", LogSuffix()));
    }
    return GrabResult::kNoFrame;
  }

  void FlushHeld() override { DeliverPaired(pairer_.Flush()); }

  absl::Status ConfigureModes() {
    std::optional<freenect_frame_mode> depth_mode = FindDepthMode(FREENECT_DEPTH_MM);
    depth_is_mm_ = depth_mode.has_value();
    if (!depth_mode) depth_mode = FindDepthMode(FREENECT_DEPTH_11BIT);
    if (!depth_mode) {
      return absl::UnimplementedError(
          "libfreenect offers neither a 640x480 millimetre nor an 11-bit depth mode");
    }
    const std::optional<freenect_frame_mode> video_mode = FindVideoMode(FREENECT_VIDEO_RGB);
    if (!video_mode) return absl::UnimplementedError("libfreenect offers no 640x480 RGB mode");
    if (freenect_set_depth_mode(device_, *depth_mode) < 0 ||
        freenect_set_video_mode(device_, *video_mode) < 0) {
      return absl::UnavailableError(
          absl::StrCat(sensor_id(), ": cannot set the depth/colour modes", LogSuffix()));
    }
    return absl::OkStatus();
  }

  static void DepthThunk(freenect_device* dev, void* data, uint32_t timestamp) {
    static_cast<FreenectSensor*>(freenect_get_user(dev))->OnDepth(data, timestamp);
  }
  static void VideoThunk(freenect_device* dev, void* data, uint32_t timestamp) {
    static_cast<FreenectSensor*>(freenect_get_user(dev))->OnVideo(data, timestamp);
  }

  void OnDepth(const void* data, uint32_t timestamp) {
    const int64_t host_ns = WallNowNs();
    NoteFrame();
    DepthImageMm depth(kWidth, kHeight);
    // libfreenect's buffer need not be 2-byte aligned (fakenect hands out a
    // pointer just past a recording's text header), so the samples are
    // copied out as bytes before they are read as uint16_t.
    std::memcpy(depth.data.data(), data, depth.data.size() * sizeof(uint16_t));
    if (!depth_is_mm_) {
      for (uint16_t& value : depth.data) value = KinectV1RawToMm(value);
    }
    DeliverPaired(pairer_.AddDepth(std::move(depth), clock_.ToNs(timestamp), host_ns));
  }

  void OnVideo(const void* data, uint32_t timestamp) {
    RgbImage color(kWidth, kHeight);
    std::memcpy(color.data.data(), data, color.data.size());
    DeliverPaired(pairer_.AddColor(std::move(color), clock_.ToNs(timestamp)));
  }

  ContextPtr ctx_;
  freenect_device* device_;
  // Capture-thread state (depth_is_mm_ is set by StartStreams before the
  // thread starts).
  bool depth_is_mm_ = false;
  DepthColorPairer pairer_;
  KinectV1Clock clock_;
};

bool IsIndex(const std::string& s) {
  return !s.empty() && s.size() < 4 && std::all_of(s.begin(), s.end(), [](char c) {
    return std::isdigit(static_cast<unsigned char>(c));
  });
}

struct Target {
  int index = -1;      // Open by index when >= 0.
  std::string serial;  // Open by serial otherwise; known serial either way.
};

absl::StatusOr<std::vector<Target>> ResolveTargets(const std::string& device) {
  ASSIGN_OR_RETURN(ContextPtr probe, InitContext());
  const int count = freenect_num_devices(probe.get());
  const std::string looked_for = device.empty() ? "all" : device;
  if (count <= 0) {
    return absl::NotFoundError(
        absl::StrCat("no Kinect v1 found (looked for: ", looked_for, ")", LogSuffix()));
  }
  const std::vector<std::string> serials = ListSerials(probe.get());
  auto serial_of = [&](int i) { return i < static_cast<int>(serials.size()) ? serials[i] : ""; };
  std::vector<Target> targets;
  if (device.empty() || device == "all" || device == "any") {
    for (int i = 0; i < count; ++i) targets.push_back({i, serial_of(i)});
  } else if (IsIndex(device)) {
    const int index = std::stoi(device);
    if (index >= count) {
      return absl::NotFoundError(absl::StrCat("no Kinect v1 with index ", index, " (looked for: ",
                                              looked_for, "; ", count, " connected)"));
    }
    targets.push_back({index, serial_of(index)});
  } else {
    if (!serials.empty() && std::find(serials.begin(), serials.end(), device) == serials.end()) {
      return absl::NotFoundError(
          absl::StrCat("no Kinect v1 with serial ", device, " (looked for: ", looked_for, ")"));
    }
    targets.push_back({-1, device});
  }
  return targets;
}

}  // namespace

absl::StatusOr<SensorList> OpenFreenectSensors(const std::string& device,
                                               const SourceOptions& options) {
  ASSIGN_OR_RETURN(std::vector<Target> targets, ResolveTargets(device));
  const std::string prefix = options.id_prefix.empty() ? "k" : options.id_prefix;
  SensorList sensors;
  for (size_t k = 0; k < targets.size(); ++k) {
    const Target& target = targets[k];
    ASSIGN_OR_RETURN(ContextPtr ctx, InitContext());
    freenect_device* dev = nullptr;
    const int rc = target.index >= 0 ? freenect_open_device(ctx.get(), &dev, target.index)
                                     : freenect_open_device_by_camera_serial(ctx.get(), &dev,
                                                                             target.serial.c_str());
    const std::string uri = target.index >= 0 ? absl::StrCat("freenect:", target.index)
                                              : absl::StrCat("freenect:serial:", target.serial);
    if (rc < 0 || dev == nullptr) {
      return absl::UnavailableError(
          absl::StrCat("cannot open Kinect v1 ", uri, " (error ", rc, ")", LogSuffix()));
    }
    const std::string id = absl::StrCat(prefix, options.first_index + static_cast<int>(k));
    v1::SensorInfo info;
    info.set_sensor_id(id);
    info.set_backend("freenect");
    info.set_model("kinect_v1");
    info.set_serial(target.serial);
    info.set_uri(uri);
    info.set_state(v1::SENSOR_STATE_DETECTED);
    info.set_depth_width_px(kWidth);
    info.set_depth_height_px(kHeight);
    info.set_color_width_px(kWidth);
    info.set_color_height_px(kHeight);
    info.set_nominal_fps(kFps);
    info.set_provides_skeleton(false);
    info.set_provides_mask(false);
    info.set_provides_registration(false);
    *info.mutable_calibration() = KinectV1DefaultCalibration(id, target.serial);
    sensors.push_back(std::make_unique<FreenectSensor>(std::move(ctx), dev, std::move(info)));
  }
  return sensors;
}

}  // namespace reenact::capture
