#include "common/io/mcap_reader.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <memory>
#include <utility>

#include <zstd.h>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "common/base/status_macros.h"
#include "common/io/mcap_format.h"

namespace reenact {

namespace mf = mcap_format;

namespace {

// Largest uncompressed chunk we accept; a larger claim is treated as damage
// rather than an allocation request.
constexpr uint64_t kMaxChunkRecordsBytes = uint64_t{4} << 30;
// First output buffer of a compressed chunk: what its frame is sure to need.
constexpr uint64_t kFirstChunkBuffer = uint64_t{1} << 16;

std::string OpcodeName(uint8_t opcode) { return absl::StrFormat("opcode 0x%02x", opcode); }

}  // namespace

std::string McapReadReport::Summary() const {
  std::string s = indexed ? "read through the summary" : "recovered by scanning the data section";
  if (!summary_problem.empty()) absl::StrAppend(&s, " (summary unusable: ", summary_problem, ")");
  if (!stop_reason.empty()) {
    absl::StrAppend(&s, "; stopped at byte offset ", stop_offset, ": ", stop_reason);
  }
  for (const std::string& chunk : skipped_chunks) absl::StrAppend(&s, "; skipped ", chunk);
  return s;
}

McapReader::McapReader(std::string path, int fd, uint64_t file_size)
    : path_(std::move(path)), fd_(fd), file_size_(file_size) {}

McapReader::~McapReader() {
  if (fd_ >= 0) ::close(fd_);
}

absl::Status McapReader::Error(absl::StatusCode code, uint64_t offset,
                               std::string_view what) const {
  return absl::Status(code, absl::StrCat(path_, ": byte offset ", offset, ": ", std::string(what)));
}

absl::StatusOr<std::string> McapReader::ReadAt(uint64_t offset, uint64_t size) const {
  if (offset > file_size_ || size > file_size_ - offset) {
    return Error(absl::StatusCode::kDataLoss, offset,
                 absl::StrCat("read of ", size, " bytes runs past the end of the file (",
                              file_size_, " bytes)"));
  }
  std::string bytes(size, '\0');
  uint64_t done = 0;
  while (done < size) {
    const ssize_t n = ::pread(fd_, bytes.data() + done, size - done, offset + done);
    if (n <= 0) {
      if (n < 0 && errno == EINTR) continue;
      return Error(absl::StatusCode::kDataLoss, offset + done,
                   absl::StrCat("read failed: ", n < 0 ? std::strerror(errno) : "end of file"));
    }
    done += static_cast<uint64_t>(n);
  }
  return bytes;
}

absl::Status McapReaderOptions::Validate() const {
  if (max_chunk_bytes == 0 || max_chunk_bytes > kMaxChunkRecordsBytes) {
    return absl::InvalidArgumentError(absl::StrCat(
        "max_chunk_bytes must be in 1..", kMaxChunkRecordsBytes, ", got ", max_chunk_bytes));
  }
  return absl::OkStatus();
}

absl::StatusOr<std::unique_ptr<McapReader>> McapReader::Open(const std::string& path,
                                                             const McapReaderOptions& options) {
  RETURN_IF_ERROR(options.Validate());
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) {
    const int err = errno;
    const std::string message =
        absl::StrCat("cannot open MCAP file ", path, ": ", std::strerror(err));
    return err == ENOENT ? absl::NotFoundError(message) : absl::UnavailableError(message);
  }
  struct stat st {};
  if (::fstat(fd, &st) != 0) {
    ::close(fd);
    return absl::UnavailableError(absl::StrCat("cannot stat ", path, ": ", std::strerror(errno)));
  }
  std::unique_ptr<McapReader> reader(new McapReader(path, fd, static_cast<uint64_t>(st.st_size)));
  reader->options_ = options;
  const uint64_t head_size = std::min<uint64_t>(reader->file_size_, mf::kMagic.size());
  ASSIGN_OR_RETURN(const std::string head, reader->ReadAt(0, head_size));
  if (head != mf::kMagic.substr(0, head_size)) {
    return reader->Error(absl::StatusCode::kInvalidArgument, 0,
                         "not an MCAP file (the leading magic bytes do not match)");
  }
  if (head_size < mf::kMagic.size()) {
    return reader->Error(absl::StatusCode::kDataLoss, head_size,
                         "file ends inside the leading MCAP magic");
  }
  const absl::Status summary = reader->ReadSummary();
  if (summary.ok()) return reader;
  reader->report_.summary_problem = std::string(summary.message());
  if (!options.allow_recovery) return absl::DataLossError(summary.message());
  RETURN_IF_ERROR(reader->Recover());
  return reader;
}

