// A take: one recorded (or synthesized) performance, stored as an MCAP file
// of reenact.v1 protobuf messages (https://mcap.dev/spec). Any MCAP reader
// opens it: every channel's schema embeds its FileDescriptorSet.
//
// Channels (one per stream; <id> is SensorCalibration.sensor_id):
//   /take/info                  TakeInfo             once, at the start
//   /sensor/<id>/calibration    SensorCalibration    once per sensor
//   /sensor/<id>/color          ColorImage           per frame
//   /sensor/<id>/depth          DepthImage           per frame
//   /sensor/<id>/mask           ActorMask            per frame
//   /sensor/<id>/skeleton       Skeleton             per frame and body
//   /ground_truth/depth/<id>    DepthImage           noise-free, synthetic takes
//   /ground_truth/joints        GroundTruthJoints    per frame, synthetic takes
//   /ground_truth/body          GroundTruthBody      per frame, synthetic takes
//   /ground_truth/mesh          GroundTruthMesh      per frame, synthetic takes
//   /ground_truth/topology      GroundTruthTopology  once, synthetic takes
//   /ingest/frame_set           FrameSetRecord       per frame set, takes the server
//                                                    ingested (after the set's frames,
//                                                    in the same chunk)
//   /ingest/sensor_lost         SensorLostRecord     when a sensor's stream ended early
// Log time: per-frame sensor messages use host_stamp_ns, ground truth uses
// stamp_ns, ingest records use their stamp_ns, and the once-written messages
// use TakeInfo.start_stamp_ns.
//
// Durability: TakeWriter::Sync() ends the chunk in progress and fsyncs, so a
// writer that closes chunks only between whole frame sets leaves, after any
// crash, a file whose intact chunks hold whole frame sets;
// TakeWriter::OpenForAppend continues such a file (or a finished one).
#pragma once

#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include <google/protobuf/message.h>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/str_cat.h"
#include "common/base/status_macros.h"
#include "common/io/mcap_reader.h"
#include "common/io/mcap_writer.h"
#include "reenact/v1/ground_truth.pb.h"
#include "reenact/v1/sensor.pb.h"
#include "reenact/v1/take.pb.h"

namespace reenact {

// Topic names of a take (see the table above).
inline constexpr std::string_view kTakeInfoTopic = "/take/info";
inline constexpr std::string_view kGroundTruthJointsTopic = "/ground_truth/joints";
inline constexpr std::string_view kGroundTruthBodyTopic = "/ground_truth/body";
inline constexpr std::string_view kGroundTruthMeshTopic = "/ground_truth/mesh";
inline constexpr std::string_view kGroundTruthTopologyTopic = "/ground_truth/topology";
inline constexpr std::string_view kIngestFrameSetTopic = "/ingest/frame_set";
inline constexpr std::string_view kIngestSensorLostTopic = "/ingest/sensor_lost";
// "/sensor/<sensor_id>/<stream>", stream one of calibration, color, depth,
// mask, skeleton.
std::string SensorTopic(std::string_view sensor_id, std::string_view stream);
// "/ground_truth/depth/<sensor_id>".
std::string GroundTruthDepthTopic(std::string_view sensor_id);

// Options of TakeWriter.
struct TakeWriterOptions {
  // Container options; chunks of 4 MiB, zstd level 3 by default.
  McapWriterOptions mcap;

  // InvalidArgument naming the first bad field.
  absl::Status Validate() const { return mcap.Validate(); }
};

// Writes one take. Not thread-safe. Messages may arrive in any time order;
// readers sort by log time within a chunk only.
class TakeWriter {
 public:
  // Creates `path` and writes `info` on /take/info.
  static absl::StatusOr<std::unique_ptr<TakeWriter>> Open(const std::string& path,
                                                          const v1::TakeInfo& info,
                                                          const TakeWriterOptions& options = {});

  // Reopens a take written by TakeWriter to add to it: McapWriter::
  // OpenForAppend keeps its intact leading part (everything of a finished
  // file but its summary), and the writer goes on with the take's info and
  // sensors as the file holds them. DataLoss when /take/info did not
  // survive; the other errors as McapWriter::OpenForAppend.
  static absl::StatusOr<std::unique_ptr<TakeWriter>> OpenForAppend(
      const std::string& path, const TakeWriterOptions& options = {},
      McapAppendReport* report = nullptr);

  // Declares a sensor: creates its channels and writes its calibration.
  // InvalidArgument when sensor_id is empty, has characters other than
  // [A-Za-z0-9_-], or was added before.
  absl::Status AddSensor(const v1::SensorCalibration& calibration);

  // Per-frame sensor streams. FailedPrecondition when the message's
  // sensor_id was not added; InvalidArgument for a negative host stamp.
  absl::Status WriteColor(const v1::ColorImage& image);
  absl::Status WriteDepth(const v1::DepthImage& image);
  absl::Status WriteMask(const v1::ActorMask& mask);
  absl::Status WriteSkeleton(const v1::Skeleton& skeleton);

  // Ground truth of synthetic takes. InvalidArgument for a negative stamp.
  absl::Status WriteGroundTruthDepth(const v1::DepthImage& image);
  absl::Status WriteGroundTruthJoints(const v1::GroundTruthJoints& joints);
  absl::Status WriteGroundTruthBody(const v1::GroundTruthBody& body);
  absl::Status WriteGroundTruthMesh(const v1::GroundTruthMesh& mesh);
  // Once per take; FailedPrecondition on a second call.
  absl::Status WriteGroundTruthTopology(const v1::GroundTruthTopology& topology);

