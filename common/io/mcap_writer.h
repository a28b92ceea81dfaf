// Writes MCAP v0 files (https://mcap.dev/spec) from scratch: magic, Header,
// Schema and Channel records in the data section, messages grouped in Chunks
// (optionally zstd-compressed, with the CRC-32 of their uncompressed records)
// each followed by its Message Index records, DataEnd, a Summary section
// (Schemas, Channels, Statistics, Chunk Indexes) with Summary Offsets, Footer
// and the closing magic.
//
// Durability: each finished chunk is written and flushed to the operating
// system at once, and Schema/Channel records are written outside chunks
// before the first chunk that uses them, so a writer that dies leaves a file
// whose complete chunks McapReader recovers. Sync() also makes them survive a
// crash of the machine (fsync).
//
// Appending: OpenForAppend reopens a file this writer wrote (finished, or cut
// short by a crash), keeps its intact leading records and goes on writing
// after them; Close() then writes a summary that covers old and new chunks.
// Resuming a long recording therefore costs a scan of record headers, not a
// copy of the file.
#pragma once

#include <cstdint>
#include <cstdio>
#include <map>
#include <memory>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"

namespace reenact {

// Options of McapWriter.
struct McapWriterOptions {
  // A chunk is closed once its uncompressed records reach this many bytes.
  uint64_t chunk_size_bytes = uint64_t{4} << 20;
  // Chunk compression: "zstd" or "" (none).
  std::string compression = "zstd";
  // zstd compression level, 1 (fast) .. 19 (small).
  int zstd_level = 3;
  // Header.profile of the file (empty: no well-known profile).
  std::string profile;
  // Header.library: the program that wrote the file.
  std::string library = "reenact";
  // Close() and the cut of OpenForAppend fsync the file, so that they
  // survive a crash of the machine (Sync() always does).
  bool durable = false;

  // InvalidArgument naming the first bad field.
  absl::Status Validate() const;
};

// Identifies a schema within one file; 0 is never a valid id.
using McapSchemaId = uint16_t;
// Identifies a channel within one file.
using McapChannelId = uint16_t;

// What McapWriter::OpenForAppend kept of an existing file.
struct McapAppendReport {
  // Bytes kept from the start of the file; new records follow them.
  uint64_t kept_bytes = 0;
  // Bytes cut off the end: a chunk torn by a crash, a damaged chunk and all
  // after it, or the DataEnd record, summary and footer of a finished file.
  uint64_t dropped_bytes = 0;
  // Chunks and messages kept.
  uint64_t kept_chunks = 0;
  uint64_t kept_messages = 0;
  // Why the kept part ends where it does, naming the byte offset.
  std::string stop_reason;
};

// Streams messages into one MCAP file. Not thread-safe.
class McapWriter {
 public:
  // Creates (truncates) `path` and writes the magic and Header.
  static absl::StatusOr<std::unique_ptr<McapWriter>> Open(const std::string& path,
                                                          const McapWriterOptions& options = {});
  // Reopens `path`, written by McapWriter, to add to it. Keeps the leading
  // records up to the first one that is not whole and intact (Header, Schema
  // and Channel records, Chunks that McapReader reads without damage together
  // with all their Message Index records), cuts off the rest (ftruncate;
  // fsync with options.durable) and writes new records after it. Channel
  // sequence numbers and statistics continue from the kept messages; new
  // chunks use `options` (profile and library come from the kept Header).
  // NotFound when `path` does not exist, InvalidArgument when it is not an
  // MCAP file, DataLoss when not even its Header survived, FailedPrecondition
  // when it holds what McapWriter never writes (sparse schema or channel ids,
  // messages outside chunks).
  static absl::StatusOr<std::unique_ptr<McapWriter>> OpenForAppend(
      const std::string& path, const McapWriterOptions& options = {},
      McapAppendReport* report = nullptr);
  // Closes the file if Close() or Abort() was not called (errors are lost
  // then).
  ~McapWriter();
  McapWriter(const McapWriter&) = delete;
  McapWriter& operator=(const McapWriter&) = delete;

  // Registers a schema: `name` (e.g. "reenact.v1.DepthImage"), `encoding`
  // (e.g. "protobuf") and its `data` (e.g. a FileDescriptorSet).
  absl::StatusOr<McapSchemaId> AddSchema(std::string_view name, std::string_view encoding,
                                         std::string_view data);