absl::Status McapReader::ReadSummary() {
  constexpr uint64_t kFooterRecordBytes = mf::kRecordPrefixBytes + mf::kFooterContentBytes;
  const uint64_t tail_bytes = kFooterRecordBytes + mf::kMagic.size();
  if (file_size_ < mf::kMagic.size() + tail_bytes) {
    return Error(absl::StatusCode::kDataLoss, file_size_, "file too short to hold a footer");
  }
  const uint64_t footer_offset = file_size_ - tail_bytes;
  ASSIGN_OR_RETURN(const std::string tail, ReadAt(footer_offset, tail_bytes));
  if (std::string_view(tail).substr(kFooterRecordBytes) != mf::kMagic) {
    return Error(absl::StatusCode::kDataLoss, file_size_ - mf::kMagic.size(),
                 "no closing MCAP magic (truncated file?)");
  }
  mf::ByteCursor footer(tail);
  if (footer.U8() != mf::kFooter || footer.U64() != mf::kFooterContentBytes) {
    return Error(absl::StatusCode::kDataLoss, footer_offset, "no Footer record before the magic");
  }
  const uint64_t summary_start = footer.U64();
  const uint64_t summary_offset_start = footer.U64();
  const uint32_t summary_crc = footer.U32();
  if (summary_start == 0) {
    return Error(absl::StatusCode::kNotFound, footer_offset, "file has no summary section");
  }
  const uint64_t summary_end = summary_offset_start != 0 ? summary_offset_start : footer_offset;
  if (summary_start < mf::kMagic.size() || summary_start > summary_end ||
      summary_end > footer_offset) {
    return Error(absl::StatusCode::kDataLoss, footer_offset,
                 absl::StrCat("footer points at summary [", summary_start, ", ", summary_end,
                              ") outside the file"));
  }
  ASSIGN_OR_RETURN(const std::string summary,
                   ReadAt(summary_start, footer_offset + 1 + 8 + 8 + 8 - summary_start));
  const std::string_view sections =
      std::string_view(summary).substr(0, footer_offset - summary_start);
  if (summary_crc != 0 && mf::Crc32(summary) != summary_crc) {
    return Error(absl::StatusCode::kDataLoss, summary_start, "summary CRC mismatch");
  }
  bool has_statistics = false;
  uint64_t pos = 0;
  const uint64_t records_end = summary_end - summary_start;
  while (pos < records_end) {
    mf::ByteCursor prefix(sections.substr(pos, records_end - pos));
    const uint8_t opcode = prefix.U8();
    const uint64_t length = prefix.U64();
    if (!prefix.ok() || length > prefix.remaining()) {
      return Error(absl::StatusCode::kDataLoss, summary_start + pos,
                   "summary record runs past the summary section");
    }
    has_statistics |= opcode == mf::kStatistics;
    RETURN_IF_ERROR(ParseSummaryRecord(
        opcode, sections.substr(pos + mf::kRecordPrefixBytes, length), summary_start + pos));
    pos += mf::kRecordPrefixBytes + length;
  }
  if (!has_statistics) {
    return Error(absl::StatusCode::kNotFound, summary_start, "summary has no Statistics record");
  }
  if (statistics_.message_count > 0 && chunks_.empty()) {
    return Error(absl::StatusCode::kNotFound, summary_start,
                 "summary indexes no chunks (messages outside chunks need a scan)");
  }
  std::sort(chunks_.begin(), chunks_.end(),
            [](const auto& a, const auto& b) { return a.chunk_offset < b.chunk_offset; });
  report_.indexed = true;
  return absl::OkStatus();
}

