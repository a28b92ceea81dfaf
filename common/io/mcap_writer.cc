#include "common/io/mcap_writer.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <optional>
#include <set>
#include <utility>

#include <zstd.h>

#include "absl/strings/str_cat.h"
#include "common/base/files.h"
#include "common/base/status_macros.h"
#include "common/io/mcap_format.h"
#include "common/io/mcap_reader.h"

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
    if (errno == ENOSPC || errno == EDQUOT) {
      return FileError(absl::StrCat("cannot create MCAP file ", path), errno);
    }
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
    return FileError(absl::StrCat("write to ", path_, " failed at byte offset ", offset_), errno);
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

  ChunkIndexEntry entry{
      chunk_start_time_ns_,  chunk_end_time_ns_,  offset_, bytes.size(), {}, 0, payload.size(),
      chunk_records_.size(), options_.compression};
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
    return FileError(absl::StrCat("flush of ", path_, " failed at byte offset ", offset_), errno);
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
    mf::PutString(&content, e.compression);
    mf::PutU64(&content, e.compressed_size);
    mf::PutU64(&content, e.uncompressed_size);
    mf::PutRecord(&records, mf::kChunkIndex, content);
  }
  return records;
}

absl::Status McapWriter::Sync() {
  RETURN_IF_ERROR(FlushChunk());
  if (std::fflush(file_) != 0 || ::fsync(::fileno(file_)) != 0) {
    return FileError(absl::StrCat("fsync of ", path_, " failed"), errno);
  }
  return absl::OkStatus();
}

absl::Status McapWriter::CloseFile(bool sync) {
  std::FILE* file = file_;
  file_ = nullptr;
  absl::Status status;
  if (sync && (std::fflush(file) != 0 || ::fsync(::fileno(file)) != 0)) {
    status = FileError(absl::StrCat("fsync of ", path_, " failed"), errno);
  }
  if (std::fclose(file) != 0 && status.ok()) {
    status = FileError(absl::StrCat("closing ", path_, " failed"), errno);
  }
  return status;
}

absl::Status McapWriter::Close() {
  RETURN_IF_ERROR(CheckOpen());
  const absl::Status written = WriteTail();
  const absl::Status closed = CloseFile(written.ok() && options_.durable);
  return written.ok() ? closed : written;
}

absl::Status McapWriter::Abort() {
  RETURN_IF_ERROR(CheckOpen());
  chunk_records_.clear();
  chunk_message_index_.clear();
  return CloseFile(/*sync=*/false);
}

std::vector<std::pair<McapSchemaId, std::string>> McapWriter::SchemaNames() const {
  std::vector<std::pair<McapSchemaId, std::string>> out;
  for (size_t i = 0; i < schemas_.size(); ++i) {
    out.emplace_back(static_cast<McapSchemaId>(i + 1), schemas_[i].name);
  }
  return out;
}

std::vector<std::pair<McapChannelId, std::string>> McapWriter::ChannelTopics() const {
  std::vector<std::pair<McapChannelId, std::string>> out;
  for (size_t i = 0; i < channels_.size(); ++i) {
    out.emplace_back(static_cast<McapChannelId>(i), channels_[i].topic);
  }
  return out;
}

// ------------------------------------------------------------------ appending

// Walks the records of a file reopened for appending, rebuilds the writer's
// schemas, channels, chunk indexes and counts from those it keeps, and finds
// where the kept part ends. A chunk counts when McapReader read it without
// damage (at Open: through the summary of a finished file, or by a recovery
// scan that checks every chunk's CRC) and every Message Index record that
// McapWriter writes after it is there too.
class McapWriter::AppendScan {
 public:
  AppendScan(McapWriter* writer, int fd, uint64_t file_size, const McapReader& reader)
      : w_(writer), fd_(fd), file_size_(file_size) {
    for (const McapChunkInfo& chunk : reader.chunks())
      good_chunks_.emplace(chunk.chunk_offset, chunk);
  }

  // Fills the writer's state; `report` gets the kept size and the reason.
  absl::Status Run(McapAppendReport* report);

