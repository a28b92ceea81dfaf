#include "common/ingest/spool.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>
#include <zlib.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <vector>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "common/base/files.h"
#include "common/base/status_macros.h"

namespace reenact::ingest {

namespace {

constexpr uint32_t kRecordMagic = 0x31505352;  // "RSP1" little-endian.
constexpr int64_t kHeaderBytes = 4 + 4 + 8 + 4;
// A payload claim above this is damage, not a record.
constexpr uint32_t kMaxPayloadBytes = uint32_t{1} << 30;
constexpr std::string_view kSegmentPrefix = "segment-";
constexpr std::string_view kSegmentSuffix = ".spool";

void PutU32(char* out, uint32_t v) {
  for (int i = 0; i < 4; ++i) out[i] = static_cast<char>((v >> (8 * i)) & 0xff);
}
void PutU64(char* out, uint64_t v) {
  for (int i = 0; i < 8; ++i) out[i] = static_cast<char>((v >> (8 * i)) & 0xff);
}
uint32_t GetU32(const char* in) {
  uint32_t v = 0;
  for (int i = 0; i < 4; ++i) v |= static_cast<uint32_t>(static_cast<uint8_t>(in[i])) << (8 * i);
  return v;
}
uint64_t GetU64(const char* in) {
  uint64_t v = 0;
  for (int i = 0; i < 8; ++i) v |= static_cast<uint64_t>(static_cast<uint8_t>(in[i])) << (8 * i);
  return v;
}

// CRC-32 (zlib's polynomial) of the sequence bytes followed by the payload.
uint32_t RecordCrc(const char* sequence_bytes, const char* payload, size_t payload_bytes) {
  uLong crc = crc32(0L, Z_NULL, 0);
  crc = crc32(crc, reinterpret_cast<const Bytef*>(sequence_bytes), 8);
  crc = crc32_z(crc, reinterpret_cast<const Bytef*>(payload), payload_bytes);
  return static_cast<uint32_t>(crc);
}

std::string SegmentName(uint64_t first_sequence) {
  return absl::StrFormat("%s%020u%s", std::string(kSegmentPrefix), first_sequence,
                         std::string(kSegmentSuffix));
}

absl::Status ErrnoStatus(const std::string& what, const std::string& path) {
  return absl::UnavailableError(
      absl::StrCat("spool: ", what, " ", path, ": ", std::strerror(errno)));
}

// Reads exactly `size` bytes at `offset`; false at end of file.
absl::StatusOr<bool> PreadAll(int fd, char* out, size_t size, int64_t offset,
                              const std::string& path) {
  size_t done = 0;
  while (done < size) {
    const ssize_t n = ::pread(fd, out + done, size - done, offset + static_cast<int64_t>(done));
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) return ErrnoStatus("cannot read", path);
    if (n == 0) return false;
    done += static_cast<size_t>(n);
  }
  return true;
}

absl::Status WriteAll(int fd, const char* data, size_t size, const std::string& path) {
  size_t done = 0;
  while (done < size) {
    const ssize_t n = ::write(fd, data + done, size - done);
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) return ErrnoStatus("cannot write", path);
    done += static_cast<size_t>(n);
  }
  return absl::OkStatus();
}

}  // namespace

absl::Status SpoolOptions::Validate() const {
  if (dir.empty()) return absl::InvalidArgumentError("SpoolOptions.dir is empty");
  if (max_bytes < (int64_t{1} << 20)) {
    return absl::InvalidArgumentError("SpoolOptions.max_bytes below 1 MiB");
  }
  if (segment_bytes < (int64_t{64} << 10)) {
    return absl::InvalidArgumentError("SpoolOptions.segment_bytes below 64 KiB");
  }
  if (cache_bytes < 0) return absl::InvalidArgumentError("SpoolOptions.cache_bytes < 0");
  return absl::OkStatus();
}

absl::StatusOr<std::unique_ptr<Spool>> Spool::Open(const SpoolOptions& options) {
  RETURN_IF_ERROR(options.Validate());
  std::unique_ptr<Spool> spool(new Spool(options));
  spool->options_.segment_bytes = std::min(options.segment_bytes, options.max_bytes / 4);
  if (absl::Status s = CreateDirectories(options.dir); !s.ok()) {
    return absl::UnavailableError(absl::StrCat("spool: ", s.message()));
  }
  RETURN_IF_ERROR(spool->Scan());
  return spool;
}

