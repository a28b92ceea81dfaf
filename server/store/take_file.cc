#include "server/store/take_file.h"

#include <algorithm>
#include <filesystem>
#include <memory>

#include "absl/strings/match.h"
#include "absl/strings/str_cat.h"
#include "common/base/status_macros.h"
#include "common/io/take.h"

namespace reenact::server {

absl::StatusOr<TakeFileSummary> SummarizeTakeFile(const std::string& path) {
  ASSIGN_OR_RETURN(std::unique_ptr<TakeReader> reader, TakeReader::Open(path));
  TakeFileSummary summary;
  summary.info = reader->info();
  summary.sensors = reader->sensors();
  RETURN_IF_ERROR(reader->ForEach<v1::FrameSetRecord>(
      kIngestFrameSetTopic, [&](const v1::FrameSetRecord& record) -> absl::Status {
        if (record.sequence() != summary.durable_sequence + 1) {
          return absl::DataLossError(absl::StrCat(path, ": frame set ", record.sequence(),
                                                  " follows frame set ", summary.durable_sequence));
        }
        summary.durable_sequence = record.sequence();
        if (summary.frame_set_count++ == 0) summary.first_stamp_ns = record.stamp_ns();
        summary.last_stamp_ns = record.stamp_ns();
        return absl::OkStatus();
      }));
  RETURN_IF_ERROR(reader->ForEach<v1::SensorLostRecord>(kIngestSensorLostTopic,
                                                        [&](const v1::SensorLostRecord& record) {
                                                          summary.lost[record.sensor_id()] = record;
                                                          return absl::OkStatus();
                                                        }));
  for (const auto& [id, calibration] : summary.sensors) summary.frame_counts[id] = 0;
  for (const TakeChannel& channel : reader->channels()) {
    for (const auto& [id, calibration] : summary.sensors) {
      if (channel.topic == SensorTopic(id, "depth")) {
        summary.frame_counts[id] = static_cast<int64_t>(channel.message_count);
      }
    }
  }
  std::error_code ec;
  summary.size_bytes = static_cast<int64_t>(std::filesystem::file_size(path, ec));
  return summary;
}

absl::StatusOr<TakeFileSummary> RecoverTakeFile(const std::string& path,
                                                const McapWriterOptions& options,
                                                McapAppendReport* report) {
  TakeWriterOptions writer_options;
  writer_options.mcap = options;
  writer_options.mcap.durable = true;
  ASSIGN_OR_RETURN(std::unique_ptr<TakeWriter> writer,
                   TakeWriter::OpenForAppend(path, writer_options, report));
  RETURN_IF_ERROR(writer->Close());
  return SummarizeTakeFile(path);
}

void ApplyTakeFileSummary(const TakeFileSummary& summary, TakeRow& row) {
  v1::Take& t = row.take;
  t.set_durable_sequence(summary.durable_sequence);
  t.set_frame_set_count(summary.frame_set_count);
  t.set_size_bytes(summary.size_bytes);
  row.first_stamp_ns = summary.first_stamp_ns;
  row.last_stamp_ns = summary.last_stamp_ns;
  t.set_duration_ns(summary.last_stamp_ns - summary.first_stamp_ns);
  for (v1::TakeSensor& s : *t.mutable_sensors()) {
    const auto count = summary.frame_counts.find(s.sensor_id());
    s.set_frame_count(count == summary.frame_counts.end() ? 0 : count->second);
    const auto lost = summary.lost.find(s.sensor_id());
    s.set_lost_stamp_ns(lost == summary.lost.end() ? 0 : lost->second.stamp_ns());
    s.set_lost_reason(lost == summary.lost.end() ? "" : lost->second.reason());
  }
}

}  // namespace reenact::server