absl::Status McapReader::ParseSchemaOrChannel(uint8_t opcode, std::string_view content,
                                              uint64_t offset) {
  mf::ByteCursor c(content);
  if (opcode == mf::kSchema) {
    McapSchema schema;
    schema.id = c.U16();
    schema.name = c.String();
    schema.encoding = c.String();
    schema.data = c.String();
    if (!c.ok()) return Error(absl::StatusCode::kDataLoss, offset, "malformed Schema record");
    if (schema.id != 0) schemas_[schema.id] = std::move(schema);
    return absl::OkStatus();
  }
  McapChannel channel;
  channel.id = c.U16();
  channel.schema_id = c.U16();
  channel.topic = c.String();
  channel.message_encoding = c.String();
  mf::ByteCursor map(c.String());
  while (c.ok() && map.ok() && map.remaining() > 0) {
    std::string key(map.String());
    channel.metadata[key] = map.String();
  }
  if (!c.ok() || !map.ok()) {
    return Error(absl::StatusCode::kDataLoss, offset, "malformed Channel record");
  }
  channels_[channel.id] = std::move(channel);
  return absl::OkStatus();
}

absl::Status McapReader::ParseSummaryRecord(uint8_t opcode, std::string_view content,
                                            uint64_t offset) {
  mf::ByteCursor c(content);
  if (opcode == mf::kSchema || opcode == mf::kChannel) {
    return ParseSchemaOrChannel(opcode, content, offset);
  } else if (opcode == mf::kChunkIndex) {
    McapChunkInfo chunk;
    chunk.start_time_ns = c.U64();
    chunk.end_time_ns = c.U64();
    chunk.chunk_offset = c.U64();
    chunk.chunk_length = c.U64();
    mf::ByteCursor offsets(c.String());
    while (c.ok() && offsets.ok() && offsets.remaining() > 0) {
      chunk.channel_ids.push_back(offsets.U16());
      offsets.U64();
    }
    if (!c.ok() || !offsets.ok() || chunk.chunk_offset > file_size_ ||
        chunk.chunk_length > file_size_ - chunk.chunk_offset) {
      return Error(absl::StatusCode::kDataLoss, offset, "malformed Chunk Index record");
    }
    chunks_.push_back(std::move(chunk));
  } else if (opcode == mf::kStatistics) {
    statistics_.message_count = c.U64();
    c.U16();  // schema_count
    c.U32();  // channel_count
    c.U32();  // attachment_count
    c.U32();  // metadata_count
    statistics_.chunk_count = c.U32();
    statistics_.start_time_ns = c.U64();
    statistics_.end_time_ns = c.U64();
    mf::ByteCursor counts(c.String());
    while (c.ok() && counts.ok() && counts.remaining() > 0) {
      const uint16_t channel_id = counts.U16();
      statistics_.channel_message_counts[channel_id] = counts.U64();
    }
    if (!c.ok() || !counts.ok()) {
      return Error(absl::StatusCode::kDataLoss, offset, "malformed Statistics record");
    }
  }
  return absl::OkStatus();  // Other records are not needed to read messages.
}