  // Ingest records (take.proto). FailedPrecondition when the sensor_id of a
  // SensorLostRecord was not added; InvalidArgument for a negative stamp.
  absl::Status WriteFrameSetRecord(const v1::FrameSetRecord& record);
  absl::Status WriteSensorLost(const v1::SensorLostRecord& record);

  // Ends the chunk in progress (written and flushed to the OS).
  absl::Status FlushChunk() { return mcap_->FlushChunk(); }
  // FlushChunk(), then fsync: what was written survives a crash.
  absl::Status Sync() { return mcap_->Sync(); }

  // Finishes the file (summary, footer). Further writes fail.
  absl::Status Close();
  // Closes the file as it stands after the last flushed chunk, dropping the
  // chunk in progress (McapWriter::Abort). Further writes fail.
  absl::Status Abort() { return mcap_->Abort(); }

  const v1::TakeInfo& info() const { return info_; }
  // Calibrations by sensor id.
  const std::map<std::string, v1::SensorCalibration>& sensors() const { return sensors_; }
  // File bytes written so far, and record bytes of the chunk in progress.
  uint64_t bytes_written() const { return mcap_->bytes_written(); }
  uint64_t pending_chunk_bytes() const { return mcap_->pending_chunk_bytes(); }

 private:
  TakeWriter(std::string path, std::unique_ptr<McapWriter> mcap, v1::TakeInfo info);
  absl::Status Write(std::string_view topic, const google::protobuf::Message& message,
                     int64_t stamp_ns);
  absl::Status WriteSensorFrame(std::string_view stream, const std::string& sensor_id,
                                const google::protobuf::Message& message, int64_t host_stamp_ns);
  absl::StatusOr<McapChannelId> ChannelFor(std::string_view topic,
                                           const google::protobuf::Descriptor& descriptor);

  std::string path_;
  std::unique_ptr<McapWriter> mcap_;
  v1::TakeInfo info_;
  int64_t start_stamp_ns_ = 0;
  std::map<std::string, McapSchemaId> schema_ids_;                 // By full message name.
  std::map<std::string, McapChannelId, std::less<>> channel_ids_;  // By topic.
  std::map<std::string, v1::SensorCalibration> sensors_;
  bool wrote_topology_ = false;
};

// One channel of a take as the reader sees it.
struct TakeChannel {
  std::string topic;
  std::string message_type;  // Full protobuf name, e.g. "reenact.v1.DepthImage".
  uint64_t message_count = 0;
};

// Reads a take. Truncated takes (a writer that died) open in recovery mode:
// every complete chunk is read, and report() says where reading stopped.
class TakeReader {
 public:
  // Opens `path`. InvalidArgument when it is not an MCAP file; DataLoss when
  // not even /take/info survived.
  static absl::StatusOr<std::unique_ptr<TakeReader>> Open(const std::string& path);

  const v1::TakeInfo& info() const { return info_; }
  // Calibrations by sensor id.
  const std::map<std::string, v1::SensorCalibration>& sensors() const { return sensors_; }
  // Every channel with its message count, sorted by topic.
  std::vector<TakeChannel> channels() const;
  // Frames of the longest depth stream (colour when there is no depth).
  int64_t frame_count() const;
  // Latest minus earliest log time over all messages, nanoseconds.
  int64_t duration_ns() const;
  // How the file was read (indexed or recovered, where it stopped).
  const McapReadReport& report() const { return mcap_->report(); }
  const McapReader& mcap() const { return *mcap_; }

  // Calls `callback` with every message on `topic` decoded as `Message`, in
  // file order. InvalidArgument when the channel's schema is not `Message`;
  // DataLoss naming the topic and log time when a message does not parse.
  template <typename Message>
  absl::Status ForEach(std::string_view topic,
                       const std::function<absl::Status(const Message&)>& callback) const;

  // All messages on `topic` decoded as `Message`.
  template <typename Message>
  absl::StatusOr<std::vector<Message>> ReadAll(std::string_view topic) const;

 private:
  explicit TakeReader(std::unique_ptr<McapReader> mcap) : mcap_(std::move(mcap)) {}
  // Checks that `topic`'s schema is `full_name`; OK when the topic is absent.
  absl::Status CheckType(std::string_view topic, const std::string& full_name) const;

  std::unique_ptr<McapReader> mcap_;
  v1::TakeInfo info_;
  std::map<std::string, v1::SensorCalibration> sensors_;
};

template <typename Message>
absl::Status TakeReader::ForEach(
    std::string_view topic, const std::function<absl::Status(const Message&)>& callback) const {
  RETURN_IF_ERROR(CheckType(topic, Message::descriptor()->full_name()));
  Message decoded;
  return mcap_->ForEachMessage(
      [&](const McapChannel& channel, const McapMessage& message) -> absl::Status {
        if (!decoded.ParseFromString(message.data)) {
          return absl::DataLossError(absl::StrCat(
              mcap_->path(), ": message on ", channel.topic, " at log time ", message.log_time_ns,
              " ns does not parse as ", Message::descriptor()->full_name()));
        }
        return callback(decoded);
      },
      topic);
}

template <typename Message>
absl::StatusOr<std::vector<Message>> TakeReader::ReadAll(std::string_view topic) const {
  std::vector<Message> messages;
  RETURN_IF_ERROR(ForEach<Message>(topic, [&messages](const Message& m) {
    messages.push_back(m);
    return absl::OkStatus();
  }));
  return messages;
}

}  // namespace reenact