 private:
  struct PendingChunk {
    ChunkIndexEntry entry;
    uint64_t end = 0;  // End of its last Message Index record read so far.
    std::set<McapChannelId> expected_channels;
    std::map<McapChannelId, uint64_t> counts;
  };

  absl::StatusOr<std::string> ReadAt(uint64_t offset, uint64_t size) const;
  // Handles the record at `pos`; false ends the kept part (`stop_` says why).
  absl::StatusOr<bool> Visit(uint8_t opcode, uint64_t pos, uint64_t length);
  absl::Status AddDefinition(uint8_t opcode, std::string_view content, uint64_t pos);
  bool StartChunk(uint64_t pos, uint64_t length, std::string_view head);
  bool AddMessageIndex(uint64_t pos, std::string_view content);
  // Keeps the pending chunk when its Message Index records are complete.
  bool FinishChunk();

  McapWriter* w_;
  int fd_;
  uint64_t file_size_;
  std::map<uint64_t, McapChunkInfo> good_chunks_;
  std::optional<PendingChunk> pending_;
  uint64_t keep_ = mf::kMagic.size();
  uint64_t kept_messages_ = 0;
  bool header_seen_ = false;
  std::string stop_;
};

absl::StatusOr<std::string> McapWriter::AppendScan::ReadAt(uint64_t offset, uint64_t size) const {
  std::string bytes(size, '\0');
  uint64_t done = 0;
  while (done < size) {
    const ssize_t n = ::pread(fd_, bytes.data() + done, size - done, offset + done);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      return absl::DataLossError(absl::StrCat("read of ", w_->path_, " failed at byte offset ",
                                              offset + done, ": ",
                                              n < 0 ? std::strerror(errno) : "end of file"));
    }
    done += static_cast<uint64_t>(n);
  }
  return bytes;
}

absl::Status McapWriter::AppendScan::AddDefinition(uint8_t opcode, std::string_view content,
                                                   uint64_t pos) {
  mf::ByteCursor c(content);
  if (opcode == mf::kSchema) {
    const uint16_t id = c.U16();
    SchemaEntry s{std::string(c.String()), std::string(c.String()), std::string(c.String())};
    if (!c.ok()) return absl::DataLossError("malformed Schema record");
    if (id != w_->schemas_.size() + 1) {
      return absl::FailedPreconditionError(absl::StrCat(
          w_->path_, ": Schema id ", id, " at byte offset ", pos, " is not the next id (",
          w_->schemas_.size() + 1, "); only files written by McapWriter can be appended to"));
    }
    w_->schemas_.push_back(std::move(s));
    return absl::OkStatus();
  }
  const uint16_t id = c.U16();
  ChannelEntry ch;
  ch.schema_id = c.U16();
  ch.topic = std::string(c.String());
  ch.message_encoding = std::string(c.String());
  mf::ByteCursor map(c.String());
  while (c.ok() && map.ok() && map.remaining() > 0) {
    std::string key(map.String());
    ch.metadata[key] = std::string(map.String());
  }
  if (!c.ok() || !map.ok()) return absl::DataLossError("malformed Channel record");
  if (id != w_->channels_.size() || ch.schema_id > w_->schemas_.size()) {
    return absl::FailedPreconditionError(absl::StrCat(
        w_->path_, ": Channel id ", id, " at byte offset ", pos,
        " is not the next id or names an unknown schema; only files written by McapWriter can "
        "be appended to"));
  }
  w_->channels_.push_back(std::move(ch));
  w_->channel_message_counts_.push_back(0);
  return absl::OkStatus();
}