absl::StatusOr<std::string> McapReader::LoadChunkRecords(uint64_t chunk_offset,
                                                         std::string_view content) const {
  mf::ByteCursor c(content);
  c.U64();  // message_start_time
  c.U64();  // message_end_time
  const uint64_t uncompressed_size = c.U64();
  const uint32_t uncompressed_crc = c.U32();
  const std::string_view compression = c.String();
  const uint64_t records_size = c.U64();
  const std::string_view records = c.Bytes(records_size);
  if (!c.ok()) return Error(absl::StatusCode::kDataLoss, chunk_offset, "malformed Chunk record");
  if (uncompressed_size > options_.max_chunk_bytes) {
    return Error(absl::StatusCode::kDataLoss, chunk_offset,
                 absl::StrCat("chunk claims ", uncompressed_size,
                              " uncompressed bytes, more than the reader's limit of ",
                              options_.max_chunk_bytes));
  }
  std::string out;
  if (compression.empty()) {
    out.assign(records);
  } else if (compression == "zstd") {
    // Streamed, the buffer doubling only as the frames fill it: a header's
    // claim (the chunk's or the frame's) allocates nothing by itself. It may
    // reach uncompressed_size + 1, so that a frame producing more shows.
    std::unique_ptr<ZSTD_DCtx, size_t (*)(ZSTD_DCtx*)> dctx(ZSTD_createDCtx(), ZSTD_freeDCtx);
    if (dctx == nullptr) return absl::ResourceExhaustedError("no memory for a zstd context");
    const uint64_t most = uncompressed_size + 1;
    out.resize(std::min<uint64_t>(most, std::max<uint64_t>(kFirstChunkBuffer, records.size())));
    ZSTD_inBuffer in{records.data(), records.size(), 0};
    size_t produced = 0;
    while (true) {
      ZSTD_outBuffer o{out.data(), out.size(), produced};
      const size_t r = ZSTD_decompressStream(dctx.get(), &o, &in);
      if (ZSTD_isError(r)) {
        return Error(absl::StatusCode::kDataLoss, chunk_offset,
                     absl::StrCat("chunk does not decompress: ", ZSTD_getErrorName(r)));
      }
      produced = o.pos;
      if (produced > uncompressed_size) {
        return Error(absl::StatusCode::kDataLoss, chunk_offset,
                     absl::StrCat("chunk decompresses to more than the ", uncompressed_size,
                                  " bytes its header says"));
      }
      if (r == 0 && in.pos == in.size) break;  // The last frame ended with the input.
      if (produced == out.size()) {
        out.resize(std::min<uint64_t>(most, 2 * static_cast<uint64_t>(out.size())));
      } else if (in.pos == in.size) {
        return Error(absl::StatusCode::kDataLoss, chunk_offset,
                     "chunk's zstd frame ends before its data");
      }
    }
    out.resize(produced);
  } else {
    return Error(absl::StatusCode::kUnimplemented, chunk_offset,
                 absl::StrCat("unsupported chunk compression \"", std::string(compression), "\""));
  }
  if (out.size() != uncompressed_size) {
    return Error(
        absl::StatusCode::kDataLoss, chunk_offset,
        absl::StrCat("chunk holds ", out.size(), " bytes, header says ", uncompressed_size));
  }
  if (uncompressed_crc != 0 && mf::Crc32(out) != uncompressed_crc) {
    return Error(absl::StatusCode::kDataLoss, chunk_offset,
                 absl::StrFormat("chunk CRC mismatch (stored %08x, computed %08x)",
                                 uncompressed_crc, mf::Crc32(out)));
  }
  return out;
}

absl::Status McapReader::ParseChunk(uint64_t chunk_offset, std::string_view records,
                                    std::vector<McapMessage>* messages,
                                    std::vector<DefinitionRecord>* definitions) const {
  uint64_t pos = 0;
  while (pos < records.size()) {
    mf::ByteCursor c(records.substr(pos));
    const uint8_t opcode = c.U8();
    const uint64_t length = c.U64();
    if (!c.ok() || length > c.remaining()) {
      return Error(absl::StatusCode::kDataLoss, chunk_offset,
                   absl::StrCat("chunk record at offset ", pos, " of its records runs past them"));
    }
    const std::string_view content = records.substr(pos + mf::kRecordPrefixBytes, length);
    if (opcode == mf::kMessage) {
      mf::ByteCursor m(content);
      McapMessage message;
      message.channel_id = m.U16();
      message.sequence = m.U32();
      message.log_time_ns = m.U64();
      message.publish_time_ns = m.U64();
      if (!m.ok()) {
        return Error(absl::StatusCode::kDataLoss, chunk_offset,
                     absl::StrCat("malformed Message at offset ", pos, " of the chunk's records"));
      }
      message.data = m.Bytes(m.remaining());
      messages->push_back(std::move(message));
    } else if (definitions != nullptr && (opcode == mf::kSchema || opcode == mf::kChannel)) {
      definitions->push_back({opcode, content});
    }
    pos += mf::kRecordPrefixBytes + length;
  }
  std::stable_sort(messages->begin(), messages->end(),
                   [](const auto& a, const auto& b) { return a.log_time_ns < b.log_time_ns; });
  return absl::OkStatus();
}

