// The disk spool of reenactd: every FrameSet of a take is appended here before
// it is sent, and stays until the server acknowledges it as durable, so that
// nothing is lost while the server is away or the daemon restarts.
//
// Layout: one folder per take holding segment files "segment-<first
// sequence, 20 digits>.spool" and small metadata files. A segment is a run of
// records, each
//   u32 magic "RSP1" | u32 payload bytes | u64 sequence | u32 CRC-32 of the
//   sequence and payload | payload (a serialized FrameSet)
// in little-endian order. A new segment starts when the current one would
// grow past `segment_bytes`; a segment is deleted once every record in it is
// acknowledged. Opening a folder scans every segment: a record whose header
// runs past the file, whose CRC fails or whose sequence breaks the run (the
// torn tail of an unclean stop) is cut off, together with anything after it,
// and recovery() says how much was cut.
//
// The spool is bounded by `max_bytes` on disk: an Append that does not fit is
// refused (ResourceExhausted), counted, and nothing already spooled is
// touched. Thread-safe.
#pragma once

#include <cstdint>
#include <deque>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "reenact/v1/frame.pb.h"

namespace reenact::ingest {

struct SpoolOptions {
  // Folder of this take's spool; created when missing.
  std::string dir;
  // Bound on the bytes of all segments on disk.
  int64_t max_bytes = int64_t{1} << 30;
  // Size at which a segment is closed and the next one begun (capped to a
  // quarter of max_bytes so that acknowledged space comes back in steps).
  int64_t segment_bytes = int64_t{64} << 20;
  // Sets kept in memory after Append until first read, bytes (saves reading
  // them back from disk on the send path; 0 disables).
  int64_t cache_bytes = int64_t{32} << 20;
  // fdatasync after every append (survives power loss, costs a disk flush per
  // set). Without it, appended sets survive a crash of the daemon.
  bool sync_each_append = false;

  // InvalidArgument naming the first bad field.
  absl::Status Validate() const;
};

// What opening an existing folder found.
struct SpoolRecovery {
  int64_t segments = 0;   // Segment files found.
  int64_t records = 0;    // Intact records kept.
  int64_t cut_bytes = 0;  // Bytes cut off (torn or corrupt tails).
  std::string detail;     // Where and why, empty when nothing was cut.
};

class Spool {
 public:
  // Opens (creating when needed) the spool in options.dir and scans what is
  // there. Unavailable when the folder cannot be created or read.
  static absl::StatusOr<std::unique_ptr<Spool>> Open(const SpoolOptions& options);
  ~Spool();
  Spool(const Spool&) = delete;
  Spool& operator=(const Spool&) = delete;

  // Appends `set`. Its sequence must follow the last appended one (any
  // sequence above acked_sequence() when the spool holds nothing):
  // InvalidArgument otherwise. ResourceExhausted when it would exceed
  // max_bytes (the set is refused and counted); Unavailable when the write
  // fails (the segment is left as it was). `set` is moved from only on
  // success (into the cache). `record_bytes` receives the size written.
  absl::Status Append(v1::FrameSet&& set, int64_t* record_bytes = nullptr);

  // The set with `sequence`, from memory when it is still cached (then the
  // cached copy is handed over) or else from disk. NotFound when it is not
  // held (acknowledged, or never appended); DataLoss when the record on disk
  // is damaged.
  absl::StatusOr<v1::FrameSet> Take(uint64_t sequence);

  // Everything up to and including `durable_sequence` is acknowledged:
  // segments whose records are all acknowledged are deleted.
  absl::Status Ack(uint64_t durable_sequence);

  // Lowest held sequence (0: none held), highest appended sequence (0: none
  // since the folder was created), highest acknowledged sequence.
  uint64_t first_sequence() const;
  uint64_t last_sequence() const;
  uint64_t acked_sequence() const;
  // Sets held (appended, not acknowledged) and the bytes of all segments.
  int64_t frame_sets() const;
  int64_t bytes() const;
  // Appends refused because the spool was full.
  int64_t refused() const;
  const SpoolRecovery& recovery() const { return recovery_; }
  const std::string& dir() const { return options_.dir; }

  // Small files beside the segments (take description, close request),
  // written atomically. ReadMeta: nullopt when absent.
  absl::Status WriteMeta(const std::string& name, const std::string& bytes);
  absl::StatusOr<std::optional<std::string>> ReadMeta(const std::string& name) const;

  // Deletes the folder and everything in it (after the take is closed).
  absl::Status RemoveAll();

 private:
  struct Segment {
    std::string path;
    int fd = -1;
    uint64_t first_sequence = 0;
    uint64_t last_sequence = 0;
    int64_t bytes = 0;
  };
  struct RecordRef {
    uint64_t sequence = 0;
    uint64_t segment_first_sequence = 0;  // Key of its segment.
    int64_t offset = 0;                   // Of the record header.
    int64_t bytes = 0;                    // Header and payload.
  };

  explicit Spool(const SpoolOptions& options) : options_(options) {}
  absl::Status Scan();
  absl::Status ScanSegment(Segment& segment, bool* damaged);
  absl::StatusOr<Segment*> SegmentForAppend(int64_t record_bytes);
  void DropCachedLocked(uint64_t up_to_sequence);

  SpoolOptions options_;
  mutable std::mutex mutex_;
  std::map<uint64_t, Segment> segments_;  // By first sequence.
  std::deque<RecordRef> records_;         // Held records, by sequence.
  std::map<uint64_t, v1::FrameSet> cache_;
  int64_t cache_bytes_ = 0;
  uint64_t last_sequence_ = 0;
  uint64_t acked_sequence_ = 0;
  int64_t bytes_ = 0;
  int64_t refused_ = 0;
  SpoolRecovery recovery_;
};

}  // namespace reenact::ingest
