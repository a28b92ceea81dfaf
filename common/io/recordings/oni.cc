// OpenNI2 recordings (.oni), read through OpenNI2's own file device
// (openni::Device::open on the file's path, driver libOniFile): the depth
// stream, and the colour stream when the recording has an RGB888 one. The
// player is left at its default pace (real time) and its frames are waited
// for with waitForAnyStream, as from a live device; its manual mode
// (PlaybackControl::setSpeed(-1)) blocks forever in readFrame with some
// builds of the library. The end of the recording is the depth stream's
// frame count (PlaybackControl::getNumberOfFrames) with repeat turned off.
//
// Intrinsics are not stored in .oni files; they are derived from the
// recorded fields of view (as the live OpenNI2 backend of reenactd does),
// or, when the file records none, the Kinect v1 / PrimeSense nominal
// fx = fy = 525, cx = 319.5, cy = 239.5 at 640x480, scaled. Depth recorded in
// 100 micrometre units is converted to millimetres.
//
// OpenNI::initialize() runs once per process and OpenNI::shutdown() never
// (it crashes with some drivers at exit).
#include <OpenNI.h>

#include <cmath>
#include <cstring>

#include "absl/strings/str_cat.h"
#include "common/base/status_macros.h"
#include "common/io/recordings/recording.h"

namespace reenact::recordings {
namespace {

std::string OniError() {
  const char* text = openni::OpenNI::getExtendedError();
  std::string s = text != nullptr ? text : "";
  while (!s.empty() && std::isspace(static_cast<unsigned char>(s.back()))) s.pop_back();
  while (!s.empty() && std::isspace(static_cast<unsigned char>(s.front()))) s.erase(0, 1);
  return s;
}

absl::Status EnsureInitialized() {
  static const absl::Status status = [] {
    if (openni::OpenNI::initialize() != openni::STATUS_OK) {
      return absl::UnavailableError(absl::StrCat("OpenNI2 failed to initialise: ", OniError()));
    }
    return absl::OkStatus();
  }();
  return status;
}

CameraIntrinsics Nominal(int width, int height, float hfov, float vfov) {
  CameraIntrinsics k;
  k.width = width;
  k.height = height;
  if (hfov > 0.01f && vfov > 0.01f && hfov < 3.1f && vfov < 3.1f) {
    k.fx = width / (2.0 * std::tan(hfov / 2.0));
    k.fy = height / (2.0 * std::tan(vfov / 2.0));
    k.cx = (width - 1) / 2.0;
    k.cy = (height - 1) / 2.0;
    return k;
  }
  k.fx = 525.0 * width / 640.0;
  k.fy = 525.0 * height / 480.0;
  k.cx = (319.5 + 0.5) * width / 640.0 - 0.5;
  k.cy = (239.5 + 0.5) * height / 480.0 - 0.5;
  return k;
}

class OniReader : public RecordingReader {
 public:
  ~OniReader() override {
    if (color_created_) {
      color_.stop();
      color_.destroy();
    }
    if (depth_created_) {
      depth_.stop();
      depth_.destroy();
    }
    if (device_open_) device_.close();
  }

  static absl::StatusOr<std::unique_ptr<RecordingReader>> Open(const std::string& path,
                                                               const RecordingOptions& options) {
    RETURN_IF_ERROR(EnsureInitialized());
    std::unique_ptr<OniReader> reader(new OniReader(path, options));
    RETURN_IF_ERROR(reader->Init());
    return std::unique_ptr<RecordingReader>(std::move(reader));
  }

  const RecordingInfo& info() const override { return info_; }

