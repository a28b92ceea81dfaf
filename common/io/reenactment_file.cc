#include "common/io/reenactment_file.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <memory>
#include <set>
#include <system_error>
#include <utility>

#include "absl/strings/str_cat.h"
#include "common/base/files.h"
#include "common/base/status_macros.h"
#include "common/io/body_reenactment.h"
#include "common/io/mcap_reader.h"
#include "common/io/mcap_writer.h"
#include "common/io/proto_schema.h"

namespace reenact {
namespace {

constexpr std::string_view kProtobufEncoding = "protobuf";

absl::Status Invalid(const std::string& what) {
  return absl::InvalidArgumentError(absl::StrCat("invalid reenactment: ", what));
}

bool Finite(double v) { return std::isfinite(v); }

bool AllFinite(const std::vector<float>& values) {
  return std::all_of(values.begin(), values.end(), [](float v) { return std::isfinite(v); });
}

// Unpacks a packed float field with `per_vertex` floats per vertex; sets
// `vertex_count` (or checks it against an earlier field when >= 0).
absl::Status CheckPackedField(const std::string& bytes, int per_vertex, const std::string& what,
                              int64_t* vertex_count) {
  if (bytes.size() % (sizeof(float) * per_vertex) != 0) {
    return Invalid(absl::StrCat(what, " holds ", bytes.size(), " bytes, not a multiple of ",
                                sizeof(float) * per_vertex));
  }
  const auto count = static_cast<int64_t>(bytes.size() / (sizeof(float) * per_vertex));
  if (*vertex_count >= 0 && count != *vertex_count) {
    return Invalid(absl::StrCat(what, " has ", count, " vertices, the positions ", *vertex_count));
  }
  *vertex_count = count;
  ASSIGN_OR_RETURN(const std::vector<float> values, UnpackFloats(bytes));
  if (!AllFinite(values)) return Invalid(absl::StrCat(what, " holds a non-finite number"));
  return absl::OkStatus();
}

absl::Status ValidatePart(const v1::PartMesh& mesh, int part, const std::string& name,
                          int64_t* vertex_count) {
  const std::string what = absl::StrCat("part mesh ", part, " (", name, ")");
  if (mesh.part() != part) {
    return Invalid(absl::StrCat(what, " is numbered ", mesh.part()));
  }
  if (mesh.name() != name) {
    return Invalid(absl::StrCat(what, " is named \"", mesh.name(), "\""));
  }
  *vertex_count = -1;
  RETURN_IF_ERROR(
      CheckPackedField(mesh.positions_in_part_m_f32(), 3, what + " positions", vertex_count));
  RETURN_IF_ERROR(CheckPackedField(mesh.normals_in_part_f32(), 3, what + " normals", vertex_count));
  RETURN_IF_ERROR(CheckPackedField(mesh.uvs_f32(), 2, what + " uvs", vertex_count));
  if (mesh.triangle_indices_size() % 3 != 0) {
    return Invalid(absl::StrCat(what, " has ", mesh.triangle_indices_size(),
                                " triangle indices, not a multiple of 3"));
  }
  for (int i = 0; i < mesh.triangle_indices_size(); ++i) {
    if (static_cast<int64_t>(mesh.triangle_indices(i)) >= *vertex_count) {
      return Invalid(absl::StrCat(what, " triangle index ", i, " = ", mesh.triangle_indices(i),
                                  " is out of range (", *vertex_count, " vertices)"));
    }
  }
  if (!Finite(mesh.radius_rate()) || !Finite(mesh.reference_length_m()) || mesh.radius_rate() < 0 ||
      mesh.reference_length_m() < 0) {
    return Invalid(absl::StrCat(what, " has a bad radius_rate ", mesh.radius_rate(),
                                " or reference_length_m ", mesh.reference_length_m()));
  }
  return absl::OkStatus();
}

absl::Status ValidatePose(const v1::PartPose& pose, const std::string& what) {
  const v1::Quaternion& q = pose.world_from_part().rotation();
  const v1::Vector3& t = pose.world_from_part().translation_m();
  if (!Finite(q.w()) || !Finite(q.x()) || !Finite(q.y()) || !Finite(q.z()) || !Finite(t.x()) ||
      !Finite(t.y()) || !Finite(t.z()) || !Finite(pose.scale())) {
    return Invalid(absl::StrCat(what, " holds a non-finite number"));
  }
  if (!pose.valid()) return absl::OkStatus();
  const double norm = std::sqrt(q.w() * q.w() + q.x() * q.x() + q.y() * q.y() + q.z() * q.z());
  if (norm < 1e-6) return Invalid(absl::StrCat(what, " has a zero rotation quaternion"));
  if (!(pose.scale() > 0)) {
    return Invalid(absl::StrCat(what, " is valid with scale ", pose.scale()));
  }
  return absl::OkStatus();
}

absl::Status ValidateFrame(const v1::PartFrame& frame, int index, int part_count) {
  const std::string what = absl::StrCat("frame ", index);
  if (frame.frame_index() != index) {
    return Invalid(absl::StrCat(what, " is numbered ", frame.frame_index()));
  }
  if (frame.parts_size() != part_count) {
    return Invalid(
        absl::StrCat(what, " has ", frame.parts_size(), " part poses, expected ", part_count));
  }
  for (int p = 0; p < part_count; ++p) {
    RETURN_IF_ERROR(ValidatePose(frame.parts(p), absl::StrCat(what, " pose of part ", p)));
  }
  if (frame.joints_in_world_m_size() != 0 && frame.joints_in_world_m_size() != 25) {
    return Invalid(
        absl::StrCat(what, " has ", frame.joints_in_world_m_size(), " joints, expected 0 or 25"));
  }
  for (const v1::Vector3& j : frame.joints_in_world_m()) {
    if (!Finite(j.x()) || !Finite(j.y()) || !Finite(j.z())) {
      return Invalid(absl::StrCat(what, " has a non-finite joint"));
    }
  }
  return absl::OkStatus();
}

absl::Status ValidateKeyframe(const v1::TextureKeyframe& keyframe, int index,
                              const ReenactmentData& data, const std::vector<int64_t>& vertices,
                              const std::set<std::string>& sensors) {
  const std::string what = absl::StrCat("keyframe ", index);
  if (keyframe.frame_index() < 0 ||
      keyframe.frame_index() >= static_cast<int64_t>(data.frames.size())) {
    return Invalid(
        absl::StrCat(what, " names frame ", keyframe.frame_index(), " of ", data.frames.size()));
  }
  if (!sensors.contains(keyframe.sensor_id())) {
    return Invalid(absl::StrCat(what, " names unknown sensor \"", keyframe.sensor_id(), "\""));
  }
  if (keyframe.crop_x_px() < 0 || keyframe.crop_y_px() < 0) {
    return Invalid(absl::StrCat(what, " has a negative crop origin"));
  }
  if (!Finite(keyframe.crop_scale()) || keyframe.crop_scale() < 0 || keyframe.crop_scale() > 1) {
    return Invalid(
        absl::StrCat(what, " has crop_scale ", keyframe.crop_scale(), " outside [0, 1]"));
  }
  if (keyframe.vertex_visible_bits_size() != static_cast<int>(vertices.size())) {
    return Invalid(absl::StrCat(what, " has visibility of ", keyframe.vertex_visible_bits_size(),
                                " parts, expected ", vertices.size()));
  }
  for (size_t p = 0; p < vertices.size(); ++p) {
    const auto expected = static_cast<size_t>((vertices[p] + 7) / 8);
    if (keyframe.vertex_visible_bits(static_cast<int>(p)).size() != expected) {
      return Invalid(absl::StrCat(what, " visibility of part ", p, " has ",
                                  keyframe.vertex_visible_bits(static_cast<int>(p)).size(),
                                  " bytes, expected ", expected, " (one bit per vertex)"));
    }
  }
  return absl::OkStatus();
}

// The log time of a message stamped `stamp_ns` (MCAP log times are unsigned).
uint64_t LogTime(int64_t stamp_ns) { return static_cast<uint64_t>(std::max<int64_t>(stamp_ns, 0)); }

class ChannelWriter {
 public:
  explicit ChannelWriter(McapWriter* mcap) : mcap_(mcap) {}