Spool::~Spool() {
  for (auto& [first, segment] : segments_) {
    if (segment.fd >= 0) ::close(segment.fd);
  }
}

absl::Status Spool::Scan() {
  std::vector<std::pair<uint64_t, std::string>> found;
  std::error_code ec;
  for (const auto& entry : std::filesystem::directory_iterator(options_.dir, ec)) {
    const std::string name = entry.path().filename().string();
    if (name.size() != kSegmentPrefix.size() + 20 + kSegmentSuffix.size() ||
        name.rfind(kSegmentPrefix, 0) != 0 || !name.ends_with(kSegmentSuffix)) {
      continue;
    }
    uint64_t first = 0;
    bool digits = true;
    for (char c : name.substr(kSegmentPrefix.size(), 20)) {
      if (c < '0' || c > '9') digits = false;
      first = first * 10 + static_cast<uint64_t>(c - '0');
    }
    if (digits) found.emplace_back(first, entry.path().string());
  }
  if (ec)
    return absl::UnavailableError(
        absl::StrCat("spool: cannot list ", options_.dir, ": ", ec.message()));
  std::sort(found.begin(), found.end());
  recovery_.segments = static_cast<int64_t>(found.size());
  bool damaged = false;
  for (const auto& [first, path] : found) {
    if (damaged) {  // Everything after a cut would leave a gap: cut it too.
      recovery_.cut_bytes += static_cast<int64_t>(std::filesystem::file_size(path, ec));
      std::filesystem::remove(path, ec);
      absl::StrAppend(&recovery_.detail, "; removed ", path, " after the cut");
      continue;
    }
    Segment segment;
    segment.path = path;
    segment.first_sequence = first;
    segment.fd = ::open(path.c_str(), O_RDWR | O_APPEND | O_CLOEXEC);
    if (segment.fd < 0) return ErrnoStatus("cannot open", path);
    RETURN_IF_ERROR(ScanSegment(segment, &damaged));
    if (segment.last_sequence == 0) {  // Nothing intact in it.
      ::close(segment.fd);
      std::filesystem::remove(path, ec);
      continue;
    }
    bytes_ += segment.bytes;
    segments_.emplace(first, segment);
  }
  if (!records_.empty()) {
    last_sequence_ = records_.back().sequence;
    acked_sequence_ = records_.front().sequence - 1;
  }
  return absl::OkStatus();
}

absl::Status Spool::ScanSegment(Segment& segment, bool* damaged) {
  struct stat st {};
  if (::fstat(segment.fd, &st) != 0) return ErrnoStatus("cannot stat", segment.path);
  const int64_t file_bytes = st.st_size;
  int64_t offset = 0;
  std::string payload;
  std::string why;
  while (offset < file_bytes) {
    char header[kHeaderBytes];
    if (file_bytes - offset < kHeaderBytes) {
      why = "record header runs past the end of the file";
      break;
    }
    ASSIGN_OR_RETURN(bool full, PreadAll(segment.fd, header, kHeaderBytes, offset, segment.path));
    const uint32_t magic = GetU32(header);
    const uint32_t length = GetU32(header + 4);
    const uint64_t sequence = GetU64(header + 8);
    const uint32_t crc = GetU32(header + 16);
    if (!full || magic != kRecordMagic || length > kMaxPayloadBytes) {
      why = "not a record header";
      break;
    }
    if (file_bytes - offset - kHeaderBytes < static_cast<int64_t>(length)) {
      why = "record payload runs past the end of the file";
      break;
    }
    payload.resize(length);
    ASSIGN_OR_RETURN(
        full, PreadAll(segment.fd, payload.data(), length, offset + kHeaderBytes, segment.path));
    if (!full || RecordCrc(header + 8, payload.data(), length) != crc) {
      why = "CRC mismatch";
      break;
    }
    const uint64_t expected =
        records_.empty() ? segment.first_sequence : records_.back().sequence + 1;
    if (sequence != expected) {
      why = absl::StrCat("sequence ", sequence, " where ", expected, " was expected");
      break;
    }
    const int64_t record_bytes = kHeaderBytes + length;
    records_.push_back({sequence, segment.first_sequence, offset, record_bytes});
    segment.last_sequence = sequence;
    offset += record_bytes;
    ++recovery_.records;
  }
  segment.bytes = offset;
  if (offset < file_bytes) {
    *damaged = true;
    recovery_.cut_bytes += file_bytes - offset;
    absl::StrAppend(&recovery_.detail, recovery_.detail.empty() ? "" : "; ", segment.path, ": cut ",
                    file_bytes - offset, " bytes at offset ", offset, " (", why, ")");
    if (::ftruncate(segment.fd, offset) != 0) return ErrnoStatus("cannot truncate", segment.path);
  }
  return absl::OkStatus();
}

