#include "common/io/take.h"

#include <algorithm>
#include <utility>

#include "absl/strings/match.h"
#include "common/io/proto_schema.h"

namespace reenact {
namespace {

constexpr std::string_view kProtobufEncoding = "protobuf";

bool IsValidSensorId(std::string_view id) {
  return !id.empty() && std::all_of(id.begin(), id.end(), [](char c) {
    return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_' ||
           c == '-';
  });
}

}  // namespace

std::string SensorTopic(std::string_view sensor_id, std::string_view stream) {
  return absl::StrCat("/sensor/", std::string(sensor_id), "/", std::string(stream));
}

std::string GroundTruthDepthTopic(std::string_view sensor_id) {
  return absl::StrCat("/ground_truth/depth/", std::string(sensor_id));
}

// ---------------------------------------------------------------- TakeWriter

TakeWriter::TakeWriter(std::string path, std::unique_ptr<McapWriter> mcap, v1::TakeInfo info)
    : path_(std::move(path)),
      mcap_(std::move(mcap)),
      info_(std::move(info)),
      start_stamp_ns_(info_.start_stamp_ns()) {}

absl::StatusOr<std::unique_ptr<TakeWriter>> TakeWriter::Open(const std::string& path,
                                                             const v1::TakeInfo& info,
                                                             const TakeWriterOptions& options) {
  RETURN_IF_ERROR(options.Validate());
  if (info.start_stamp_ns() < 0) {
    return absl::InvalidArgumentError(
        absl::StrCat("TakeInfo.start_stamp_ns is negative: ", info.start_stamp_ns()));
  }
  McapWriterOptions mcap_options = options.mcap;
  if (mcap_options.profile.empty()) mcap_options.profile = "reenact";
  ASSIGN_OR_RETURN(std::unique_ptr<McapWriter> mcap, McapWriter::Open(path, mcap_options));
  std::unique_ptr<TakeWriter> writer(new TakeWriter(path, std::move(mcap), info));
  RETURN_IF_ERROR(writer->Write(kTakeInfoTopic, info, info.start_stamp_ns()));
  return writer;
}

absl::StatusOr<std::unique_ptr<TakeWriter>> TakeWriter::OpenForAppend(
    const std::string& path, const TakeWriterOptions& options, McapAppendReport* report) {
  RETURN_IF_ERROR(options.Validate());
  v1::TakeInfo info;
  std::map<std::string, v1::SensorCalibration> sensors;
  bool wrote_topology = false;
  {
    ASSIGN_OR_RETURN(std::unique_ptr<TakeReader> reader, TakeReader::Open(path));
    info = reader->info();
    sensors = reader->sensors();
    for (const TakeChannel& c : reader->channels()) {
      if (c.topic == kGroundTruthTopologyTopic && c.message_count > 0) wrote_topology = true;
    }
  }
  ASSIGN_OR_RETURN(std::unique_ptr<McapWriter> mcap,
                   McapWriter::OpenForAppend(path, options.mcap, report));
  std::unique_ptr<TakeWriter> writer(new TakeWriter(path, std::move(mcap), std::move(info)));
  for (const auto& [id, name] : writer->mcap_->SchemaNames()) writer->schema_ids_.emplace(name, id);
  for (const auto& [id, topic] : writer->mcap_->ChannelTopics()) {
    writer->channel_ids_.emplace(topic, id);
  }
  writer->sensors_ = std::move(sensors);
  writer->wrote_topology_ = wrote_topology;
  return writer;
}

absl::StatusOr<McapChannelId> TakeWriter::ChannelFor(
    std::string_view topic, const google::protobuf::Descriptor& descriptor) {
  if (auto it = channel_ids_.find(topic); it != channel_ids_.end()) return it->second;
  auto schema = schema_ids_.find(descriptor.full_name());
  if (schema == schema_ids_.end()) {
    ASSIGN_OR_RETURN(const McapSchemaId id,
                     mcap_->AddSchema(descriptor.full_name(), kProtobufEncoding,
                                      BuildFileDescriptorSet(descriptor)));
    schema = schema_ids_.emplace(descriptor.full_name(), id).first;
  }
  ASSIGN_OR_RETURN(const McapChannelId id,
                   mcap_->AddChannel(schema->second, topic, kProtobufEncoding));
  channel_ids_.emplace(std::string(topic), id);
  return id;
}

absl::Status TakeWriter::Write(std::string_view topic, const google::protobuf::Message& message,
                               int64_t stamp_ns) {
  if (stamp_ns < 0) {
    return absl::InvalidArgumentError(absl::StrCat(path_, ": ", message.GetTypeName(), " on ",
                                                   std::string(topic), " has a negative stamp ",
                                                   stamp_ns));
  }
  ASSIGN_OR_RETURN(const McapChannelId channel, ChannelFor(topic, *message.GetDescriptor()));
  const auto log_time_ns = static_cast<uint64_t>(stamp_ns);
  return mcap_->WriteMessage(channel, log_time_ns, log_time_ns, message.SerializeAsString());
}

absl::Status TakeWriter::AddSensor(const v1::SensorCalibration& calibration) {
  const std::string& id = calibration.sensor_id();
  if (!IsValidSensorId(id)) {
    return absl::InvalidArgumentError(
        absl::StrCat("sensor id \"", id, "\" must be non-empty [A-Za-z0-9_-]"));
  }
  if (!sensors_.emplace(id, calibration).second) {
    return absl::InvalidArgumentError(absl::StrCat("sensor \"", id, "\" added twice"));
  }
  RETURN_IF_ERROR(ChannelFor(SensorTopic(id, "color"), *v1::ColorImage::descriptor()).status());
  RETURN_IF_ERROR(ChannelFor(SensorTopic(id, "depth"), *v1::DepthImage::descriptor()).status());
  RETURN_IF_ERROR(ChannelFor(SensorTopic(id, "mask"), *v1::ActorMask::descriptor()).status());
  RETURN_IF_ERROR(ChannelFor(SensorTopic(id, "skeleton"), *v1::Skeleton::descriptor()).status());
  return Write(SensorTopic(id, "calibration"), calibration, start_stamp_ns_);
}

absl::Status TakeWriter::WriteSensorFrame(std::string_view stream, const std::string& sensor_id,
                                          const google::protobuf::Message& message,
                                          int64_t host_stamp_ns) {
  if (!sensors_.contains(sensor_id)) {
    return absl::FailedPreconditionError(absl::StrCat(
        path_, ": ", message.GetTypeName(), " from sensor \"", sensor_id, "\" not added"));
  }
  return Write(SensorTopic(sensor_id, stream), message, host_stamp_ns);
}

absl::Status TakeWriter::WriteColor(const v1::ColorImage& image) {
  return WriteSensorFrame("color", image.sensor_id(), image, image.host_stamp_ns());
}

absl::Status TakeWriter::WriteDepth(const v1::DepthImage& image) {
  return WriteSensorFrame("depth", image.sensor_id(), image, image.host_stamp_ns());
}

absl::Status TakeWriter::WriteMask(const v1::ActorMask& mask) {
  return WriteSensorFrame("mask", mask.sensor_id(), mask, mask.host_stamp_ns());
}

absl::Status TakeWriter::WriteSkeleton(const v1::Skeleton& skeleton) {
  return WriteSensorFrame("skeleton", skeleton.sensor_id(), skeleton, skeleton.host_stamp_ns());
}

absl::Status TakeWriter::WriteGroundTruthDepth(const v1::DepthImage& image) {
  if (!sensors_.contains(image.sensor_id())) {
    return absl::FailedPreconditionError(absl::StrCat(path_, ": ground-truth depth of sensor \"",
                                                      image.sensor_id(), "\" not added"));
  }
  return Write(GroundTruthDepthTopic(image.sensor_id()), image, image.host_stamp_ns());
}

absl::Status TakeWriter::WriteGroundTruthJoints(const v1::GroundTruthJoints& joints) {
  return Write(kGroundTruthJointsTopic, joints, joints.stamp_ns());
}

absl::Status TakeWriter::WriteGroundTruthBody(const v1::GroundTruthBody& body) {
  return Write(kGroundTruthBodyTopic, body, body.stamp_ns());
}

absl::Status TakeWriter::WriteGroundTruthMesh(const v1::GroundTruthMesh& mesh) {
  return Write(kGroundTruthMeshTopic, mesh, mesh.stamp_ns());
}

absl::Status TakeWriter::WriteGroundTruthTopology(const v1::GroundTruthTopology& topology) {
  if (wrote_topology_) {
    return absl::FailedPreconditionError(absl::StrCat(path_, ": topology written twice"));
  }
  wrote_topology_ = true;
  return Write(kGroundTruthTopologyTopic, topology, start_stamp_ns_);
}

absl::Status TakeWriter::WriteFrameSetRecord(const v1::FrameSetRecord& record) {
  return Write(kIngestFrameSetTopic, record, record.stamp_ns());
}

absl::Status TakeWriter::WriteSensorLost(const v1::SensorLostRecord& record) {
  if (!sensors_.contains(record.sensor_id())) {
    return absl::FailedPreconditionError(
        absl::StrCat(path_, ": lost sensor \"", record.sensor_id(), "\" not added"));
  }
  return Write(kIngestSensorLostTopic, record, record.stamp_ns());
}

absl::Status TakeWriter::Close() { return mcap_->Close(); }

// ---------------------------------------------------------------- TakeReader

absl::StatusOr<std::unique_ptr<TakeReader>> TakeReader::Open(const std::string& path) {
  ASSIGN_OR_RETURN(std::unique_ptr<McapReader> mcap, McapReader::Open(path));
  std::unique_ptr<TakeReader> reader(new TakeReader(std::move(mcap)));
  ASSIGN_OR_RETURN(const std::vector<v1::TakeInfo> infos,
                   reader->ReadAll<v1::TakeInfo>(kTakeInfoTopic));
  if (infos.empty()) {
    return absl::DataLossError(absl::StrCat(path, ": no ", std::string(kTakeInfoTopic),
                                            " message (", reader->report().Summary(), ")"));
  }
  reader->info_ = infos.front();
  for (const auto& [id, channel] : reader->mcap_->channels()) {
    if (!absl::StartsWith(channel.topic, "/sensor/") ||
        !absl::EndsWith(channel.topic, "/calibration")) {
      continue;
    }
    ASSIGN_OR_RETURN(const std::vector<v1::SensorCalibration> calibrations,
                     reader->ReadAll<v1::SensorCalibration>(channel.topic));
    for (const v1::SensorCalibration& c : calibrations) reader->sensors_[c.sensor_id()] = c;
  }
  return reader;
}

absl::Status TakeReader::CheckType(std::string_view topic, const std::string& full_name) const {
  const McapChannel* channel = mcap_->FindChannel(topic);
  if (channel == nullptr) return absl::OkStatus();
  const auto schema = mcap_->schemas().find(channel->schema_id);
  if (schema == mcap_->schemas().end() || schema->second.name != full_name ||
      channel->message_encoding != kProtobufEncoding) {
    return absl::InvalidArgumentError(absl::StrCat(mcap_->path(), ": channel ", std::string(topic),
                                                   " does not hold ", full_name));
  }
  return absl::OkStatus();
}

std::vector<TakeChannel> TakeReader::channels() const {
  std::vector<TakeChannel> out;
  const McapStatistics& stats = mcap_->statistics();
  for (const auto& [id, channel] : mcap_->channels()) {
    TakeChannel c{channel.topic, "", 0};
    if (auto s = mcap_->schemas().find(channel.schema_id); s != mcap_->schemas().end()) {
      c.message_type = s->second.name;
    }
    if (auto n = stats.channel_message_counts.find(id); n != stats.channel_message_counts.end()) {
      c.message_count = n->second;
    }
    out.push_back(std::move(c));
  }
  std::sort(out.begin(), out.end(), [](const auto& a, const auto& b) { return a.topic < b.topic; });
  return out;
}

int64_t TakeReader::frame_count() const {
  uint64_t depth = 0, color = 0;
  for (const TakeChannel& c : channels()) {
    if (!absl::StartsWith(c.topic, "/sensor/")) continue;
    if (absl::EndsWith(c.topic, "/depth")) depth = std::max(depth, c.message_count);
    if (absl::EndsWith(c.topic, "/color")) color = std::max(color, c.message_count);
  }
  return static_cast<int64_t>(depth > 0 ? depth : color);
}

int64_t TakeReader::duration_ns() const {
  const McapStatistics& stats = mcap_->statistics();
  return static_cast<int64_t>(stats.end_time_ns - stats.start_time_ns);
}

}  // namespace reenact
