// Azure Kinect recordings (k4arecorder), read through libavformat.
//
// The layout, after the Azure Kinect Sensor SDK's "Recording file format"
// page: a Matroska file with one video track per camera, named by the track
// name ("COLOR", "DEPTH", "IR"; Matroska TrackName, libavformat's "title"),
// an IMU track, and the device's factory calibration as an attachment named
// "calibration.json". Depth and IR are V_MS/VFW/FOURCC tracks of codec "b16g":
// one uncompressed 16-bit image per block, big-endian as the FOURCC says
// (checked against the SDK's own decoding of a real recording: the shared
// data's derived/depth_640x576_mm.png), depth in millimetres. Colour here is MJPG
// (one JPEG per block). Block timestamps are the device timestamps minus the
// tag K4A_START_OFFSET_NS.
//
// The calibration (calibration.json, the SDK's raw calibration format):
// CalibrationInformation.Cameras[] holds, per camera, Location
// ("CALIBRATION_CameraLocationD0" depth, "..PV0" colour), SensorWidth/Height
// of the full sensor, Intrinsics.ModelParameters
//   [cx, cy, fx, fy, k1, k2, k3, k4, k5, k6, codx, cody, p2, p1]
// (note p2 before p1) with cx, cy, fx, fy divided by the sensor size and
// measured from the image corner, and Rt: Rotation (row-major 3x3) and
// Translation in metres (the SDK multiplies by 1000 for its millimetre API)
// mapping points of the depth camera (the reference, identity Rt) into the
// camera's frame. The intrinsics of a recorded mode follow the SDK's
// transformation_get_mode_specific_camera_calibration(): scale by the binned
// resolution of the mode, subtract the crop offset, and move the origin to
// the centre of the top-left pixel (-0.5):
//   depth NFOV unbinned 640x576: binned 1024x1024, crop (192, 180)
//   depth NFOV 2x2 binned 320x288: 512x512, (96, 90)
//   depth WFOV 2x2 binned 512x512: 512x512, (0, 0)
//   depth WFOV unbinned 1024x1024: 1024x1024, (0, 0)
//   colour WxH: binned W x 3W/4, crop (0, (3W/4 - H) / 2) (a 4:3 sensor;
//   older 16:9 calibrations are first mapped onto 4:3, as the SDK does).
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <deque>
#include <optional>

#include <nlohmann/json.hpp>

extern "C" {
#include <libavformat/avformat.h>
#include <libavutil/error.h>
#include <libavutil/log.h>
}

#include "absl/strings/str_cat.h"
#include "common/base/status_macros.h"
#include "common/io/recordings/recording.h"