absl::StatusOr<Spool::Segment*> Spool::SegmentForAppend(int64_t record_bytes) {
  if (!segments_.empty()) {
    Segment& last = segments_.rbegin()->second;
    if (last.bytes == 0 || last.bytes + record_bytes <= options_.segment_bytes) return &last;
  }
  Segment segment;
  segment.first_sequence = last_sequence_ + 1;
  segment.path =
      (std::filesystem::path(options_.dir) / SegmentName(segment.first_sequence)).string();
  segment.fd =
      ::open(segment.path.c_str(), O_RDWR | O_APPEND | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (segment.fd < 0) return ErrnoStatus("cannot create", segment.path);
  // The segment's name must survive a power loss with the frames in it.
  if (absl::Status synced = SyncDirectory(options_.dir); !synced.ok()) {
    ::close(segment.fd);
    return synced;
  }
  auto [it, inserted] = segments_.emplace(segment.first_sequence, segment);
  return &it->second;
}

absl::Status Spool::Append(v1::FrameSet&& set, int64_t* record_bytes) {
  const uint64_t sequence = set.sequence();
  std::string record(kHeaderBytes, '\0');
  if (!set.AppendToString(&record)) {
    return absl::InvalidArgumentError(
        absl::StrCat("spool: frame set ", sequence, " does not serialize"));
  }
  const size_t payload_bytes = record.size() - kHeaderBytes;
  if (payload_bytes > kMaxPayloadBytes) {
    return absl::InvalidArgumentError(
        absl::StrCat("spool: frame set ", sequence, " is ", payload_bytes, " bytes"));
  }
  PutU32(record.data(), kRecordMagic);
  PutU32(record.data() + 4, static_cast<uint32_t>(payload_bytes));
  PutU64(record.data() + 8, sequence);
  PutU32(record.data() + 16,
         RecordCrc(record.data() + 8, record.data() + kHeaderBytes, payload_bytes));
  const int64_t size = static_cast<int64_t>(record.size());

  std::lock_guard<std::mutex> lock(mutex_);
  const bool holds_records = !records_.empty();
  if (holds_records ? sequence != last_sequence_ + 1
                    : sequence <= acked_sequence_ || sequence == 0) {
    return absl::InvalidArgumentError(
        absl::StrCat("spool: frame set ", sequence, " does not follow ",
                     holds_records ? last_sequence_ : acked_sequence_));
  }
  if (bytes_ + size > options_.max_bytes) {
    ++refused_;
    return absl::ResourceExhaustedError(absl::StrCat(
        "spool ", options_.dir, " is full (", bytes_, " of ", options_.max_bytes,
        " bytes held by unacknowledged frame sets): frame set ", sequence, " refused"));
  }
  if (!holds_records) last_sequence_ = sequence - 1;
  ASSIGN_OR_RETURN(Segment * segment, SegmentForAppend(size));
  if (absl::Status s = WriteAll(segment->fd, record.data(), record.size(), segment->path);
      !s.ok()) {
    // Leave the segment as it was: no torn record behind.
    if (::ftruncate(segment->fd, segment->bytes) != 0) {
      return absl::DataLossError(
          absl::StrCat(s.message(), "; and the partial record could not be cut"));
    }
    return s;
  }
  if (options_.sync_each_append && ::fdatasync(segment->fd) != 0) {
    return ErrnoStatus("cannot sync", segment->path);
  }
  records_.push_back({sequence, segment->first_sequence, segment->bytes, size});
  segment->bytes += size;
  segment->last_sequence = sequence;
  bytes_ += size;
  last_sequence_ = sequence;
  if (record_bytes != nullptr) *record_bytes = size;
  if (options_.cache_bytes > 0 && cache_bytes_ + size <= options_.cache_bytes) {
    cache_bytes_ += size;
    cache_.emplace(sequence, std::move(set));
  }
  return absl::OkStatus();
}

absl::StatusOr<v1::FrameSet> Spool::Take(uint64_t sequence) {
  std::unique_lock<std::mutex> lock(mutex_);
  if (records_.empty() || sequence < records_.front().sequence ||
      sequence > records_.back().sequence) {
    return absl::NotFoundError(absl::StrCat("spool: frame set ", sequence, " is not held"));
  }
  const RecordRef ref = records_[sequence - records_.front().sequence];
  if (auto cached = cache_.find(sequence); cached != cache_.end()) {
    v1::FrameSet set = std::move(cached->second);
    cache_bytes_ -= ref.bytes;
    cache_.erase(cached);
    return set;
  }
  const Segment& segment = segments_.at(ref.segment_first_sequence);
  const std::string path = segment.path;
  std::string record(static_cast<size_t>(ref.bytes), '\0');
  // Read under the lock: Ack may delete and close the segment otherwise.
  ASSIGN_OR_RETURN(const bool full,
                   PreadAll(segment.fd, record.data(), record.size(), ref.offset, path));
  lock.unlock();
  const char* header = record.data();
  const uint32_t length = GetU32(header + 4);
  if (!full || GetU32(header) != kRecordMagic || GetU64(header + 8) != sequence ||
      kHeaderBytes + static_cast<int64_t>(length) != ref.bytes ||
      RecordCrc(header + 8, header + kHeaderBytes, length) != GetU32(header + 16)) {
    return absl::DataLossError(absl::StrCat("spool: record of frame set ", sequence, " in ", path,
                                            " at offset ", ref.offset, " is damaged"));
  }
  v1::FrameSet set;
  if (!set.ParseFromArray(header + kHeaderBytes, static_cast<int>(length))) {
    return absl::DataLossError(
        absl::StrCat("spool: frame set ", sequence, " in ", path, " does not parse"));
  }
  return set;
}

void Spool::DropCachedLocked(uint64_t up_to_sequence) {
  while (!cache_.empty() && cache_.begin()->first <= up_to_sequence) {
    const uint64_t sequence = cache_.begin()->first;
    cache_bytes_ -= records_[sequence - records_.front().sequence].bytes;
    cache_.erase(cache_.begin());
  }
}

absl::Status Spool::Ack(uint64_t durable_sequence) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (durable_sequence <= acked_sequence_) return absl::OkStatus();
  if (!records_.empty()) DropCachedLocked(durable_sequence);
  acked_sequence_ = durable_sequence;
  while (!records_.empty() && records_.front().sequence <= durable_sequence) records_.pop_front();
  // Delete fully acknowledged segments.
  for (auto it = segments_.begin(); it != segments_.end();) {
    Segment& segment = it->second;
    if (segment.last_sequence == 0 || segment.last_sequence > durable_sequence) break;
    std::error_code ec;
    std::filesystem::remove(segment.path, ec);
    if (ec) {
      return absl::UnavailableError(
          absl::StrCat("spool: cannot delete ", segment.path, ": ", ec.message()));
    }
    ::close(segment.fd);
    bytes_ -= segment.bytes;
    it = segments_.erase(it);
  }
  return absl::OkStatus();
}