  // Registers a channel on `topic` whose messages follow `schema_id` and are
  // encoded as `message_encoding` (e.g. "protobuf").
  absl::StatusOr<McapChannelId> AddChannel(McapSchemaId schema_id, std::string_view topic,
                                           std::string_view message_encoding,
                                           const std::map<std::string, std::string>& metadata = {});

  // Appends one message. `log_time_ns`: when it was recorded; `publish_time_ns`:
  // when it was produced; both nanoseconds on the file's common clock. The
  // sequence number counts the channel's messages from 0.
  absl::Status WriteMessage(McapChannelId channel_id, uint64_t log_time_ns,
                            uint64_t publish_time_ns, std::string_view data);

  // Writes the chunk in progress (if any) and flushes it to the OS.
  absl::Status FlushChunk();

  // FlushChunk(), then fsync: everything written so far survives a crash of
  // the machine.
  absl::Status Sync();

  // Writes the last chunk, DataEnd, the Summary section, the Footer and the
  // closing magic, then closes the file. Further calls fail.
  absl::Status Close();

  // Closes the file without writing the chunk in progress or anything after
  // it: the file ends after the last flushed chunk, as if the writer had
  // died (McapReader recovers it, OpenForAppend continues it). For writers
  // whose last write failed half-way. Further calls fail.
  absl::Status Abort();

  // Bytes written to the file so far (after OpenForAppend: the kept bytes
  // plus those written since).
  uint64_t bytes_written() const { return offset_; }
  // Uncompressed record bytes of the chunk in progress (0 right after a
  // flush).
  uint64_t pending_chunk_bytes() const { return chunk_records_.size(); }
  // Schemas (id, name) and channels (id, topic) registered so far, including
  // those OpenForAppend kept, in id order.
  std::vector<std::pair<McapSchemaId, std::string>> SchemaNames() const;
  std::vector<std::pair<McapChannelId, std::string>> ChannelTopics() const;
  // Messages per channel id so far (kept and new).
  uint64_t channel_message_count(McapChannelId id) const {
    return id < channel_message_counts_.size() ? channel_message_counts_[id] : 0;
  }

 private:
  struct ChunkIndexEntry {
    uint64_t start_time_ns, end_time_ns, chunk_offset, chunk_length;
    std::map<McapChannelId, uint64_t> message_index_offsets;
    uint64_t message_index_length, compressed_size, uncompressed_size;
    std::string compression;
  };
  class AppendScan;
  struct SchemaEntry {
    std::string name, encoding, data;
  };
  struct ChannelEntry {
    McapSchemaId schema_id;
    std::string topic, message_encoding;
    std::map<std::string, std::string> metadata;
    uint32_t next_sequence = 0;
  };

  McapWriter(std::string path, McapWriterOptions options, std::FILE* file);
  absl::Status Append(std::string_view bytes);
  absl::Status CheckOpen() const;
  // Closes file_ (fsync first when `sync`); DataLoss naming the file on
  // failure.
  absl::Status CloseFile(bool sync);
  // Everything from the last chunk to the closing magic.
  absl::Status WriteTail();
  std::string ChunkIndexRecords() const;
  std::string StatisticsRecord() const;
  static std::string SchemaContent(McapSchemaId id, const SchemaEntry& s);
  static std::string ChannelContent(McapChannelId id, const ChannelEntry& c);

  std::string path_;
  McapWriterOptions options_;
  std::FILE* file_ = nullptr;
  uint64_t offset_ = 0;
  std::vector<SchemaEntry> schemas_;    // id = index + 1
  std::vector<ChannelEntry> channels_;  // id = index
  std::vector<uint64_t> channel_message_counts_;
  std::vector<ChunkIndexEntry> chunk_indexes_;
  // Chunk in progress: uncompressed records and per-channel (log time, offset).
  std::string chunk_records_;
  std::map<McapChannelId, std::vector<std::pair<uint64_t, uint64_t>>> chunk_message_index_;
  uint64_t chunk_start_time_ns_ = 0, chunk_end_time_ns_ = 0;
  uint64_t message_count_ = 0, start_time_ns_ = 0, end_time_ns_ = 0;
};

}  // namespace reenact
