// Checks of what the capture daemon sends before any of it reaches a take
// file: take ids, sensor calibrations, and every FrameSet against the sensors
// of its take. A message that fails is refused as a whole (InvalidArgument
// naming the frame, the field and the value), so a stored take never holds
// half a frame set or data a reader cannot decode.
#pragma once

#include <cstdint>
#include <map>
#include <string>
#include <string_view>
#include <vector>

#include "absl/status/status.h"
#include "reenact/v1/frame.pb.h"
#include "reenact/v1/sensor.pb.h"
#include "reenact/v1/take.pb.h"

namespace reenact::server {

// How thoroughly depth bytes are checked.
enum class DepthCheck {
  // InspectDepth (common/io/depth_codec.h): magic, version, flags agreeing
  // with the encoding, size equal to the message's, payload and RVL sizes
  // agreeing with the bytes, and the CRC-32C of header and payload. Catches
  // truncation, foreign data, mislabelled encodings and flipped bits; not an
  // encoder that wrote a wrong RVL stream with a right checksum.
  kHeader,
  // kHeader, then a full DecodeDepth: the RVL stream itself. Catches
  // everything; costs a decode per frame (about 1.5 ms at 512x424).
  kDecode,
};

// Limits of FrameSet validation.
struct FrameSetLimits {
  // Largest width or height of a colour, depth or mask image, pixels.
  int32_t max_image_side_px = 8192;
  // Largest width * height of one image, pixels (4096 x 4096: every Kinect
  // class sensor's colour and depth fit). At most kMaxDecodedImagePixels.
  int64_t max_image_pixels = int64_t{1} << 24;
  // Largest number of skeletons in one frame and joints in one skeleton.
  int max_skeletons_per_frame = 16;
  int max_joints_per_skeleton = 64;
  DepthCheck depth_check = DepthCheck::kDecode;
  // Largest TakeInfo name, generator, motion_source and body_model, bytes
  // (UTF-8), and largest TakeInfo notes: the catalog lists these to everyone.
  int max_name_bytes = 256;
  int max_notes_bytes = 16384;

  // InvalidArgument naming the first bad field.
  absl::Status Validate() const;
};

// Sensors of one take by id.
using SensorMap = std::map<std::string, v1::SensorCalibration>;

// [A-Za-z0-9_-], 1..64 characters (OpenTake.take_id); InvalidArgument
// otherwise, quoting the id.
absl::Status ValidateTakeId(std::string_view take_id);

// The sensors of a new take: at least one, at most 16, ids of [A-Za-z0-9_-]
// (1..64 characters) without repeats, image sizes within `limits`.
absl::Status ValidateSensors(const std::vector<v1::SensorCalibration>& sensors,
                             const FrameSetLimits& limits);

// The TakeInfo of a new take: its text fields within `limits`
// (InvalidArgument naming the field and its size, not its content).
absl::Status ValidateTakeInfo(const v1::TakeInfo& info, const FrameSetLimits& limits);

// One FrameSet of a take whose sensors are `sensors`: stamps not negative;
// every frame from a known sensor, at most one per sensor, with depth; the
// nested messages carrying the frame's sensor_id, stamps and frame_index;
// known encodings ("jpeg"; "rvl", "rvl+zstd"; "rle", "rvl") whose bytes
// start the way the encoding says and whose stated sizes (1..limit pixels)
// match the bytes, the calibration's intrinsics (when set) and, for masks,
// the depth image; skeleton joints finite and within the limits;
// missing_sensor_ids known, without repeats and without a frame in the set.
// The sequence number is not looked at (the take recorder orders sets).
absl::Status ValidateFrameSet(const v1::FrameSet& set, const SensorMap& sensors,
                              const FrameSetLimits& limits);

}  // namespace reenact::server