uint64_t Spool::first_sequence() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return records_.empty() ? 0 : records_.front().sequence;
}
uint64_t Spool::last_sequence() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return last_sequence_;
}
uint64_t Spool::acked_sequence() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return acked_sequence_;
}
int64_t Spool::frame_sets() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return static_cast<int64_t>(records_.size());
}
int64_t Spool::bytes() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return bytes_;
}
int64_t Spool::refused() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return refused_;
}

absl::Status Spool::WriteMeta(const std::string& name, const std::string& bytes) {
  return WriteFileAtomically((std::filesystem::path(options_.dir) / name).string(), bytes);
}

absl::StatusOr<std::optional<std::string>> Spool::ReadMeta(const std::string& name) const {
  absl::StatusOr<std::string> bytes =
      ReadFileToString((std::filesystem::path(options_.dir) / name).string());
  if (absl::IsNotFound(bytes.status())) return std::optional<std::string>();
  if (!bytes.ok()) return bytes.status();
  return std::optional<std::string>(std::move(*bytes));
}

absl::Status Spool::RemoveAll() {
  std::lock_guard<std::mutex> lock(mutex_);
  for (auto& [first, segment] : segments_) {
    if (segment.fd >= 0) ::close(segment.fd);
  }
  segments_.clear();
  records_.clear();
  cache_.clear();
  cache_bytes_ = 0;
  bytes_ = 0;
  std::error_code ec;
  std::filesystem::remove_all(options_.dir, ec);
  if (ec) {
    return absl::UnavailableError(
        absl::StrCat("spool: cannot remove ", options_.dir, ": ", ec.message()));
  }
  return absl::OkStatus();
}

}  // namespace reenact::ingest
