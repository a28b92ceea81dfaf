// What a take file holds, read from the file alone, and the recovery of a
// file whose writer died. The ingest writes every frame set's frames and
// then its FrameSetRecord into one MCAP chunk and ends chunks only between
// frame sets (common/io/take.h), so the intact chunks of a cut file hold
// exactly the frame sets 1..N whose records survived.
#pragma once

#include <cstdint>
#include <map>
#include <string>

#include "absl/status/statusor.h"
#include "common/io/mcap_writer.h"
#include "reenact/v1/sensor.pb.h"
#include "reenact/v1/take.pb.h"
#include "server/store/catalog.h"

namespace reenact::server {

// The ingest-relevant contents of one take file.
struct TakeFileSummary {
  v1::TakeInfo info;
  std::map<std::string, v1::SensorCalibration> sensors;
  // Highest FrameSetRecord.sequence (0: none), and how many records there are.
  uint64_t durable_sequence = 0;
  int64_t frame_set_count = 0;
  // Stamps of the first and last frame set, host clock, ns (0 when none).
  int64_t first_stamp_ns = 0;
  int64_t last_stamp_ns = 0;
  // Depth frames per sensor id.
  std::map<std::string, int64_t> frame_counts;
  // The last SensorLostRecord per sensor id.
  std::map<std::string, v1::SensorLostRecord> lost;
  // Size of the file, bytes.
  int64_t size_bytes = 0;
};

// Reads `path` (finished or not). DataLoss when the records are unreadable
// or their sequences are not 1..N without gaps; the errors of TakeReader.
absl::StatusOr<TakeFileSummary> SummarizeTakeFile(const std::string& path);

// Makes the file at `path`, cut short by a crash or a failed write, a
// finished and durable take file again: keeps its intact leading chunks
// (TakeWriter::OpenForAppend), writes the summary, fsyncs, and summarizes it.
// `report` (optional) says what was cut off. Errors: those of OpenForAppend
// (DataLoss when not even the take's header survived) and of
// SummarizeTakeFile.
absl::StatusOr<TakeFileSummary> RecoverTakeFile(const std::string& path,
                                                const McapWriterOptions& options,
                                                McapAppendReport* report = nullptr);

// Sets the counts, stamps, size and lost sensors of `row` from `summary`
// (zero for what the file lacks).
void ApplyTakeFileSummary(const TakeFileSummary& summary, TakeRow& row);

}  // namespace reenact::server
