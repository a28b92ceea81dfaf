// A reenactment file: an MCAP file (https://mcap.dev/spec, written by
// McapWriter) of reenact.v1 messages from reenactment.proto, one channel per
// kind. Any MCAP reader opens it.
//
// Channels:
//   /reenactment/info       ReenactmentInfo   once, first
//   /reenactment/part_mesh  PartMesh          once per part, in part order
//   /reenactment/frame      PartFrame         per instant, in frame order
//   /reenactment/keyframe   TextureKeyframe   per kept colour image
//   /reenactment/body_mesh  BodyMesh          once, body-model reenactments
//                                             only (they have no parts and
//                                             no keyframes)
// Log time: ReenactmentInfo.created_unix_ns for info and meshes, the stamps
// of frames and keyframes for those.
#pragma once

#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "reenact/v1/reenactment.pb.h"

namespace reenact {

inline constexpr std::string_view kReenactmentInfoTopic = "/reenactment/info";
inline constexpr std::string_view kReenactmentPartMeshTopic = "/reenactment/part_mesh";
inline constexpr std::string_view kReenactmentFrameTopic = "/reenactment/frame";
inline constexpr std::string_view kReenactmentKeyframeTopic = "/reenactment/keyframe";
inline constexpr std::string_view kReenactmentBodyMeshTopic = "/reenactment/body_mesh";

// A whole reenactment in memory.
struct ReenactmentData {
  v1::ReenactmentInfo info;
  std::vector<v1::PartMesh> parts;    // In part-id order.
  std::vector<v1::PartFrame> frames;  // In frame order.
  std::vector<v1::TextureKeyframe> keyframes;
  // Body-model reenactments: the skinned mesh (each frame then holds a
  // BodyPose). Empty (no message) for rigid-part reenactments.
  std::vector<v1::BodyMesh> body;  // 0 or 1 element.

  bool is_body() const { return !body.empty(); }
};

// Checks consistency: one mesh per part name with sizes that agree (positions,
// normals and uvs per vertex, indices in range, visibility bits per vertex),
// one pose per part in every frame, frame_count equal to the frames,
// keyframes naming known frames and sensors, finite numbers. A body-model
// reenactment instead has one BodyMesh that decodes, no parts or keyframes,
// and a valid BodyPose in every frame. InvalidArgument
// naming the first problem.
absl::Status ValidateReenactment(const ReenactmentData& data);

// Writes `data` (validated first) to `path` through a temporary name, so a
// failed write leaves nothing at `path`.
absl::Status WriteReenactmentFile(const ReenactmentData& data, const std::string& path);

// Reads and validates a reenactment file. NotFound when it does not exist;
// InvalidArgument / DataLoss for a file that is not a valid reenactment.
// `skip_keyframes` leaves keyframes out (they hold most of the bytes).
absl::StatusOr<ReenactmentData> ReadReenactmentFile(const std::string& path,
                                                    bool skip_keyframes = false);

// Packed float32 helpers of the *_f32 fields (little-endian).
std::string PackFloats(const std::vector<float>& values);
absl::StatusOr<std::vector<float>> UnpackFloats(const std::string& bytes);

}  // namespace reenact