namespace reenact::recordings {
namespace {

constexpr int64_t kMaxCalibrationBytes = 1 << 20;

std::string AvError(int code) {
  char text[AV_ERROR_MAX_STRING_SIZE] = {0};
  av_strerror(code, text, sizeof(text));
  return text;
}

std::string Tag(AVDictionary* metadata, const char* key) {
  const AVDictionaryEntry* entry = av_dict_get(metadata, key, nullptr, 0);
  return entry != nullptr && entry->value != nullptr ? entry->value : "";
}

struct ModeInfo {
  double binned_width, binned_height, crop_x, crop_y;
};

absl::StatusOr<ModeInfo> DepthMode(int width, int height) {
  if (width == 640 && height == 576) return ModeInfo{1024, 1024, 192, 180};
  if (width == 320 && height == 288) return ModeInfo{512, 512, 96, 90};
  if (width == 512 && height == 512) return ModeInfo{512, 512, 0, 0};
  if (width == 1024 && height == 1024) return ModeInfo{1024, 1024, 0, 0};
  return absl::InvalidArgumentError(
      absl::StrCat("depth track of ", width, "x", height,
                   " px is no Azure Kinect depth mode (640x576, 320x288, 512x512, 1024x1024)"));
}

absl::StatusOr<ModeInfo> ColorMode(int width, int height) {
  const int binned_height = width * 3 / 4;
  if (width <= 0 || width % 4 != 0 || height > binned_height || (binned_height - height) % 2) {
    return absl::InvalidArgumentError(
        absl::StrCat("colour track of ", width, "x", height, " px is no Azure Kinect mode"));
  }
  return ModeInfo{static_cast<double>(width), static_cast<double>(binned_height), 0,
                  (binned_height - height) / 2.0};
}

// One camera of calibration.json in the pixels of a `width` x `height` mode.
absl::StatusOr<LensModel> CameraLens(const nlohmann::json& camera, bool is_color, int width,
                                     int height) {
  const nlohmann::json& p = camera.at("Intrinsics").at("ModelParameters");
  if (!p.is_array() || p.size() < 14) {
    return absl::InvalidArgumentError("Intrinsics.ModelParameters has fewer than 14 values");
  }
  double cx = p[0].get<double>(), cy = p[1].get<double>();
  double fx = p[2].get<double>(), fy = p[3].get<double>();
  const double sensor_w = camera.value("SensorWidth", 0.0);
  const double sensor_h = camera.value("SensorHeight", 0.0);
  ModeInfo mode{};
  if (is_color) {
    if (sensor_w > 0 && std::abs(sensor_w * 9 / 16 - sensor_h) < 0.5) {
      // A 16:9 (legacy) calibration: onto the 4:3 sensor, still unitised.
      cy = (cy * 2304 + 384) / 3072;
      fy = fy * 2304 / 3072;
    }
    ASSIGN_OR_RETURN(mode, ColorMode(width, height));
  } else {
    ASSIGN_OR_RETURN(mode, DepthMode(width, height));
  }
  LensModel lens;
  CameraIntrinsics& k = lens.pinhole;
  k.width = width;
  k.height = height;
  k.cx = cx * mode.binned_width - mode.crop_x - 0.5;
  k.cy = cy * mode.binned_height - mode.crop_y - 0.5;
  k.fx = fx * mode.binned_width;
  k.fy = fy * mode.binned_height;
  k.k1 = p[4].get<double>();
  k.k2 = p[5].get<double>();
  k.k3 = p[6].get<double>();
  lens.k4 = p[7].get<double>();
  lens.k5 = p[8].get<double>();
  lens.k6 = p[9].get<double>();
  k.p2 = p[12].get<double>();
  k.p1 = p[13].get<double>();
  RETURN_IF_ERROR(k.Validate());
  return lens;
}

absl::StatusOr<Rigid3d> CameraPose(const nlohmann::json& camera) {
  const nlohmann::json& rt = camera.at("Rt");
  const nlohmann::json& r = rt.at("Rotation");
  const nlohmann::json& t = rt.at("Translation");
  if (!r.is_array() || r.size() != 9 || !t.is_array() || t.size() != 3) {
    return absl::InvalidArgumentError("Rt needs 9 rotation and 3 translation values");
  }
  Eigen::Matrix3d rotation;
  for (int i = 0; i < 9; ++i) rotation(i / 3, i % 3) = r[i].get<double>();
  // Re-orthonormalise the float rotation before it becomes a quaternion.
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(rotation, Eigen::ComputeFullU | Eigen::ComputeFullV);
  rotation = svd.matrixU() * svd.matrixV().transpose();
  if (rotation.determinant() < 0) return absl::InvalidArgumentError("Rt is not a rotation");
  return Rigid3d(Eigen::Quaterniond(rotation).normalized(),
                 Eigen::Vector3d(t[0].get<double>(), t[1].get<double>(), t[2].get<double>()));
}

struct Packet {
  int64_t stamp_ns = 0;
  std::string data;
};

class AzureMkvReader : public RecordingReader {
 public:
  ~AzureMkvReader() override {
    if (format_ != nullptr) avformat_close_input(&format_);
    if (packet_ != nullptr) av_packet_free(&packet_);
  }

  static absl::StatusOr<std::unique_ptr<RecordingReader>> Open(const std::string& path,
                                                               const RecordingOptions& options) {
    std::unique_ptr<AzureMkvReader> reader(new AzureMkvReader(path));
    RETURN_IF_ERROR(reader->Init(options));
    return std::unique_ptr<RecordingReader>(std::move(reader));
  }