absl::Status McapReader::Recover() {
  McapReadReport fresh;
  fresh.summary_problem = report_.summary_problem;
  report_ = std::move(fresh);
  schemas_.clear();
  channels_.clear();
  chunks_.clear();
  statistics_ = McapStatistics{};
  auto count = [this](const McapMessage& m) {
    statistics_.start_time_ns = statistics_.message_count == 0
                                    ? m.log_time_ns
                                    : std::min(statistics_.start_time_ns, m.log_time_ns);
    statistics_.end_time_ns = std::max(statistics_.end_time_ns, m.log_time_ns);
    ++statistics_.message_count;
    ++statistics_.channel_message_counts[m.channel_id];
  };
  auto stop = [this](uint64_t offset, std::string reason) {
    report_.complete = false;
    report_.stop_offset = offset;
    report_.stop_reason = std::move(reason);
  };
  uint64_t pos = mf::kMagic.size();
  while (true) {
    if (pos + mf::kRecordPrefixBytes > file_size_) {
      stop(pos, pos == file_size_ ? "file ends before the DataEnd record"
                                  : "file ends inside a record header");
      break;
    }
    ASSIGN_OR_RETURN(const std::string prefix_bytes, ReadAt(pos, mf::kRecordPrefixBytes));
    mf::ByteCursor prefix(prefix_bytes);
    const uint8_t opcode = prefix.U8();
    const uint64_t length = prefix.U64();
    const uint64_t available = file_size_ - pos - mf::kRecordPrefixBytes;
    if (length > available) {
      stop(pos, absl::StrCat("record (", OpcodeName(opcode), ") declares ", length,
                             " bytes but the file has ", available, " left"));
      break;
    }
    if (pos == mf::kMagic.size() && opcode != mf::kHeader) {
      stop(pos, absl::StrCat("first record is ", OpcodeName(opcode), ", not a Header"));
      break;
    }
    if (opcode == mf::kDataEnd || opcode == mf::kFooter) break;
    ASSIGN_OR_RETURN(const std::string content, ReadAt(pos + mf::kRecordPrefixBytes, length));
    if (opcode == mf::kSchema || opcode == mf::kChannel) {
      if (absl::Status s = ParseSchemaOrChannel(opcode, content, pos); !s.ok()) {
        stop(pos, std::string(s.message()));
        break;
      }
    } else if (opcode == mf::kMessage) {
      std::vector<McapMessage> one;
      std::string record;
      mf::PutRecord(&record, opcode, content);
      if (absl::Status s = ParseChunk(pos, record, &one, nullptr); !s.ok()) {
        stop(pos, std::string(s.message()));
        break;
      }
      count(one.front());
      loose_messages_.emplace_back(pos, std::move(one.front()));
    } else if (opcode == mf::kChunk) {
      std::vector<McapMessage> messages;
      std::vector<DefinitionRecord> definitions;
      absl::StatusOr<std::string> records = LoadChunkRecords(pos, content);
      absl::Status parsed = records.status();
      if (parsed.ok()) parsed = ParseChunk(pos, *records, &messages, &definitions);
      for (const auto& [def_opcode, def_content] : definitions) {
        if (parsed.ok()) parsed = ParseSchemaOrChannel(def_opcode, def_content, pos);
      }
      if (!parsed.ok()) {
        report_.complete = false;
        report_.skipped_chunks.push_back(std::string(parsed.message()));
      } else {
        McapChunkInfo chunk{pos, mf::kRecordPrefixBytes + length, 0, 0, {}};
        for (const McapMessage& m : messages) {
          count(m);
          if (std::find(chunk.channel_ids.begin(), chunk.channel_ids.end(), m.channel_id) ==
              chunk.channel_ids.end()) {
            chunk.channel_ids.push_back(m.channel_id);
          }
        }
        if (!messages.empty()) {
          chunk.start_time_ns = messages.front().log_time_ns;
          chunk.end_time_ns = messages.back().log_time_ns;
        }
        chunks_.push_back(std::move(chunk));
        ++statistics_.chunk_count;
      }
    }
    pos += mf::kRecordPrefixBytes + length;
  }
  return absl::OkStatus();
}

