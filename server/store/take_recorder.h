// One take being recorded: a queue of validated frame sets and a writer
// thread that stores them. The thread takes everything queued at once, writes
// it (each set's frames, then its FrameSetRecord; a chunk ends only between
// sets), ends the chunk and fsyncs once, then reports the highest sequence of
// the batch as durable. While the disk is busy sets pile up and the next
// batch is bigger, so the fsync cost is shared (coalescing).
#pragma once

#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <variant>

#include "absl/status/status.h"
#include "common/io/take.h"
#include "reenact/v1/frame.pb.h"
#include "server/store/catalog.h"
#include "server/store/frame_set_validation.h"

namespace reenact::server {

// Longest SensorLost reason a take stores, bytes.
inline constexpr size_t kMaxSensorLostReasonBytes = 1024;

// How a recording ended.
struct RecordingResult {
  // The take's final row: state COMPLETE or INTERRUPTED, counts, size.
  TakeRow row;
  // OK when the take was completed as asked; otherwise why it was
  // interrupted (the reason given to the first Finish, or the write error).
  absl::Status reason;
};

// Told what happens to a recording. Every call comes from the recorder's
// writer thread, in order; OnFinished is the last call.
class RecorderObserver {
 public:
  virtual ~RecorderObserver() = default;
  // Every frame set up to `durable_sequence` is written and fsync'ed.
  virtual void OnDurable(uint64_t durable_sequence) = 0;
  // The take file is finished and the recording over.
  virtual void OnFinished(const RecordingResult& result) = 0;
};

// Figures of a recording, for logs and benchmarks.
struct RecorderStats {
  int64_t batches = 0;         // fsync'ed batches.
  int64_t frame_sets = 0;      // Frame sets written.
  int64_t bytes = 0;           // File bytes written.
  int64_t write_ns = 0;        // Time spent serializing and writing (all batches).
  int64_t sync_ns = 0;         // Time spent in fsync (all batches).
  int64_t max_sync_ns = 0;     // Longest single fsync.
  int64_t max_batch_sets = 0;  // Most frame sets in one batch.
};

class TakeRecorder : public std::enable_shared_from_this<TakeRecorder> {
 public:
  struct Options {
    // A chunk ends at the first frame-set boundary past this many
    // uncompressed bytes, and after every batch.
    uint64_t chunk_target_bytes = uint64_t{8} << 20;
  };
  // Called on the writer thread when the recording ended, before the
  // observer's OnFinished; may adjust the result (the store records it in
  // the catalog).
  using FinishHook = std::function<void(RecordingResult& result)>;

  // Records into `writer` (a file holding `row.take.durable_sequence()` frame
  // sets). `absolute_path` is the writer's file. Start() launches the thread.
  TakeRecorder(std::unique_ptr<TakeWriter> writer, std::string absolute_path, TakeRow row,
               const Options& options, RecorderObserver* observer, FinishHook hook);
  // Joins the writer thread (Finish must have been asked for).
  ~TakeRecorder();
  TakeRecorder(const TakeRecorder&) = delete;
  TakeRecorder& operator=(const TakeRecorder&) = delete;

  void Start();

  // InvalidArgument unless `sequence` is the last accepted + 1, naming both
  // and whether it is a gap, a duplicate or a step back.
  absl::Status CheckNextSequence(uint64_t sequence) const;
  // Queues a validated frame set. CheckNextSequence's error; FailedPrecondition
  // (or the write error) once the recording is finishing.
  absl::Status Enqueue(v1::FrameSet set);
  // Queues a SensorLost record (sensor known, stamp >= 0: InvalidArgument).
  absl::Status EnqueueSensorLost(v1::SensorLostRecord record);

  // Ends the recording once everything queued is durable: `complete` makes
  // the take COMPLETE (when `last_sequence` is the last accepted sequence),
  // otherwise INTERRUPTED with `reason`. Only the first call counts.
  void Finish(bool complete, uint64_t last_sequence, absl::Status reason);

  // Serialized bytes waiting for the writer thread.
  uint64_t queued_bytes() const;
  // Highest sequence accepted so far (queued or durable).
  uint64_t last_sequence() const;
  // The take's row with what is durable now (state RECORDING).
  TakeRow Snapshot() const;
  RecorderStats stats() const;
  const std::string& take_id() const { return take_id_; }
  // The take's sensors (fixed for the recording).
  const SensorMap& sensors() const { return sensors_; }

 private:
  using Item = std::variant<v1::FrameSet, v1::SensorLostRecord>;
  struct FinishRequest {
    bool complete = false;
    uint64_t last_sequence = 0;
    absl::Status reason;
  };

  absl::Status CheckNextSequenceLocked(uint64_t sequence) const;
  void Run();
  // Writes `batch`, ends the chunk and fsyncs; updates `row` with it.
  absl::Status WriteBatch(std::deque<Item>& batch, TakeRow& row);
  absl::Status WriteFrameSet(const v1::FrameSet& set);
  RecordingResult FinishFile(const FinishRequest& request);

  std::unique_ptr<TakeWriter> writer_;  // Writer thread only.
  const std::string path_;
  const std::string take_id_;
  const SensorMap sensors_;
  const Options options_;
  RecorderObserver* const observer_;
  const FinishHook hook_;
  std::thread thread_;

  mutable std::mutex mu_;
  std::condition_variable wake_;
  std::deque<Item> queue_;
  uint64_t queued_bytes_ = 0;
  uint64_t last_sequence_ = 0;
  bool finishing_ = false;
  FinishRequest finish_;
  absl::Status write_error_;
  TakeRow row_;  // Durable state.
  RecorderStats stats_;
};

}  // namespace reenact::server
