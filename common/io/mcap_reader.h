// Reads MCAP v0 files (https://mcap.dev/spec).
//
// Two paths:
//  - indexed: the Footer points at the Summary section, whose Schema, Channel,
//    Statistics and Chunk Index records describe the file without reading the
//    data section; chunks are read on demand.
//  - recovery: when the closing magic, Footer or Summary is missing or
//    corrupt (e.g. a writer that died), the data section is scanned record by
//    record. Every message of every complete chunk is kept; the scan stops at
//    the first record that does not fit in the file or cannot be parsed, and
//    McapReadReport says where and why. Chunks whose CRC or compression is
//    broken are skipped and listed.
// No read ever leaves the file's bounds; malformed input yields an error that
// names the file and the byte offset.
#pragma once

#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"

namespace reenact {

// A Schema record.
struct McapSchema {
  uint16_t id = 0;
  std::string name;      // e.g. "reenact.v1.DepthImage".
  std::string encoding;  // e.g. "protobuf".
  std::string data;      // e.g. a serialized FileDescriptorSet.
};

// A Channel record.
struct McapChannel {
  uint16_t id = 0;
  uint16_t schema_id = 0;  // 0: no schema.
  std::string topic;
  std::string message_encoding;
  std::map<std::string, std::string> metadata;
};

// A Message record.
struct McapMessage {
  uint16_t channel_id = 0;
  uint32_t sequence = 0;
  uint64_t log_time_ns = 0;
  uint64_t publish_time_ns = 0;
  std::string data;
};

// Where a chunk lies and what it covers (a Chunk Index record, or the same
// facts found by scanning).
struct McapChunkInfo {
  uint64_t chunk_offset = 0;  // Byte offset of the Chunk record's opcode.
  uint64_t chunk_length = 0;  // Bytes of the whole Chunk record.
  uint64_t start_time_ns = 0;
  uint64_t end_time_ns = 0;
  std::vector<uint16_t> channel_ids;  // Channels with messages in the chunk.
};

// Counts over the file (the Statistics record, or counted while scanning).
struct McapStatistics {
  uint64_t message_count = 0;
  uint64_t chunk_count = 0;
  uint64_t start_time_ns = 0;  // Earliest message log time (0 if none).
  uint64_t end_time_ns = 0;    // Latest message log time (0 if none).
  std::map<uint16_t, uint64_t> channel_message_counts;
};

// How a file was opened.
struct McapReadReport {
  // True when the Summary section was used; false when the data section was
  // scanned (recovery).
  bool indexed = false;
  // True when the whole file was read without finding damage.
  bool complete = true;
  // Why the summary could not be used (empty when it was).
  std::string summary_problem;
  // Where the recovery scan stopped reading (byte offset) and why; empty when
  // it reached DataEnd or the file was read through the summary.
  uint64_t stop_offset = 0;
  std::string stop_reason;
  // One line per chunk skipped because it was damaged, naming its offset.
  std::vector<std::string> skipped_chunks;

  // One line for logs and CLI output.
  std::string Summary() const;
};

// Options of McapReader::Open.
struct McapReaderOptions {
  // Scan the data section when the summary is missing or damaged. When false
  // such files fail to open with DataLoss.
  bool allow_recovery = true;
  // Largest uncompressed chunk the reader loads, bytes: a chunk whose header
  // claims more is DataLoss, before anything is allocated. Whatever the
  // claim, a compressed chunk's buffer grows only with what its frame really
  // produces. Reenact's writers make 4 MiB chunks.
  uint64_t max_chunk_bytes = uint64_t{1} << 30;

  // InvalidArgument unless 0 < max_chunk_bytes <= 4 GiB.
  absl::Status Validate() const;
};

// Called once per message; returning an error stops the iteration and is
// passed through.
using McapMessageCallback =
    std::function<absl::Status(const McapChannel& channel, const McapMessage& message)>;

// An open MCAP file. Thread-compatible: const methods may run concurrently.
class McapReader {
 public:
  // Opens `path`. InvalidArgument when it is not an MCAP file, DataLoss when
  // it is damaged beyond what recovery (if allowed) can use.
  static absl::StatusOr<std::unique_ptr<McapReader>> Open(const std::string& path,
                                                          const McapReaderOptions& options = {});
  ~McapReader();
  McapReader(const McapReader&) = delete;
  McapReader& operator=(const McapReader&) = delete;

  const std::map<uint16_t, McapSchema>& schemas() const { return schemas_; }
  const std::map<uint16_t, McapChannel>& channels() const { return channels_; }
  const std::vector<McapChunkInfo>& chunks() const { return chunks_; }
  const McapStatistics& statistics() const { return statistics_; }
  const McapReadReport& report() const { return report_; }
  const std::string& path() const { return path_; }
  uint64_t file_size() const { return file_size_; }

  // The channel on `topic`, or nullptr.
  const McapChannel* FindChannel(std::string_view topic) const;

  // Calls `callback` for every message (only those on `topic` when given),
  // chunk by chunk in file order and by log time within a chunk. DataLoss
  // naming the chunk's byte offset when a chunk is damaged (in a recovered
  // file such chunks were already dropped at Open).
  absl::Status ForEachMessage(const McapMessageCallback& callback,
                              std::optional<std::string_view> topic = std::nullopt) const;

  // All messages (on `topic` when given), in ForEachMessage order.
  absl::StatusOr<std::vector<McapMessage>> ReadMessages(
      std::optional<std::string_view> topic = std::nullopt) const;

 private:
  McapReader(std::string path, int fd, uint64_t file_size);
  absl::StatusOr<std::string> ReadAt(uint64_t offset, uint64_t size) const;
  absl::Status ReadSummary();
  absl::Status ParseSummaryRecord(uint8_t opcode, std::string_view content, uint64_t offset);
  absl::Status Recover();
  absl::StatusOr<std::string> LoadChunkRecords(uint64_t chunk_offset,
                                               std::string_view content) const;
  // A Schema or Channel record found inside a chunk: (opcode, content).
  using DefinitionRecord = std::pair<uint8_t, std::string_view>;
  // Parses the uncompressed records of a chunk: messages sorted by log time,
  // and Schema/Channel records when `definitions` is given.
  absl::Status ParseChunk(uint64_t chunk_offset, std::string_view records,
                          std::vector<McapMessage>* messages,
                          std::vector<DefinitionRecord>* definitions) const;
  absl::Status ParseSchemaOrChannel(uint8_t opcode, std::string_view content, uint64_t offset);
  absl::Status ForEachInChunk(const McapChunkInfo& chunk, const McapMessageCallback& callback,
                              std::optional<uint16_t> channel_id) const;
  absl::Status Error(absl::StatusCode code, uint64_t offset, std::string_view what) const;

  std::string path_;
  McapReaderOptions options_;
  int fd_ = -1;
  uint64_t file_size_ = 0;
  std::map<uint16_t, McapSchema> schemas_;
  std::map<uint16_t, McapChannel> channels_;
  std::vector<McapChunkInfo> chunks_;
  // Messages found outside chunks: (offset in the file, record) in file
  // order, interleaved with chunks by offset.
  std::vector<std::pair<uint64_t, McapMessage>> loose_messages_;
  McapStatistics statistics_;
  McapReadReport report_;
};

}  // namespace reenact