const McapChannel* McapReader::FindChannel(std::string_view topic) const {
  for (const auto& [id, channel] : channels_) {
    if (channel.topic == topic) return &channel;
  }
  return nullptr;
}

absl::Status McapReader::ForEachInChunk(const McapChunkInfo& chunk,
                                        const McapMessageCallback& callback,
                                        std::optional<uint16_t> channel_id) const {
  if (channel_id && std::find(chunk.channel_ids.begin(), chunk.channel_ids.end(), *channel_id) ==
                        chunk.channel_ids.end()) {
    return absl::OkStatus();
  }
  ASSIGN_OR_RETURN(const std::string record, ReadAt(chunk.chunk_offset, chunk.chunk_length));
  mf::ByteCursor prefix(record);
  if (prefix.U8() != mf::kChunk || prefix.U64() != chunk.chunk_length - mf::kRecordPrefixBytes) {
    return Error(absl::StatusCode::kDataLoss, chunk.chunk_offset,
                 "chunk index does not point at a Chunk record");
  }
  ASSIGN_OR_RETURN(const std::string records,
                   LoadChunkRecords(chunk.chunk_offset,
                                    std::string_view(record).substr(mf::kRecordPrefixBytes)));
  std::vector<McapMessage> messages;
  RETURN_IF_ERROR(ParseChunk(chunk.chunk_offset, records, &messages, nullptr));
  for (const McapMessage& message : messages) {
    if (channel_id && message.channel_id != *channel_id) continue;
    const auto channel = channels_.find(message.channel_id);
    if (channel == channels_.end()) {
      return Error(absl::StatusCode::kDataLoss, chunk.chunk_offset,
                   absl::StrCat("message on unknown channel ", message.channel_id));
    }
    RETURN_IF_ERROR(callback(channel->second, message));
  }
  return absl::OkStatus();
}

absl::Status McapReader::ForEachMessage(const McapMessageCallback& callback,
                                        std::optional<std::string_view> topic) const {
  std::optional<uint16_t> channel_id;
  if (topic) {
    const McapChannel* channel = FindChannel(*topic);
    if (channel == nullptr) return absl::OkStatus();
    channel_id = channel->id;
  }
  size_t next_loose = 0;
  auto emit_loose_before = [&](uint64_t offset) -> absl::Status {
    for (; next_loose < loose_messages_.size() && loose_messages_[next_loose].first < offset;
         ++next_loose) {
      const McapMessage& m = loose_messages_[next_loose].second;
      if (channel_id && m.channel_id != *channel_id) continue;
      const auto channel = channels_.find(m.channel_id);
      if (channel == channels_.end()) {
        return Error(absl::StatusCode::kDataLoss, loose_messages_[next_loose].first,
                     absl::StrCat("message on unknown channel ", m.channel_id));
      }
      RETURN_IF_ERROR(callback(channel->second, m));
    }
    return absl::OkStatus();
  };
  for (const McapChunkInfo& chunk : chunks_) {
    RETURN_IF_ERROR(emit_loose_before(chunk.chunk_offset));
    RETURN_IF_ERROR(ForEachInChunk(chunk, callback, channel_id));
  }
  return emit_loose_before(file_size_);
}

absl::StatusOr<std::vector<McapMessage>> McapReader::ReadMessages(
    std::optional<std::string_view> topic) const {
  std::vector<McapMessage> messages;
  RETURN_IF_ERROR(ForEachMessage(
      [&messages](const McapChannel&, const McapMessage& m) {
        messages.push_back(m);
        return absl::OkStatus();
      },
      topic));
  return messages;
}

}  // namespace reenact