  absl::StatusOr<std::optional<RecordedFrame>> Next() override {
    if (info_.frame_count >= 0 && depth_read_ >= info_.frame_count) {
      return std::optional<RecordedFrame>();
    }
    openni::VideoStream* streams[2] = {&depth_, &color_};
    const int count = color_created_ ? 2 : 1;
    const int timeout_ms = static_cast<int>(options_.oni_frame_timeout_s * 1000);
    for (;;) {
      int ready = -1;
      const openni::Status rc =
          openni::OpenNI::waitForAnyStream(streams, count, &ready, timeout_ms);
      if (rc == openni::STATUS_TIME_OUT) {
        return absl::DeadlineExceededError(
            absl::StrCat(path_, ": the OpenNI2 file device delivered no frame within ",
                         options_.oni_frame_timeout_s, " s after ", depth_read_, " of ",
                         info_.frame_count, " depth frames"));
      }
      openni::VideoFrameRef frame;
      if (rc != openni::STATUS_OK || ready < 0 || ready >= count ||
          streams[ready]->readFrame(&frame) != openni::STATUS_OK || !frame.isValid()) {
        return absl::DataLossError(absl::StrCat(path_, ": reading a frame failed: ", OniError()));
      }
      if (ready == 1) {
        RETURN_IF_ERROR(KeepColor(frame));
        continue;
      }
      return ToFrame(frame);
    }
  }

 private:
  OniReader(std::string path, const RecordingOptions& options)
      : path_(std::move(path)), options_(options) {}

  absl::Status Init() {
    info_.format = RecordingFormat::kOni;
    info_.source = path_;
    if (device_.open(path_.c_str()) != openni::STATUS_OK) {
      return absl::InvalidArgumentError(
          absl::StrCat(path_, ": not an OpenNI2 recording: ", OniError()));
    }
    device_open_ = true;
    if (!device_.isFile()) {
      return absl::InvalidArgumentError(absl::StrCat(path_, " did not open as a recording"));
    }
    const openni::DeviceInfo& device_info = device_.getDeviceInfo();
    info_.model = absl::StrCat("oni:", device_info.getVendor(), " ", device_info.getName());
    openni::PlaybackControl* playback = device_.getPlaybackControl();
    if (playback != nullptr) playback->setRepeatEnabled(false);
    if (!device_.hasSensor(openni::SENSOR_DEPTH) ||
        depth_.create(device_, openni::SENSOR_DEPTH) != openni::STATUS_OK) {
      return absl::InvalidArgumentError(absl::StrCat(path_, ": the recording has no depth stream"));
    }
    depth_created_ = true;
    const openni::VideoMode depth_mode = depth_.getVideoMode();
    const openni::PixelFormat depth_format = depth_mode.getPixelFormat();
    if (depth_format != openni::PIXEL_FORMAT_DEPTH_1_MM &&
        depth_format != openni::PIXEL_FORMAT_DEPTH_100_UM) {
      return absl::UnimplementedError(
          absl::StrCat(path_, ": depth pixel format ", static_cast<int>(depth_format),
                       " (only millimetre and 100-micrometre depth are read)"));
    }
    depth_in_100um_ = depth_format == openni::PIXEL_FORMAT_DEPTH_100_UM;
    depth_width_ = depth_mode.getResolutionX();
    depth_height_ = depth_mode.getResolutionY();
    if (depth_width_ <= 0 || depth_height_ <= 0 ||
        static_cast<uint64_t>(depth_width_) * depth_height_ > options_.max_pixels) {
      return absl::InvalidArgumentError(
          absl::StrCat(path_, ": depth stream of ", depth_width_, "x", depth_height_, " px"));
    }
    info_.nominal_fps = depth_mode.getFps() > 0 ? depth_mode.getFps() : 30;
    if (playback != nullptr) info_.frame_count = playback->getNumberOfFrames(depth_);
    if (info_.frame_count < 0) info_.frame_count = -1;
    info_.depth_lens.pinhole =
        Nominal(depth_width_, depth_height_, depth_.getHorizontalFieldOfView(),
                depth_.getVerticalFieldOfView());
    if (device_.hasSensor(openni::SENSOR_COLOR) &&
        color_.create(device_, openni::SENSOR_COLOR) == openni::STATUS_OK) {
      color_created_ = true;
      const openni::VideoMode color_mode = color_.getVideoMode();
      color_width_ = color_mode.getResolutionX();
      color_height_ = color_mode.getResolutionY();
      if (color_mode.getPixelFormat() != openni::PIXEL_FORMAT_RGB888 || color_width_ <= 0 ||
          color_height_ <= 0 ||
          static_cast<uint64_t>(color_width_) * color_height_ > options_.max_pixels) {
        color_.destroy();  // Colour in another format is left out.
        color_created_ = false;
      } else {
        info_.has_color = true;
        info_.color_lens.pinhole =
            Nominal(color_width_, color_height_, color_.getHorizontalFieldOfView(),
                    color_.getVerticalFieldOfView());
      }
    }
    // Recordings made with registration hold depth in the colour camera's
    // grid; without it the baseline is unknown and left at zero.
    info_.calibration_note =
        "calibration: nominal, from the recorded fields of view (.oni files hold no lens "
        "calibration)";
    if (depth_.start() != openni::STATUS_OK ||
        (color_created_ && color_.start() != openni::STATUS_OK)) {
      return absl::UnavailableError(
          absl::StrCat(path_, ": the recording's streams do not start: ", OniError()));
    }
    return absl::OkStatus();
  }