bool McapWriter::AppendScan::StartChunk(uint64_t pos, uint64_t length, std::string_view head) {
  const auto good = good_chunks_.find(pos);
  if (good == good_chunks_.end() || good->second.chunk_length != mf::kRecordPrefixBytes + length) {
    stop_ = absl::StrCat("chunk at byte offset ", pos, " is damaged");
    return false;
  }
  mf::ByteCursor c(head);
  PendingChunk chunk;
  ChunkIndexEntry& e = chunk.entry;
  e.start_time_ns = c.U64();
  e.end_time_ns = c.U64();
  e.uncompressed_size = c.U64();
  c.U32();  // uncompressed_crc
  e.compression = std::string(c.String());
  e.compressed_size = c.U64();
  if (!c.ok()) {
    stop_ = absl::StrCat("chunk at byte offset ", pos, " has a malformed header");
    return false;
  }
  e.chunk_offset = pos;
  e.chunk_length = mf::kRecordPrefixBytes + length;
  e.message_index_length = 0;
  chunk.end = pos + e.chunk_length;
  chunk.expected_channels.insert(good->second.channel_ids.begin(), good->second.channel_ids.end());
  pending_ = std::move(chunk);
  return true;
}

bool McapWriter::AppendScan::AddMessageIndex(uint64_t pos, std::string_view content) {
  mf::ByteCursor c(content);
  const McapChannelId channel = c.U16();
  const std::string_view entries = c.String();
  if (!c.ok() || entries.size() % 16 != 0 || channel >= w_->channels_.size()) {
    stop_ = absl::StrCat("malformed Message Index record at byte offset ", pos);
    return false;
  }
  pending_->entry.message_index_offsets[channel] = pos;
  pending_->entry.message_index_length += mf::kRecordPrefixBytes + content.size();
  pending_->counts[channel] += entries.size() / 16;
  pending_->end = pos + mf::kRecordPrefixBytes + content.size();
  return true;
}

bool McapWriter::AppendScan::FinishChunk() {
  PendingChunk chunk = std::move(*pending_);
  pending_.reset();
  std::set<McapChannelId> indexed;
  for (const auto& [channel, count] : chunk.counts) indexed.insert(channel);
  if (indexed != chunk.expected_channels) {
    stop_ = absl::StrCat("chunk at byte offset ", chunk.entry.chunk_offset,
                         " lacks Message Index records (torn after the chunk)");
    return false;
  }
  for (const auto& [channel, count] : chunk.counts) {
    if (count == 0) continue;
    w_->start_time_ns_ = w_->message_count_ == 0
                             ? chunk.entry.start_time_ns
                             : std::min(w_->start_time_ns_, chunk.entry.start_time_ns);
    w_->end_time_ns_ = w_->message_count_ == 0
                           ? chunk.entry.end_time_ns
                           : std::max(w_->end_time_ns_, chunk.entry.end_time_ns);
    w_->message_count_ += count;
    w_->channel_message_counts_[channel] += count;
    w_->channels_[channel].next_sequence += static_cast<uint32_t>(count);
    kept_messages_ += count;
  }
  w_->chunk_indexes_.push_back(std::move(chunk.entry));
  keep_ = chunk.end;
  return true;
}

absl::StatusOr<bool> McapWriter::AppendScan::Visit(uint8_t opcode, uint64_t pos, uint64_t length) {
  const uint64_t end = pos + mf::kRecordPrefixBytes + length;
  if (pending_ && opcode != mf::kMessageIndex && !FinishChunk()) return false;
  if (!header_seen_) {
    if (opcode != mf::kHeader) {
      return absl::DataLossError(
          absl::StrCat(w_->path_, ": no Header record at byte offset ", pos));
    }
    header_seen_ = true;
    keep_ = end;
    return true;
  }
  switch (opcode) {
    case mf::kSchema:
    case mf::kChannel: {
      ASSIGN_OR_RETURN(const std::string content, ReadAt(pos + mf::kRecordPrefixBytes, length));
      if (absl::Status s = AddDefinition(opcode, content, pos); !s.ok()) {
        if (s.code() == absl::StatusCode::kFailedPrecondition) return s;
        stop_ = absl::StrCat(s.message(), " at byte offset ", pos);
        return false;
      }
      keep_ = end;
      return true;
    }
    case mf::kChunk: {
      ASSIGN_OR_RETURN(const std::string head,
                       ReadAt(pos + mf::kRecordPrefixBytes, std::min<uint64_t>(length, 256)));
      return StartChunk(pos, length, head);
    }
    case mf::kMessageIndex: {
      if (!pending_) {
        stop_ = absl::StrCat("Message Index record at byte offset ", pos, " follows no chunk");
        return false;
      }
      ASSIGN_OR_RETURN(const std::string content, ReadAt(pos + mf::kRecordPrefixBytes, length));
      return AddMessageIndex(pos, content);
    }
    case mf::kMessage:
      return absl::FailedPreconditionError(
          absl::StrCat(w_->path_, ": message outside chunks at byte offset ", pos,
                       "; only files written by McapWriter can be appended to"));
    case mf::kDataEnd:
      stop_ = absl::StrCat("DataEnd record at byte offset ", pos);
      return false;
    default:
      stop_ = absl::StrCat("record with opcode ", static_cast<int>(opcode), " at byte offset ", pos,
                           " ends the data section");
      return false;
  }
}