  const RecordingInfo& info() const override { return info_; }

  absl::StatusOr<std::optional<RecordedFrame>> Next() override {
    // A depth frame is handed over once the next one (or the end) is read,
    // so that the colour of the same capture, which may follow it in the
    // file, has been seen.
    while (!ended_ && (!held_depth_ || !next_depth_)) {
      RETURN_IF_ERROR(ReadPacket());
    }
    if (!held_depth_) {
      if (!next_depth_) return std::optional<RecordedFrame>();
      held_depth_ = std::move(next_depth_);
      next_depth_.reset();
    }
    Packet depth = std::move(*held_depth_);
    held_depth_ = std::move(next_depth_);
    next_depth_.reset();
    return MakeFrame(depth);
  }

 private:
  explicit AzureMkvReader(std::string path) : path_(std::move(path)) {}

  absl::Status Init(const RecordingOptions& options) {
    info_.format = RecordingFormat::kAzureMkv;
    info_.source = path_;
    info_.model = "azure_kinect";
    // libavformat logs what it skips (the IMU track's codec, a cut file) on
    // stderr; the errors returned here say what matters.
    static const bool quiet = [] {
      if (av_log_get_level() == AV_LOG_INFO) av_log_set_level(AV_LOG_FATAL);
      return true;
    }();
    (void)quiet;
    int rc = avformat_open_input(&format_, path_.c_str(), nullptr, nullptr);
    if (rc < 0) {
      format_ = nullptr;
      return absl::DataLossError(
          absl::StrCat(path_, ": not a readable Matroska file: ", AvError(rc)));
    }
    if (std::string(format_->iformat->name).find("matroska") == std::string::npos) {
      return absl::InvalidArgumentError(absl::StrCat(path_, ": a ", format_->iformat->name,
                                                     " file, not a Matroska (.mkv) recording"));
    }
    std::string calibration;
    for (unsigned i = 0; i < format_->nb_streams; ++i) {
      const AVStream* stream = format_->streams[i];
      const AVCodecParameters* par = stream->codecpar;
      if (par->codec_type == AVMEDIA_TYPE_ATTACHMENT) {
        if (Tag(stream->metadata, "filename") == "calibration.json" && par->extradata != nullptr &&
            par->extradata_size > 0 && par->extradata_size <= kMaxCalibrationBytes) {
          calibration.assign(reinterpret_cast<const char*>(par->extradata), par->extradata_size);
        }
        continue;
      }
      if (par->codec_type != AVMEDIA_TYPE_VIDEO) continue;
      const std::string title = Tag(stream->metadata, "title");
      if (title == "DEPTH") depth_stream_ = static_cast<int>(i);
      if (title == "COLOR") color_stream_ = static_cast<int>(i);
    }
    if (depth_stream_ < 0) {
      return absl::InvalidArgumentError(
          absl::StrCat(path_, ": no DEPTH track; not an Azure Kinect recording with depth"));
    }
    const AVCodecParameters* depth_par = format_->streams[depth_stream_]->codecpar;
    depth_width_ = depth_par->width;
    depth_height_ = depth_par->height;
    if (depth_width_ <= 0 || depth_height_ <= 0 ||
        static_cast<uint64_t>(depth_width_) * depth_height_ > options.max_pixels) {
      return absl::InvalidArgumentError(
          absl::StrCat(path_, ": depth track of ", depth_width_, "x", depth_height_, " px"));
    }
    if (depth_par->codec_tag != MKTAG('b', '1', '6', 'g')) {
      return absl::InvalidArgumentError(
          absl::StrCat(path_, ": the DEPTH track is not 16-bit grey (b16g)"));
    }
    if (color_stream_ >= 0) {
      const AVCodecParameters* color_par = format_->streams[color_stream_]->codecpar;
      if (color_par->codec_id != AV_CODEC_ID_MJPEG) {
        return absl::UnimplementedError(
            absl::StrCat(path_,
                         ": the COLOR track is not MJPG (only MJPG colour is read; record with "
                         "--color-mode MJPG or import depth alone is not supported yet)"));
      }
      color_width_ = color_par->width;
      color_height_ = color_par->height;
      if (color_width_ <= 0 || color_height_ <= 0 ||
          static_cast<uint64_t>(color_width_) * color_height_ > options.max_pixels) {
        return absl::InvalidArgumentError(
            absl::StrCat(path_, ": colour track of ", color_width_, "x", color_height_, " px"));
      }
    }
    if (calibration.empty()) {
      return absl::InvalidArgumentError(
          absl::StrCat(path_, ": no calibration.json attachment (k4arecorder writes one)"));
    }
    RETURN_IF_ERROR(ParseCalibration(calibration));
    info_.serial = Tag(format_->metadata, "K4A_DEVICE_SERIAL_NUMBER");
    const AVRational rate = format_->streams[depth_stream_]->avg_frame_rate;
    info_.nominal_fps = rate.num > 0 && rate.den > 0 ? av_q2d(rate) : 0.0;
    const std::string fps_tag = Tag(format_->metadata, "K4A_FPS");
    if (fps_tag == "FPS_5") info_.nominal_fps = 5;
    if (fps_tag == "FPS_15") info_.nominal_fps = 15;
    if (fps_tag == "FPS_30") info_.nominal_fps = 30;
    if (info_.nominal_fps <= 0 || info_.nominal_fps > 120) info_.nominal_fps = 30;
    int64_t offset = 0;
    if (const std::string tag = Tag(format_->metadata, "K4A_START_OFFSET_NS"); !tag.empty()) {
      offset = std::strtoll(tag.c_str(), nullptr, 10);
      if (offset < 0) offset = 0;
    }
    start_offset_ns_ = offset;
    packet_ = av_packet_alloc();
    if (packet_ == nullptr) return absl::ResourceExhaustedError("av_packet_alloc failed");
    return absl::OkStatus();
  }