  absl::Status KeepColor(const openni::VideoFrameRef& frame) {
    if (frame.getWidth() != color_width_ || frame.getHeight() != color_height_ ||
        frame.getStrideInBytes() < color_width_ * 3 ||
        static_cast<int64_t>(frame.getDataSize()) <
            static_cast<int64_t>(frame.getStrideInBytes()) * color_height_) {
      return absl::DataLossError(absl::StrCat(path_, ": colour frame of unexpected size"));
    }
    RgbImage color(color_width_, color_height_);
    const auto* base = static_cast<const uint8_t*>(frame.getData());
    const size_t row = static_cast<size_t>(color_width_) * 3;
    for (int y = 0; y < color_height_; ++y) {
      std::memcpy(&color.data[y * row], base + static_cast<size_t>(y) * frame.getStrideInBytes(),
                  row);
    }
    latest_color_ = std::move(color);
    latest_color_stamp_ns_ = static_cast<int64_t>(frame.getTimestamp()) * 1000;
    return absl::OkStatus();
  }

  absl::StatusOr<std::optional<RecordedFrame>> ToFrame(const openni::VideoFrameRef& frame) {
    if (frame.getWidth() != depth_width_ || frame.getHeight() != depth_height_ ||
        frame.getStrideInBytes() < depth_width_ * 2 ||
        static_cast<int64_t>(frame.getDataSize()) <
            static_cast<int64_t>(frame.getStrideInBytes()) * depth_height_) {
      return absl::DataLossError(absl::StrCat(path_, ": depth frame of unexpected size"));
    }
    RecordedFrame out;
    out.index = depth_read_++;
    out.stamp_ns = static_cast<int64_t>(frame.getTimestamp()) * 1000;
    out.depth_mm = DepthImageMm(depth_width_, depth_height_);
    const auto* base = static_cast<const uint8_t*>(frame.getData());
    for (int y = 0; y < depth_height_; ++y) {
      const auto* row = reinterpret_cast<const uint16_t*>(base + static_cast<size_t>(y) *
                                                                     frame.getStrideInBytes());
      for (int x = 0; x < depth_width_; ++x) {
        out.depth_mm.at(x, y) = depth_in_100um_ ? static_cast<uint16_t>((row[x] + 5) / 10) : row[x];
      }
    }
    const int64_t tolerance = static_cast<int64_t>(0.5e9 / info_.nominal_fps);
    if (latest_color_ && std::abs(latest_color_stamp_ns_ - out.stamp_ns) <= tolerance) {
      out.color_width = color_width_;
      out.color_height = color_height_;
      out.color_stamp_ns = latest_color_stamp_ns_;
      out.color_rgb = *latest_color_;
    }
    return std::optional<RecordedFrame>(std::move(out));
  }

  const std::string path_;
  const RecordingOptions options_;
  RecordingInfo info_;
  openni::Device device_;
  openni::VideoStream depth_, color_;
  bool device_open_ = false, depth_created_ = false, color_created_ = false;
  bool depth_in_100um_ = false;
  int depth_width_ = 0, depth_height_ = 0, color_width_ = 0, color_height_ = 0;
  int64_t depth_read_ = 0;
  std::optional<RgbImage> latest_color_;
  int64_t latest_color_stamp_ns_ = 0;
};

}  // namespace

absl::StatusOr<std::unique_ptr<RecordingReader>> OpenOni(const std::string& path,
                                                         const RecordingOptions& options) {
  return OniReader::Open(path, options);
}

}  // namespace reenact::recordings