absl::Status McapWriter::AppendScan::Run(McapAppendReport* report) {
  uint64_t pos = mf::kMagic.size();
  while (true) {
    if (file_size_ - pos < mf::kRecordPrefixBytes) {
      stop_ = pos == file_size_ ? "end of file"
                                : absl::StrCat("record header torn at byte offset ", pos);
      break;
    }
    ASSIGN_OR_RETURN(const std::string prefix_bytes, ReadAt(pos, mf::kRecordPrefixBytes));
    mf::ByteCursor prefix(prefix_bytes);
    const uint8_t opcode = prefix.U8();
    const uint64_t length = prefix.U64();
    if (length > file_size_ - pos - mf::kRecordPrefixBytes) {
      stop_ = absl::StrCat("record with opcode ", static_cast<int>(opcode), " at byte offset ", pos,
                           " is torn (declares ", length, " bytes)");
      break;
    }
    ASSIGN_OR_RETURN(const bool go_on, Visit(opcode, pos, length));
    if (!go_on) break;
    pos += mf::kRecordPrefixBytes + length;
  }
  if (pending_) FinishChunk();
  if (!header_seen_) {
    return absl::DataLossError(absl::StrCat(w_->path_, ": no whole Header record"));
  }
  report->kept_bytes = keep_;
  report->dropped_bytes = file_size_ - keep_;
  report->kept_chunks = w_->chunk_indexes_.size();
  report->kept_messages = kept_messages_;
  report->stop_reason = stop_;
  return absl::OkStatus();
}

absl::StatusOr<std::unique_ptr<McapWriter>> McapWriter::OpenForAppend(
    const std::string& path, const McapWriterOptions& options, McapAppendReport* report) {
  RETURN_IF_ERROR(options.Validate());
  ASSIGN_OR_RETURN(std::unique_ptr<McapReader> reader, McapReader::Open(path));
  std::FILE* file = std::fopen(path.c_str(), "r+b");
  if (file == nullptr) {
    return absl::UnavailableError(
        absl::StrCat("cannot open MCAP file ", path, " for appending: ", std::strerror(errno)));
  }
  std::unique_ptr<McapWriter> writer(new McapWriter(path, options, file));
  McapAppendReport local;
  if (report == nullptr) report = &local;
  *report = McapAppendReport{};
  const int fd = ::fileno(file);
  absl::Status status;
  struct stat st {};
  if (::fstat(fd, &st) != 0) {
    status = absl::UnavailableError(absl::StrCat("cannot stat ", path, ": ", std::strerror(errno)));
  }
  if (status.ok()) {
    status = AppendScan(writer.get(), fd, static_cast<uint64_t>(st.st_size), *reader).Run(report);
  }
  reader.reset();
  if (status.ok() && (::ftruncate(fd, static_cast<off_t>(report->kept_bytes)) != 0 ||
                      (options.durable && ::fsync(fd) != 0) ||
                      ::fseeko(file, static_cast<off_t>(report->kept_bytes), SEEK_SET) != 0)) {
    status = absl::DataLossError(absl::StrCat("cannot cut ", path, " at byte offset ",
                                              report->kept_bytes, ": ", std::strerror(errno)));
  }
  if (!status.ok()) {
    writer->Abort().IgnoreError();  // Closing normally would write a tail at a wrong offset.
    return status;
  }
  writer->offset_ = report->kept_bytes;
  return writer;
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