  absl::Status ParseCalibration(const std::string& text) {
    const nlohmann::json j = nlohmann::json::parse(text, nullptr, /*allow_exceptions=*/false);
    if (j.is_discarded()) {
      return absl::DataLossError(absl::StrCat(path_, ": calibration.json is not JSON"));
    }
    try {
      const nlohmann::json* depth = nullptr;
      const nlohmann::json* color = nullptr;
      for (const nlohmann::json& camera : j.at("CalibrationInformation").at("Cameras")) {
        const std::string location = camera.value("Location", "");
        if (location == "CALIBRATION_CameraLocationD0") depth = &camera;
        if (location == "CALIBRATION_CameraLocationPV0") color = &camera;
      }
      if (depth == nullptr) {
        return absl::InvalidArgumentError(
            absl::StrCat(path_, ": calibration.json has no depth camera (D0)"));
      }
      ASSIGN_OR_RETURN(info_.depth_lens, CameraLens(*depth, false, depth_width_, depth_height_));
      if (color_stream_ >= 0) {
        if (color == nullptr) {
          return absl::InvalidArgumentError(
              absl::StrCat(path_, ": calibration.json has no colour camera (PV0)"));
        }
        ASSIGN_OR_RETURN(info_.color_lens, CameraLens(*color, true, color_width_, color_height_));
        ASSIGN_OR_RETURN(const Rigid3d depth_pose, CameraPose(*depth));
        ASSIGN_OR_RETURN(const Rigid3d color_pose, CameraPose(*color));
        info_.color_from_depth = color_pose * depth_pose.Inverse();
        info_.has_color = true;
      }
    } catch (const nlohmann::json::exception& e) {
      return absl::InvalidArgumentError(
          absl::StrCat(path_, ": calibration.json lacks a field: ", e.what()));
    }
    info_.calibration_note =
        "calibration: the recording's calibration.json (Azure Kinect factory calibration, "
        "rational Brown-Conrady model)";
    return absl::OkStatus();
  }

  int64_t StampNs(const AVStream* stream, int64_t pts) const {
    if (pts == AV_NOPTS_VALUE) return start_offset_ns_;
    return av_rescale_q(pts, stream->time_base, AVRational{1, 1000000000}) + start_offset_ns_;
  }

