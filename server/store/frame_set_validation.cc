#include "server/store/frame_set_validation.h"

#include <turbojpeg.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <set>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "common/base/status_macros.h"
#include "common/io/depth_codec.h"
#include "common/io/mask_codec.h"

namespace reenact::server {
namespace {

constexpr size_t kMaxIdLength = 64;
constexpr size_t kMaxSensors = 16;

bool IsIdChar(char c) {
  return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_' ||
         c == '-';
}

absl::Status ValidateId(std::string_view what, std::string_view id) {
  if (id.empty() || id.size() > kMaxIdLength || !std::all_of(id.begin(), id.end(), IsIdChar)) {
    return absl::InvalidArgumentError(absl::StrCat(std::string(what), " \"",
                                                   std::string(id.substr(0, 80)),
                                                   "\" must be 1..64 characters of [A-Za-z0-9_-]"));
  }
  return absl::OkStatus();
}

uint32_t LoadLe32(const char* p) {
  uint32_t v = 0;
  for (int i = 0; i < 4; ++i) v |= static_cast<uint32_t>(static_cast<uint8_t>(p[i])) << (8 * i);
  return v;
}

absl::Status Invalid(const std::string& where, const std::string& what) {
  return absl::InvalidArgumentError(absl::StrCat(where, ": ", what));
}

absl::Status CheckSize(const std::string& where, int32_t width_px, int32_t height_px,
                       const FrameSetLimits& limits) {
  if (width_px <= 0 || height_px <= 0 || width_px > limits.max_image_side_px ||
      height_px > limits.max_image_side_px) {
    return Invalid(where, absl::StrCat("size ", width_px, "x", height_px, " px is outside 1..",
                                       limits.max_image_side_px, " px per side"));
  }
  const int64_t pixels = int64_t{width_px} * height_px;
  if (pixels > limits.max_image_pixels) {
    return Invalid(where, absl::StrCat("size ", width_px, "x", height_px, " px is ", pixels,
                                       " pixels, more than the ", limits.max_image_pixels,
                                       " allowed (--max-frame-pixels)"));
  }
  return absl::OkStatus();
}

// Sizes of an intrinsics block must match an image's when they are set.
absl::Status CheckIntrinsics(const std::string& where, const v1::CameraIntrinsics& intrinsics,
                             int32_t width_px, int32_t height_px) {
  if (intrinsics.width_px() == 0 && intrinsics.height_px() == 0) return absl::OkStatus();
  if (intrinsics.width_px() != width_px || intrinsics.height_px() != height_px) {
    return Invalid(where, absl::StrCat("size ", width_px, "x", height_px,
                                       " px differs from the calibration's ", intrinsics.width_px(),
                                       "x", intrinsics.height_px(), " px"));
  }
  return absl::OkStatus();
}

// Encoded depth (common/io/depth_codec.h) is intact (header, sizes and
// checksum) and agrees with the message.
absl::Status CheckRvldHeader(const std::string& where, std::string_view bytes, bool zstd,
                             int32_t width_px, int32_t height_px) {
  // The sizes were checked against the limits before: the header must agree
  // with them, so this bound only keeps InspectDepth's own message short.
  absl::StatusOr<DepthHeader> header = InspectDepth(bytes);
  if (!header.ok()) return Invalid(where, std::string(header.status().message()));
  if (header->zstd != zstd) {
    return Invalid(where, absl::StrCat("encoding says ", zstd ? "" : "no ",
                                       "zstd but the RVLD header says otherwise"));
  }
  if (header->width != static_cast<uint32_t>(width_px) ||
      header->height != static_cast<uint32_t>(height_px)) {
    return Invalid(where, absl::StrCat("RVLD header says ", header->width, "x", header->height,
                                       " px, the message ", width_px, "x", height_px, " px"));
  }
  return absl::OkStatus();
}

absl::Status CheckDepth(const std::string& where, const v1::DepthImage& depth,
                        const v1::SensorCalibration& sensor, const FrameSetLimits& limits) {
  RETURN_IF_ERROR(CheckSize(where, depth.width_px(), depth.height_px(), limits));
  RETURN_IF_ERROR(
      CheckIntrinsics(where, sensor.depth_intrinsics(), depth.width_px(), depth.height_px()));
  if (depth.encoding() != "rvl" && depth.encoding() != "rvl+zstd") {
    return Invalid(where, absl::StrCat("encoding \"", depth.encoding(),
                                       "\" unknown (\"rvl\" or \"rvl+zstd\")"));
  }
  RETURN_IF_ERROR(CheckRvldHeader(where, depth.data(), depth.encoding() == "rvl+zstd",
                                  depth.width_px(), depth.height_px()));
  if (limits.depth_check == DepthCheck::kDecode) {
    absl::StatusOr<DepthImageMm> decoded =
        DecodeDepth(depth.data(), static_cast<uint64_t>(limits.max_image_pixels));
    if (!decoded.ok()) return Invalid(where, std::string(decoded.status().message()));
  }
  return absl::OkStatus();
}

absl::Status CheckColor(const std::string& where, const v1::ColorImage& color,
                        const v1::SensorCalibration& sensor, const FrameSetLimits& limits) {
  RETURN_IF_ERROR(CheckSize(where, color.width_px(), color.height_px(), limits));
  RETURN_IF_ERROR(
      CheckIntrinsics(where, sensor.color_intrinsics(), color.width_px(), color.height_px()));
  if (color.encoding() != "jpeg") {
    return Invalid(where, absl::StrCat("encoding \"", color.encoding(), "\" unknown (\"jpeg\")"));
  }
  if (color.quality() < 0 || color.quality() > 100) {
    return Invalid(where, absl::StrCat("JPEG quality ", color.quality(), " outside 1..100"));
  }
  // One decompressor per thread, destroyed with it.
  struct Decompressor {
    tjhandle handle = tjInitDecompress();
    ~Decompressor() {
      if (handle != nullptr) tjDestroy(handle);
    }
  };
  thread_local Decompressor decompressor;
  const tjhandle handle = decompressor.handle;
  int width = 0, height = 0, subsampling = 0, colorspace = 0;
  const std::string& data = color.data();
  if (handle == nullptr || data.size() < 4 || static_cast<uint8_t>(data[0]) != 0xFF ||
      static_cast<uint8_t>(data[1]) != 0xD8 ||
      tjDecompressHeader3(handle, reinterpret_cast<const unsigned char*>(data.data()),
                          static_cast<unsigned long>(data.size()), &width, &height, &subsampling,
                          &colorspace) != 0 ||
      width <= 0 || height <= 0) {
    return Invalid(where, absl::StrCat("the ", data.size(), " bytes are not a JPEG image"));
  }
  if (width != color.width_px() || height != color.height_px()) {
    return Invalid(where, absl::StrCat("JPEG is ", width, "x", height, " px, the message says ",
                                       color.width_px(), "x", color.height_px(), " px"));
  }
  return absl::OkStatus();
}

// Masks are decoded whole: a mask is small next to its depth image, and an
// RLE stream is only proven to cover exactly its pixels by walking it.
absl::Status CheckMask(const std::string& where, const v1::ActorMask& mask,
                       const v1::DepthImage& depth, const FrameSetLimits& limits) {
  if (mask.width_px() != depth.width_px() || mask.height_px() != depth.height_px()) {
    return Invalid(where, absl::StrCat("size ", mask.width_px(), "x", mask.height_px(),
                                       " px differs from the depth image's ", depth.width_px(), "x",
                                       depth.height_px(), " px"));
  }
  const std::string& data = mask.data();
  if (mask.encoding() == "rvl") {
    RETURN_IF_ERROR(
        CheckRvldHeader(where, data, /*zstd=*/false, mask.width_px(), mask.height_px()));
    if (limits.depth_check == DepthCheck::kHeader) return absl::OkStatus();
    absl::StatusOr<DepthImageMm> decoded =
        DecodeDepth(data, static_cast<uint64_t>(limits.max_image_pixels));
    if (!decoded.ok()) return Invalid(where, std::string(decoded.status().message()));
    return absl::OkStatus();
  }
  if (mask.encoding() != "rle") {
    return Invalid(where,
                   absl::StrCat("encoding \"", mask.encoding(), "\" unknown (\"rle\" or \"rvl\")"));
  }
  // "RLM1", width, height (common/io/mask_codec.h), then at least one run.
  if (data.size() < 14 || std::memcmp(data.data(), "RLM1", 4) != 0 ||
      LoadLe32(data.data() + 4) != static_cast<uint32_t>(mask.width_px()) ||
      LoadLe32(data.data() + 8) != static_cast<uint32_t>(mask.height_px())) {
    return Invalid(where, "bytes do not start with an RLM1 header of the stated size");
  }
  absl::StatusOr<MaskImage> decoded =
      DecodeMaskRle(data, static_cast<uint64_t>(limits.max_image_pixels));
  if (!decoded.ok()) return Invalid(where, std::string(decoded.status().message()));
  return absl::OkStatus();
}

absl::Status CheckSkeleton(const std::string& where, const v1::Skeleton& skeleton,
                           const FrameSetLimits& limits) {
  if (skeleton.joints_size() > limits.max_joints_per_skeleton) {
    return Invalid(where, absl::StrCat(skeleton.joints_size(), " joints, more than ",
                                       limits.max_joints_per_skeleton));
  }
  for (const v1::Joint& joint : skeleton.joints()) {
    const v1::Vector3& p = joint.position_in_depth_m();
    if (!std::isfinite(p.x()) || !std::isfinite(p.y()) || !std::isfinite(p.z())) {
      return Invalid(where, absl::StrCat("joint \"", joint.name(), "\" position (", p.x(), ", ",
                                         p.y(), ", ", p.z(), ") m is not finite"));
    }
    if (!(joint.confidence() >= 0.0f && joint.confidence() <= 1.0f)) {
      return Invalid(where, absl::StrCat("joint \"", joint.name(), "\" confidence ",
                                         joint.confidence(), " is not within [0, 1]"));
    }
  }
  return absl::OkStatus();
}

// The nested message carries the frame's sensor id, stamps and index.
template <typename Message>
absl::Status CheckHeaderFields(const std::string& where, const Message& m, const v1::Frame& f) {
  if (m.sensor_id() != f.sensor_id() || m.device_stamp_ns() != f.device_stamp_ns() ||
      m.host_stamp_ns() != f.host_stamp_ns() || m.frame_index() != f.frame_index()) {
    return Invalid(where, absl::StrCat("sensor_id/stamps/frame_index (\"", m.sensor_id(), "\", ",
                                       m.device_stamp_ns(), ", ", m.host_stamp_ns(), ", ",
                                       m.frame_index(), ") differ from the frame's (\"",
                                       f.sensor_id(), "\", ", f.device_stamp_ns(), ", ",
                                       f.host_stamp_ns(), ", ", f.frame_index(), ")"));
  }
  return absl::OkStatus();
}

absl::Status CheckFrame(const std::string& where, const v1::Frame& frame,
                        const v1::SensorCalibration& sensor, const FrameSetLimits& limits) {
  if (frame.host_stamp_ns() < 0 || frame.frame_index() < 0) {
    return Invalid(where, absl::StrCat("host_stamp_ns ", frame.host_stamp_ns(), " or frame_index ",
                                       frame.frame_index(), " is negative"));
  }
  if (!frame.has_depth()) return Invalid(where, "no depth image (every frame needs one)");
  RETURN_IF_ERROR(CheckHeaderFields(where + " depth", frame.depth(), frame));
  RETURN_IF_ERROR(CheckDepth(where + " depth", frame.depth(), sensor, limits));
  if (frame.has_color()) {
    RETURN_IF_ERROR(CheckHeaderFields(where + " colour", frame.color(), frame));
    RETURN_IF_ERROR(CheckColor(where + " colour", frame.color(), sensor, limits));
  }
  if (frame.has_mask()) {
    RETURN_IF_ERROR(CheckHeaderFields(where + " mask", frame.mask(), frame));
    RETURN_IF_ERROR(CheckMask(where + " mask", frame.mask(), frame.depth(), limits));
  }
  if (frame.skeletons_size() > limits.max_skeletons_per_frame) {
    return Invalid(where, absl::StrCat(frame.skeletons_size(), " skeletons, more than ",
                                       limits.max_skeletons_per_frame));
  }
  for (int i = 0; i < frame.skeletons_size(); ++i) {
    const std::string at = absl::StrCat(where, " skeleton ", i);
    RETURN_IF_ERROR(CheckHeaderFields(at, frame.skeletons(i), frame));
    RETURN_IF_ERROR(CheckSkeleton(at, frame.skeletons(i), limits));
  }
  return absl::OkStatus();
}

}  // namespace

absl::Status FrameSetLimits::Validate() const {
  if (max_image_pixels < 1 || static_cast<uint64_t>(max_image_pixels) > kMaxDecodedImagePixels) {
    return absl::InvalidArgumentError(absl::StrCat("FrameSetLimits: max_image_pixels must be 1..",
                                                   kMaxDecodedImagePixels, ", got ",
                                                   max_image_pixels));
  }
  if (max_image_side_px < 1 || max_skeletons_per_frame < 0 || max_joints_per_skeleton < 0) {
    return absl::InvalidArgumentError(
        "FrameSetLimits: max_image_side_px must be >= 1 and the skeleton limits >= 0");
  }
  if (max_name_bytes < 1 || max_notes_bytes < 0) {
    return absl::InvalidArgumentError(
        "FrameSetLimits: max_name_bytes must be >= 1 and max_notes_bytes >= 0");
  }
  return absl::OkStatus();
}

absl::Status ValidateTakeInfo(const v1::TakeInfo& info, const FrameSetLimits& limits) {
  const std::pair<const char*, const std::string*> names[] = {
      {"name", &info.name()},
      {"generator", &info.generator()},
      {"motion_source", &info.motion_source()},
      {"body_model", &info.body_model()}};
  for (const auto& [field, value] : names) {
    if (value->size() > static_cast<size_t>(limits.max_name_bytes)) {
      return absl::InvalidArgumentError(absl::StrCat("OpenTake.info.", field, " holds ",
                                                     value->size(), " bytes, more than the ",
                                                     limits.max_name_bytes, " allowed"));
    }
  }
  if (info.notes().size() > static_cast<size_t>(limits.max_notes_bytes)) {
    return absl::InvalidArgumentError(absl::StrCat("OpenTake.info.notes holds ",
                                                   info.notes().size(), " bytes, more than the ",
                                                   limits.max_notes_bytes, " allowed"));
  }
  return absl::OkStatus();
}

absl::Status ValidateTakeId(std::string_view take_id) { return ValidateId("take_id", take_id); }

absl::Status ValidateSensors(const std::vector<v1::SensorCalibration>& sensors,
                             const FrameSetLimits& limits) {
  if (sensors.empty() || sensors.size() > kMaxSensors) {
    return absl::InvalidArgumentError(
        absl::StrCat("a take needs 1..", kMaxSensors, " sensors, OpenTake names ", sensors.size()));
  }
  std::set<std::string> seen;
  for (const v1::SensorCalibration& s : sensors) {
    RETURN_IF_ERROR(ValidateId("sensor_id", s.sensor_id()));
    if (!seen.insert(s.sensor_id()).second) {
      return absl::InvalidArgumentError(absl::StrCat("sensor \"", s.sensor_id(), "\" named twice"));
    }
    for (const v1::CameraIntrinsics* in : {&s.depth_intrinsics(), &s.color_intrinsics()}) {
      if (in->width_px() < 0 || in->height_px() < 0 || in->width_px() > limits.max_image_side_px ||
          in->height_px() > limits.max_image_side_px) {
        return absl::InvalidArgumentError(
            absl::StrCat("sensor \"", s.sensor_id(), "\": intrinsics size ", in->width_px(), "x",
                         in->height_px(), " px outside 0..", limits.max_image_side_px, " px"));
      }
    }
  }
  return absl::OkStatus();
}

absl::Status ValidateFrameSet(const v1::FrameSet& set, const SensorMap& sensors,
                              const FrameSetLimits& limits) {
  const std::string where = absl::StrCat("FrameSet ", set.sequence());
  if (set.stamp_ns() < 0 || set.skew_ns() < 0) {
    return Invalid(where, absl::StrCat("stamp_ns ", set.stamp_ns(), " or skew_ns ", set.skew_ns(),
                                       " is negative"));
  }
  std::set<std::string> with_frame;
  for (int i = 0; i < set.frames_size(); ++i) {
    const v1::Frame& frame = set.frames(i);
    const std::string at =
        absl::StrCat(where, " frame ", i, " (sensor \"", frame.sensor_id(), "\")");
    const auto sensor = sensors.find(frame.sensor_id());
    if (sensor == sensors.end()) return Invalid(at, "sensor not in the take's OpenTake");
    if (!with_frame.insert(frame.sensor_id()).second) {
      return Invalid(at, "second frame of the same sensor in one set");
    }
    RETURN_IF_ERROR(CheckFrame(at, frame, sensor->second, limits));
  }
  std::set<std::string> missing;
  for (const std::string& id : set.missing_sensor_ids()) {
    if (!sensors.contains(id) || with_frame.contains(id) || !missing.insert(id).second) {
      return Invalid(where, absl::StrCat("missing_sensor_ids names \"", id,
                                         "\", which is unknown, repeated or has a frame"));
    }
  }
  return absl::OkStatus();
}

}  // namespace reenact::server