  absl::Status Write(std::string_view topic, const google::protobuf::Message& message,
                     int64_t stamp_ns) {
    ASSIGN_OR_RETURN(const McapChannelId channel, ChannelFor(topic, *message.GetDescriptor()));
    const uint64_t t = LogTime(stamp_ns);
    return mcap_->WriteMessage(channel, t, t, message.SerializeAsString());
  }

 private:
  absl::StatusOr<McapChannelId> ChannelFor(std::string_view topic,
                                           const google::protobuf::Descriptor& descriptor) {
    if (auto it = channels_.find(std::string(topic)); it != channels_.end()) return it->second;
    ASSIGN_OR_RETURN(const McapSchemaId schema,
                     mcap_->AddSchema(descriptor.full_name(), kProtobufEncoding,
                                      BuildFileDescriptorSet(descriptor)));
    ASSIGN_OR_RETURN(const McapChannelId id, mcap_->AddChannel(schema, topic, kProtobufEncoding));
    channels_.emplace(std::string(topic), id);
    return id;
  }

  McapWriter* mcap_;
  std::map<std::string, McapChannelId> channels_;
};

absl::Status WriteAll(const ReenactmentData& data, McapWriter* mcap) {
  ChannelWriter writer(mcap);
  const int64_t created = data.info.created_unix_ns();
  RETURN_IF_ERROR(writer.Write(kReenactmentInfoTopic, data.info, created));
  for (const v1::BodyMesh& body : data.body) {
    RETURN_IF_ERROR(writer.Write(kReenactmentBodyMeshTopic, body, created));
  }
  for (const v1::PartMesh& mesh : data.parts) {
    RETURN_IF_ERROR(writer.Write(kReenactmentPartMeshTopic, mesh, created));
  }
  for (const v1::PartFrame& frame : data.frames) {
    RETURN_IF_ERROR(writer.Write(kReenactmentFrameTopic, frame, frame.stamp_ns()));
  }
  for (const v1::TextureKeyframe& keyframe : data.keyframes) {
    RETURN_IF_ERROR(writer.Write(kReenactmentKeyframeTopic, keyframe, keyframe.stamp_ns()));
  }
  return mcap->Close();
}

// Reads every message on `topic` as `Message`, checking the channel's schema.
template <typename Message>
absl::StatusOr<std::vector<Message>> ReadTopic(const McapReader& reader, std::string_view topic) {
  std::vector<Message> out;
  const McapChannel* channel = reader.FindChannel(topic);
  if (channel == nullptr) return out;
  const auto schema = reader.schemas().find(channel->schema_id);
  if (schema == reader.schemas().end() ||
      schema->second.name != Message::descriptor()->full_name() ||
      channel->message_encoding != kProtobufEncoding) {
    return absl::InvalidArgumentError(absl::StrCat(reader.path(), ": channel ", std::string(topic),
                                                   " does not hold ",
                                                   Message::descriptor()->full_name()));
  }
  RETURN_IF_ERROR(reader.ForEachMessage(
      [&](const McapChannel&, const McapMessage& message) -> absl::Status {
        Message decoded;
        if (!decoded.ParseFromString(message.data)) {
          return absl::DataLossError(absl::StrCat(reader.path(), ": message ", message.sequence,
                                                  " on ", std::string(topic), " does not parse as ",
                                                  Message::descriptor()->full_name()));
        }
        out.push_back(std::move(decoded));
        return absl::OkStatus();
      },
      topic));
  return out;
}

absl::Status WithPath(const absl::Status& status, const std::string& path) {
  if (status.ok()) return status;
  return absl::Status(status.code(), absl::StrCat(path, ": ", status.message()));
}

absl::Status ValidateBodyReenactment(const ReenactmentData& data) {
  const v1::ReenactmentInfo& info = data.info;
  if (data.body.size() != 1) return Invalid(absl::StrCat(data.body.size(), " body meshes"));
  if (info.part_names_size() != 0 || !data.parts.empty() || !data.keyframes.empty()) {
    return Invalid("a body-model reenactment with parts or keyframes");
  }
  if (info.frame_count() != static_cast<int64_t>(data.frames.size())) {
    return Invalid(absl::StrCat("frame_count is ", info.frame_count(), " but there are ",
                                data.frames.size(), " frames"));
  }
  if (!Finite(info.fps()) || info.fps() < 0) return Invalid(absl::StrCat("fps is ", info.fps()));
  absl::StatusOr<DecodedBodyMesh> mesh = DecodeBodyMesh(data.body.front());
  if (!mesh.ok()) return Invalid(std::string(mesh.status().message()));
  for (size_t f = 0; f < data.frames.size(); ++f) {
    RETURN_IF_ERROR(ValidateFrame(data.frames[f], static_cast<int>(f), 0));
    if (!data.frames[f].has_body()) return Invalid(absl::StrCat("frame ", f, " has no body pose"));
    absl::Status pose = ValidateBodyPose(data.frames[f].body(), mesh->num_vertices(),
                                         absl::StrCat("frame ", f, " body pose"));
    if (!pose.ok()) return Invalid(std::string(pose.message()));
  }
  return absl::OkStatus();
}

}  // namespace

absl::Status ValidateReenactment(const ReenactmentData& data) {
  if (data.is_body()) return ValidateBodyReenactment(data);
  const v1::ReenactmentInfo& info = data.info;
  const int part_count = info.part_names_size();
  if (part_count == 0) return Invalid("no part names");
  if (static_cast<int>(data.parts.size()) != part_count) {
    return Invalid(absl::StrCat(data.parts.size(), " part meshes for ", part_count, " part names"));
  }
  std::set<std::string> names(info.part_names().begin(), info.part_names().end());
  if (static_cast<int>(names.size()) != part_count) return Invalid("part names repeat");
  if (info.frame_count() != static_cast<int64_t>(data.frames.size())) {
    return Invalid(absl::StrCat("frame_count is ", info.frame_count(), " but there are ",
                                data.frames.size(), " frames"));
  }
  if (!Finite(info.fps()) || info.fps() < 0) {
    return Invalid(absl::StrCat("fps is ", info.fps()));
  }
  std::vector<int64_t> vertices(part_count);
  for (int p = 0; p < part_count; ++p) {
    RETURN_IF_ERROR(ValidatePart(data.parts[p], p, info.part_names(p), &vertices[p]));
  }
  for (size_t f = 0; f < data.frames.size(); ++f) {
    RETURN_IF_ERROR(ValidateFrame(data.frames[f], static_cast<int>(f), part_count));
  }
  std::set<std::string> sensors;
  for (const v1::SensorCalibration& s : info.sensors()) sensors.insert(s.sensor_id());
  for (size_t k = 0; k < data.keyframes.size(); ++k) {
    RETURN_IF_ERROR(
        ValidateKeyframe(data.keyframes[k], static_cast<int>(k), data, vertices, sensors));
  }
  return absl::OkStatus();
}

absl::Status WriteReenactmentFile(const ReenactmentData& data, const std::string& path) {
  RETURN_IF_ERROR(ValidateReenactment(data));
  const std::string tmp = path + ".tmp";
  McapWriterOptions options;
  options.profile = "reenact";
  options.durable = true;
  absl::Status status = [&]() -> absl::Status {
    ASSIGN_OR_RETURN(std::unique_ptr<McapWriter> mcap, McapWriter::Open(tmp, options));
    absl::Status written = WriteAll(data, mcap.get());
    if (!written.ok()) (void)mcap->Abort();
    return written;
  }();
  std::error_code ec;
  if (status.ok()) {
    std::filesystem::rename(tmp, path, ec);
    if (!ec) {
      // The rename itself must survive a power loss (the file was fsynced).
      const std::string parent = std::filesystem::path(path).parent_path().string();
      return SyncDirectory(parent.empty() ? "." : parent);
    }
    status = absl::DataLossError(absl::StrCat(path, ": rename failed: ", ec.message()));
  }
  std::filesystem::remove(tmp, ec);
  return status;
}

absl::StatusOr<ReenactmentData> ReadReenactmentFile(const std::string& path, bool skip_keyframes) {
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) {
    return absl::NotFoundError(absl::StrCat(path, ": no such reenactment file"));
  }
  // Reenactment files are written whole (through a temporary name): a file
  // without an intact summary is damaged, not a recording to recover.
  McapReaderOptions options;
  options.allow_recovery = false;
  ASSIGN_OR_RETURN(std::unique_ptr<McapReader> reader, McapReader::Open(path, options));
  ReenactmentData data;
  ASSIGN_OR_RETURN(std::vector<v1::ReenactmentInfo> infos,
                   ReadTopic<v1::ReenactmentInfo>(*reader, kReenactmentInfoTopic));
  if (infos.size() != 1) {
    return absl::DataLossError(absl::StrCat(path, ": ", infos.size(), " messages on ",
                                            std::string(kReenactmentInfoTopic), ", expected 1"));
  }
  data.info = std::move(infos.front());
  ASSIGN_OR_RETURN(data.parts, ReadTopic<v1::PartMesh>(*reader, kReenactmentPartMeshTopic));
  ASSIGN_OR_RETURN(data.frames, ReadTopic<v1::PartFrame>(*reader, kReenactmentFrameTopic));
  ASSIGN_OR_RETURN(data.body, ReadTopic<v1::BodyMesh>(*reader, kReenactmentBodyMeshTopic));
  // Chunks hold messages by log time; put parts and frames back in id order
  // (stable, so a file with repeated ids still fails validation).
  std::stable_sort(data.parts.begin(), data.parts.end(),
                   [](const auto& a, const auto& b) { return a.part() < b.part(); });
  std::stable_sort(data.frames.begin(), data.frames.end(),
                   [](const auto& a, const auto& b) { return a.frame_index() < b.frame_index(); });
  if (!skip_keyframes) {
    ASSIGN_OR_RETURN(data.keyframes,
                     ReadTopic<v1::TextureKeyframe>(*reader, kReenactmentKeyframeTopic));
  }
  RETURN_IF_ERROR(WithPath(ValidateReenactment(data), path));
  return data;
}

std::string PackFloats(const std::vector<float>& values) {
  std::string out(values.size() * sizeof(float), '\0');
  for (size_t i = 0; i < values.size(); ++i) {
    const auto bits = std::bit_cast<uint32_t>(values[i]);
    for (int b = 0; b < 4; ++b) out[i * 4 + b] = static_cast<char>((bits >> (8 * b)) & 0xFF);
  }
  return out;
}

absl::StatusOr<std::vector<float>> UnpackFloats(const std::string& bytes) {
  if (bytes.size() % sizeof(float) != 0) {
    return absl::InvalidArgumentError(
        absl::StrCat("packed float32 field of ", bytes.size(), " bytes, not a multiple of 4"));
  }
  std::vector<float> out(bytes.size() / sizeof(float));
  for (size_t i = 0; i < out.size(); ++i) {
    uint32_t bits = 0;
    for (int b = 0; b < 4; ++b) {
      bits |= static_cast<uint32_t>(static_cast<uint8_t>(bytes[i * 4 + b])) << (8 * b);
    }
    out[i] = std::bit_cast<float>(bits);
  }
  return out;
}

}  // namespace reenact