  absl::Status ReadPacket() {
    const int rc = av_read_frame(format_, packet_);
    if (rc == AVERROR_EOF) {
      ended_ = true;
      return absl::OkStatus();
    }
    if (rc < 0) {
      return absl::DataLossError(absl::StrCat(path_, ": reading failed after ", depth_read_,
                                              " depth frames: ", AvError(rc)));
    }
    const int index = packet_->stream_index;
    if (index == depth_stream_ || index == color_stream_) {
      Packet packet;
      packet.stamp_ns = StampNs(format_->streams[index], packet_->pts);
      packet.data.assign(reinterpret_cast<const char*>(packet_->data), packet_->size);
      if (index == depth_stream_) {
        ++depth_read_;
        (held_depth_ ? next_depth_ : held_depth_) = std::move(packet);
      } else {
        colors_.push_back(std::move(packet));
        while (colors_.size() > 4) colors_.pop_front();
      }
    }
    av_packet_unref(packet_);
    return absl::OkStatus();
  }

  absl::StatusOr<std::optional<RecordedFrame>> MakeFrame(const Packet& depth) {
    RecordedFrame frame;
    frame.index = next_index_++;
    frame.stamp_ns = depth.stamp_ns;
    const size_t expected = static_cast<size_t>(depth_width_) * depth_height_ * 2;
    if (depth.data.size() != expected) {
      return absl::DataLossError(absl::StrCat(path_, ": depth frame ", frame.index, " holds ",
                                              depth.data.size(), " bytes; ", depth_width_, "x",
                                              depth_height_, " px of b16g need ", expected,
                                              " (truncated or damaged recording)"));
    }
    frame.depth_mm = DepthImageMm(depth_width_, depth_height_);
    const auto* bytes = reinterpret_cast<const uint8_t*>(depth.data.data());
    for (size_t i = 0; i < frame.depth_mm.data.size(); ++i) {
      frame.depth_mm.data[i] = static_cast<uint16_t>((bytes[2 * i] << 8) | bytes[2 * i + 1]);
    }
    // The colour of the same capture: the nearest colour frame within half
    // a frame period.
    const int64_t tolerance = static_cast<int64_t>(0.5e9 / info_.nominal_fps);
    const Packet* best = nullptr;
    for (const Packet& color : colors_) {
      const int64_t gap = std::abs(color.stamp_ns - depth.stamp_ns);
      if (gap <= tolerance && (best == nullptr || gap < std::abs(best->stamp_ns - depth.stamp_ns)))
        best = &color;
    }
    if (best != nullptr) {
      absl::StatusOr<std::pair<int, int>> size = JpegSize(best->data);
      if (!size.ok() || size->first != color_width_ || size->second != color_height_) {
        return absl::DataLossError(absl::StrCat(
            path_, ": the colour frame of depth frame ", frame.index, " is no ", color_width_, "x",
            color_height_, " JPEG (",
            size.ok() ? absl::StrCat(size->first, "x", size->second) : size.status().ToString(),
            ")"));
      }
      frame.color_jpeg = best->data;
      frame.color_width = color_width_;
      frame.color_height = color_height_;
      frame.color_stamp_ns = best->stamp_ns;
    }
    return std::optional<RecordedFrame>(std::move(frame));
  }

  const std::string path_;
  RecordingInfo info_;
  AVFormatContext* format_ = nullptr;
  AVPacket* packet_ = nullptr;
  int depth_stream_ = -1, color_stream_ = -1;
  int depth_width_ = 0, depth_height_ = 0, color_width_ = 0, color_height_ = 0;
  int64_t start_offset_ns_ = 0;
  bool ended_ = false;
  int64_t depth_read_ = 0;
  int64_t next_index_ = 0;
  std::optional<Packet> held_depth_, next_depth_;
  std::deque<Packet> colors_;
};

}  // namespace

absl::StatusOr<std::unique_ptr<RecordingReader>> OpenAzureMkv(const std::string& path,
                                                              const RecordingOptions& options) {
  return AzureMkvReader::Open(path, options);
}

}  // namespace reenact::recordings
