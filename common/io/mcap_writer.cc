#include "common/io/mcap_writer.h"

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <utility>

#include <zstd.h>

#include "absl/strings/str_cat.h"
#include "common/base/status_macros.h"
#include "common/io/mcap_format.h"

namespace reenact {

namespace mf = mcap_format;

absl::Status McapWriterOptions::Validate() const {
  if (chunk_size_bytes == 0) {
    return absl::InvalidArgumentError("McapWriterOptions.chunk_size_bytes must be > 0");
  }
  if (compression != "zstd" && !compression.empty()) {
    return absl::InvalidArgumentError(absl::StrCat(
        "McapWriterOptions.compression must be \"zstd\" or \"\", got \"", compression, "\""));
  }
  if (zstd_level < 1 || zstd_level > ZSTD_maxCLevel()) {
    return absl::InvalidArgumentError(absl::StrCat("McapWriterOptions.zstd_level must be in [1, ",
                                                   ZSTD_maxCLevel(), "], got ", zstd_level));
  }
  return absl::OkStatus();
}

absl::StatusOr<std::unique_ptr<McapWriter>> McapWriter::Open(const std::string& path,
                                                             const McapWriterOptions& options) {
  RETURN_IF_ERROR(options.Validate());
  std::FILE* file = std::fopen(path.c_str(), "wb");
  if (file == nullptr) {
    return absl::UnavailableError(
        absl::StrCat("cannot create MCAP file ", path, ": ", std::strerror(errno)));
  }
  std::unique_ptr<McapWriter> writer(new McapWriter(path, options, file));
  std::string header;
  mf::PutString(&header, options.profile);
  mf::PutString(&header, options.library);
  std::string bytes(mf::kMagic);
  mf::PutRecord(&bytes, mf::kHeader, header);
  RETURN_IF_ERROR(writer->Append(bytes));
  return writer;
}

McapWriter::McapWriter(std::string path, McapWriterOptions options, std::FILE* file)
    : path_(std::move(path)), options_(std::move(options)), file_(file) {}

McapWriter::~McapWriter() {
  if (file_ != nullptr) Close().IgnoreError();
}

absl::Status McapWriter::CheckOpen() const {
  if (file_ == nullptr) {
    return absl::FailedPreconditionError(absl::StrCat("MCAP writer of ", path_, " is closed"));
  }
  return absl::OkStatus();
}

absl::Status McapWriter::Append(std::string_view bytes) {
  if (std::fwrite(bytes.data(), 1, bytes.size(), file_) != bytes.size()) {
    return absl::DataLossError(absl::StrCat("write to ", path_, " failed at byte offset ", offset_,
                                            ": ", std::strerror(errno)));
  }
  offset_ += bytes.size();
  return absl::OkStatus();
}

std::string McapWriter::SchemaContent(McapSchemaId id, const SchemaEntry& s) {
  std::string content;
  mf::PutU16(&content, id);
  mf::PutString(&content, s.name);
  mf::PutString(&content, s.encoding);
  mf::PutString(&content, s.data);
  return content;
}

std::string McapWriter::ChannelContent(McapChannelId id, const ChannelEntry& c) {
  std::string content;
  mf::PutU16(&content, id);
  mf::PutU16(&content, c.schema_id);
  mf::PutString(&content, c.topic);
  mf::PutString(&content, c.message_encoding);
  std::string map;
  for (const auto& [key, value] : c.metadata) {
    mf::PutString(&map, key);
    mf::PutString(&map, value);
  }
  mf::PutString(&content, map);
  return content;
}

absl::StatusOr<McapSchemaId> McapWriter::AddSchema(std::string_view name, std::string_view encoding,
                                                   std::string_view data) {
  RETURN_IF_ERROR(CheckOpen());
  if (schemas_.size() >= 0xFFFF) return absl::ResourceExhaustedError("too many MCAP schemas");
  schemas_.push_back({std::string(name), std::string(encoding), std::string(data)});
  const auto id = static_cast<McapSchemaId>(schemas_.size());
  std::string record;
  mf::PutRecord(&record, mf::kSchema, SchemaContent(id, schemas_.back()));
  RETURN_IF_ERROR(Append(record));
  return id;
}

absl::StatusOr<McapChannelId> McapWriter::AddChannel(
    McapSchemaId schema_id, std::string_view topic, std::string_view message_encoding,
    const std::map<std::string, std::string>& metadata) {
  RETURN_IF_ERROR(CheckOpen());
  if (schema_id > schemas_.size()) {
    return absl::InvalidArgumentError(absl::StrCat("unknown MCAP schema id ", schema_id));
  }
  if (channels_.size() >= 0xFFFF) return absl::ResourceExhaustedError("too many MCAP channels");
  channels_.push_back({schema_id, std::string(topic), std::string(message_encoding), metadata});
  channel_message_counts_.push_back(0);
  const auto id = static_cast<McapChannelId>(channels_.size() - 1);
  std::string record;
  mf::PutRecord(&record, mf::kChannel, ChannelContent(id, channels_.back()));
  RETURN_IF_ERROR(Append(record));
  return id;
}

absl::Status McapWriter::WriteMessage(McapChannelId channel_id, uint64_t log_time_ns,
                                      uint64_t publish_time_ns, std::string_view data) {
  RETURN_IF_ERROR(CheckOpen());
  if (channel_id >= channels_.size()) {
    return absl::InvalidArgumentError(absl::StrCat("unknown MCAP channel id ", channel_id));
  }
  ChannelEntry& channel = channels_[channel_id];
  const bool first_in_chunk = chunk_records_.empty();
  chunk_message_index_[channel_id].emplace_back(log_time_ns, chunk_records_.size());
  mf::PutU8(&chunk_records_, mf::kMessage);
  mf::PutU64(&chunk_records_, 2 + 4 + 8 + 8 + data.size());
  mf::PutU16(&chunk_records_, channel_id);
  mf::PutU32(&chunk_records_, channel.next_sequence++);
  mf::PutU64(&chunk_records_, log_time_ns);
  mf::PutU64(&chunk_records_, publish_time_ns);
  chunk_records_.append(data);
  chunk_start_time_ns_ = first_in_chunk ? log_time_ns : std::min(chunk_start_time_ns_, log_time_ns);
  chunk_end_time_ns_ = first_in_chunk ? log_time_ns : std::max(chunk_end_time_ns_, log_time_ns);
  start_time_ns_ = message_count_ == 0 ? log_time_ns : std::min(start_time_ns_, log_time_ns);
  end_time_ns_ = message_count_ == 0 ? log_time_ns : std::max(end_time_ns_, log_time_ns);
  ++message_count_;
  ++channel_message_counts_[channel_id];
  if (chunk_records_.size() >= options_.chunk_size_bytes) return FlushChunk();
  return absl::OkStatus();
}

absl::Status McapWriter::FlushChunk() {
  RETURN_IF_ERROR(CheckOpen());
  if (chunk_records_.empty()) return absl::OkStatus();
  std::string compressed;
  std::string_view payload = chunk_records_;
  if (options_.compression == "zstd") {
    compressed.resize(ZSTD_compressBound(chunk_records_.size()));
    const size_t n = ZSTD_compress(compressed.data(), compressed.size(), chunk_records_.data(),
                                   chunk_records_.size(), options_.zstd_level);
    if (ZSTD_isError(n)) {
      return absl::InternalError(absl::StrCat("zstd compression failed: ", ZSTD_getErrorName(n)));
    }
    compressed.resize(n);
    payload = compressed;
  }
  std::string content;
  mf::PutU64(&content, chunk_start_time_ns_);
  mf::PutU64(&content, chunk_end_time_ns_);
  mf::PutU64(&content, chunk_records_.size());
  mf::PutU32(&content, mf::Crc32(chunk_records_));
  mf::PutString(&content, options_.compression);
  mf::PutU64(&content, payload.size());
  content.append(payload);
  std::string bytes;
  mf::PutRecord(&bytes, mf::kChunk, content);

  ChunkIndexEntry entry{chunk_start_time_ns_, chunk_end_time_ns_,   offset_, bytes.size(), {}, 0,
                        payload.size(),       chunk_records_.size()};
  for (auto& [channel_id, index] : chunk_message_index_) {
    std::stable_sort(index.begin(), index.end(),
                     [](const auto& a, const auto& b) { return a.first < b.first; });
    std::string index_content;
    mf::PutU16(&index_content, channel_id);
    mf::PutU32(&index_content, static_cast<uint32_t>(index.size() * 16));
    for (const auto& [log_time_ns, record_offset] : index) {
      mf::PutU64(&index_content, log_time_ns);
      mf::PutU64(&index_content, record_offset);
    }
    entry.message_index_offsets[channel_id] = offset_ + bytes.size();
    mf::PutRecord(&bytes, mf::kMessageIndex, index_content);
  }
  entry.message_index_length = bytes.size() - entry.chunk_length;
  RETURN_IF_ERROR(Append(bytes));
  if (std::fflush(file_) != 0) {
    return absl::DataLossError(absl::StrCat("flush of ", path_, " failed at byte offset ", offset_,
                                            ": ", std::strerror(errno)));
  }
  chunk_indexes_.push_back(std::move(entry));
  chunk_records_.clear();
  chunk_message_index_.clear();
  return absl::OkStatus();
}

std::string McapWriter::StatisticsRecord() const {
  std::string content;
  mf::PutU64(&content, message_count_);
  mf::PutU16(&content, static_cast<uint16_t>(schemas_.size()));
  mf::PutU32(&content, static_cast<uint32_t>(channels_.size()));
  mf::PutU32(&content, 0);  // attachment_count
  mf::PutU32(&content, 0);  // metadata_count
  mf::PutU32(&content, static_cast<uint32_t>(chunk_indexes_.size()));
  mf::PutU64(&content, start_time_ns_);
  mf::PutU64(&content, end_time_ns_);
  std::string counts;
  for (size_t id = 0; id < channels_.size(); ++id) {
    mf::PutU16(&counts, static_cast<uint16_t>(id));
    mf::PutU64(&counts, channel_message_counts_[id]);
  }
  mf::PutString(&content, counts);
  std::string record;
  mf::PutRecord(&record, mf::kStatistics, content);
  return record;
}

std::string McapWriter::ChunkIndexRecords() const {
  std::string records;
  for (const ChunkIndexEntry& e : chunk_indexes_) {
    std::string content;
    mf::PutU64(&content, e.start_time_ns);
    mf::PutU64(&content, e.end_time_ns);
    mf::PutU64(&content, e.chunk_offset);
    mf::PutU64(&content, e.chunk_length);
    std::string offsets;
    for (const auto& [channel_id, offset] : e.message_index_offsets) {
      mf::PutU16(&offsets, channel_id);
      mf::PutU64(&offsets, offset);
    }
    mf::PutString(&content, offsets);
    mf::PutU64(&content, e.message_index_length);
    mf::PutString(&content, options_.compression);
    mf::PutU64(&content, e.compressed_size);
    mf::PutU64(&content, e.uncompressed_size);
    mf::PutRecord(&records, mf::kChunkIndex, content);
  }
  return records;
}

absl::Status McapWriter::Close() {
  RETURN_IF_ERROR(CheckOpen());
  const absl::Status written = WriteTail();
  std::FILE* file = file_;
  file_ = nullptr;
  if (std::fclose(file) != 0 && written.ok()) {
    return absl::DataLossError(absl::StrCat("closing ", path_, " failed: ", std::strerror(errno)));
  }
  return written;
}

absl::Status McapWriter::WriteTail() {
  RETURN_IF_ERROR(FlushChunk());
  std::string data_end;
  mf::PutU32(&data_end, 0);  // data_section_crc: not computed.
  std::string bytes;
  mf::PutRecord(&bytes, mf::kDataEnd, data_end);
  const uint64_t summary_start = offset_ + bytes.size();

  // Summary section, one group per record kind, then one Summary Offset per group.
  std::vector<std::pair<uint8_t, std::string>> groups(4);
  groups[0].first = mf::kSchema;
  for (size_t i = 0; i < schemas_.size(); ++i) {
    mf::PutRecord(&groups[0].second, mf::kSchema,
                  SchemaContent(static_cast<McapSchemaId>(i + 1), schemas_[i]));
  }
  groups[1].first = mf::kChannel;
  for (size_t i = 0; i < channels_.size(); ++i) {
    mf::PutRecord(&groups[1].second, mf::kChannel,
                  ChannelContent(static_cast<McapChannelId>(i), channels_[i]));
  }
  groups[2] = {mf::kStatistics, StatisticsRecord()};
  groups[3] = {mf::kChunkIndex, ChunkIndexRecords()};
  std::string summary, offsets;
  for (const auto& [opcode, group] : groups) {
    if (group.empty()) continue;
    std::string content;
    mf::PutU8(&content, opcode);
    mf::PutU64(&content, summary_start + summary.size());
    mf::PutU64(&content, group.size());
    mf::PutRecord(&offsets, mf::kSummaryOffset, content);
    summary += group;
  }
  const uint64_t summary_offset_start = summary_start + summary.size();
  // The footer's CRC covers the summary and summary offset sections and the
  // footer up to (excluding) the CRC field.
  std::string footer_head;
  mf::PutU8(&footer_head, mf::kFooter);
  mf::PutU64(&footer_head, mf::kFooterContentBytes);
  mf::PutU64(&footer_head, summary_start);
  mf::PutU64(&footer_head, summary_offset_start);
  const uint32_t summary_crc = mf::Crc32(footer_head, mf::Crc32(offsets, mf::Crc32(summary)));
  bytes += summary;
  bytes += offsets;
  bytes += footer_head;
  mf::PutU32(&bytes, summary_crc);
  bytes.append(mf::kMagic);
  return Append(bytes);
}

}  // namespace reenact
