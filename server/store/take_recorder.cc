#include "server/store/take_recorder.h"

#include <algorithm>
#include <utility>

#include "absl/strings/str_cat.h"
#include "common/base/files.h"
#include "common/base/status_macros.h"
#include "common/base/time.h"
#include "common/log/log.h"
#include "common/metrics/metrics.h"
#include "server/store/take_file.h"

namespace reenact::server {
namespace {

SensorMap SensorsOf(const TakeWriter& writer) { return writer.sensors(); }

v1::TakeSensor* FindSensor(TakeRow& row, const std::string& id) {
  for (v1::TakeSensor& s : *row.take.mutable_sensors()) {
    if (s.sensor_id() == id) return &s;
  }
  return nullptr;
}

}  // namespace

TakeRecorder::TakeRecorder(std::unique_ptr<TakeWriter> writer, std::string absolute_path,
                           TakeRow row, const Options& options, RecorderObserver* observer,
                           FinishHook hook)
    : writer_(std::move(writer)),
      path_(std::move(absolute_path)),
      take_id_(row.take.take_id()),
      sensors_(SensorsOf(*writer_)),
      options_(options),
      observer_(observer),
      hook_(std::move(hook)),
      last_sequence_(row.take.durable_sequence()),
      row_(std::move(row)) {}

TakeRecorder::~TakeRecorder() {
  if (!thread_.joinable()) return;
  // The last owner may be the writer thread itself, right after OnFinished.
  if (thread_.get_id() == std::this_thread::get_id()) {
    thread_.detach();
  } else {
    thread_.join();
  }
}

void TakeRecorder::Start() {
  thread_ = std::thread([self = shared_from_this()] { self->Run(); });
}

absl::Status TakeRecorder::CheckNextSequence(uint64_t sequence) const {
  std::lock_guard<std::mutex> lock(mu_);
  return CheckNextSequenceLocked(sequence);
}

absl::Status TakeRecorder::CheckNextSequenceLocked(uint64_t sequence) const {
  const uint64_t expected = last_sequence_ + 1;
  if (sequence == expected) return absl::OkStatus();
  const char* kind = sequence > expected          ? "a gap"
                     : sequence == last_sequence_ ? "a duplicate"
                                                  : "a step back";
  return absl::InvalidArgumentError(absl::StrCat("take ", take_id_, ": FrameSet sequence ",
                                                 sequence, " is ", kind, ": expected ", expected,
                                                 " (the take holds 1..", last_sequence_, ")"));
}

absl::Status TakeRecorder::Enqueue(v1::FrameSet set) {
  const uint64_t bytes = set.ByteSizeLong();
  std::lock_guard<std::mutex> lock(mu_);
  if (!write_error_.ok()) return write_error_;
  if (finishing_) {
    return absl::FailedPreconditionError(
        absl::StrCat("take ", take_id_, " is being finished; no more frame sets"));
  }
  RETURN_IF_ERROR(CheckNextSequenceLocked(set.sequence()));
  last_sequence_ = set.sequence();
  queued_bytes_ += bytes;
  queue_.emplace_back(std::move(set));
  wake_.notify_one();
  return absl::OkStatus();
}

absl::Status TakeRecorder::EnqueueSensorLost(v1::SensorLostRecord record) {
  if (!sensors_.contains(record.sensor_id()) || record.stamp_ns() < 0) {
    return absl::InvalidArgumentError(absl::StrCat("SensorLost names sensor \"",
                                                   record.sensor_id().substr(0, 80), "\" at stamp ",
                                                   record.stamp_ns(), " ns: unknown or negative"));
  }
  if (record.reason().size() > kMaxSensorLostReasonBytes) {
    return absl::InvalidArgumentError(absl::StrCat("SensorLost reason of ", record.reason().size(),
                                                   " bytes; at most ", kMaxSensorLostReasonBytes));
  }
  // Counted like frame sets: the ingest stream stops reading while the
  // queue holds too many bytes, whatever kind of message fills it.
  const uint64_t bytes = record.ByteSizeLong();
  std::lock_guard<std::mutex> lock(mu_);
  if (!write_error_.ok()) return write_error_;
  if (finishing_) {
    return absl::FailedPreconditionError(absl::StrCat("take ", take_id_, " is being finished"));
  }
  queued_bytes_ += bytes;
  queue_.emplace_back(std::move(record));
  wake_.notify_one();
  return absl::OkStatus();
}

void TakeRecorder::Finish(bool complete, uint64_t last_sequence, absl::Status reason) {
  std::lock_guard<std::mutex> lock(mu_);
  if (finishing_) return;
  finishing_ = true;
  finish_ = {complete, last_sequence, std::move(reason)};
  wake_.notify_one();
}

uint64_t TakeRecorder::queued_bytes() const {
  std::lock_guard<std::mutex> lock(mu_);
  return queued_bytes_;
}

uint64_t TakeRecorder::last_sequence() const {
  std::lock_guard<std::mutex> lock(mu_);
  return last_sequence_;
}

TakeRow TakeRecorder::Snapshot() const {
  std::lock_guard<std::mutex> lock(mu_);
  return row_;
}

RecorderStats TakeRecorder::stats() const {
  std::lock_guard<std::mutex> lock(mu_);
  return stats_;
}

absl::Status TakeRecorder::WriteFrameSet(const v1::FrameSet& set) {
  v1::FrameSetRecord record;
  record.set_sequence(set.sequence());
  record.set_stamp_ns(set.stamp_ns());
  record.set_skew_ns(set.skew_ns());
  *record.mutable_missing_sensor_ids() = set.missing_sensor_ids();
  for (const v1::Frame& frame : set.frames()) {
    if (frame.has_color()) RETURN_IF_ERROR(writer_->WriteColor(frame.color()));
    RETURN_IF_ERROR(writer_->WriteDepth(frame.depth()));
    if (frame.has_mask()) RETURN_IF_ERROR(writer_->WriteMask(frame.mask()));
    for (const v1::Skeleton& skeleton : frame.skeletons()) {
      RETURN_IF_ERROR(writer_->WriteSkeleton(skeleton));
    }
    record.add_sensor_ids(frame.sensor_id());
    record.add_frame_indices(frame.frame_index());
  }
  // Last, so that a chunk holding the record holds the whole set.
  RETURN_IF_ERROR(writer_->WriteFrameSetRecord(record));
  if (writer_->pending_chunk_bytes() >= options_.chunk_target_bytes) {
    RETURN_IF_ERROR(writer_->FlushChunk());
  }
  return absl::OkStatus();
}

absl::Status TakeRecorder::WriteBatch(std::deque<Item>& batch, TakeRow& row) {
  const int64_t start_ns = SteadyNowNs();
  int64_t sets = 0;
  for (Item& item : batch) {
    if (const auto* set = std::get_if<v1::FrameSet>(&item)) {
      RETURN_IF_ERROR(WriteFrameSet(*set));
      ++sets;
      v1::Take& t = row.take;
      t.set_durable_sequence(set->sequence());
      if (t.frame_set_count() == 0) row.first_stamp_ns = set->stamp_ns();
      t.set_frame_set_count(t.frame_set_count() + 1);
      row.last_stamp_ns = std::max(row.last_stamp_ns, set->stamp_ns());
      t.set_duration_ns(row.last_stamp_ns - row.first_stamp_ns);
      for (const v1::Frame& frame : set->frames()) {
        if (v1::TakeSensor* s = FindSensor(row, frame.sensor_id())) {
          s->set_frame_count(s->frame_count() + 1);
        }
      }
    } else {
      const auto& lost = std::get<v1::SensorLostRecord>(item);
      RETURN_IF_ERROR(writer_->WriteSensorLost(lost));
      if (v1::TakeSensor* s = FindSensor(row, lost.sensor_id())) {
        s->set_lost_stamp_ns(lost.stamp_ns());
        s->set_lost_reason(lost.reason());
      }
    }
  }
  RETURN_IF_ERROR(writer_->FlushChunk());
  const int64_t written_ns = SteadyNowNs();
  RETURN_IF_ERROR(writer_->Sync());
  const int64_t synced_ns = SteadyNowNs();
  row.take.set_size_bytes(static_cast<int64_t>(writer_->bytes_written()));
  row.take.set_updated_unix_ns(WallNowNs());
  std::lock_guard<std::mutex> lock(mu_);
  stats_.batches += 1;
  stats_.frame_sets += sets;
  stats_.bytes = row.take.size_bytes();
  stats_.write_ns += written_ns - start_ns;
  stats_.sync_ns += synced_ns - written_ns;
  stats_.max_sync_ns = std::max(stats_.max_sync_ns, synced_ns - written_ns);
  stats_.max_batch_sets = std::max(stats_.max_batch_sets, sets);
  return absl::OkStatus();
}

void TakeRecorder::Run() {
  while (true) {
    std::deque<Item> batch;
    bool finish = false;
    TakeRow row;
    {
      std::unique_lock<std::mutex> lock(mu_);
      wake_.wait(lock, [this] { return !queue_.empty() || finishing_; });
      batch.swap(queue_);
      queued_bytes_ = 0;
      // Nothing is queued once finishing_ is set, so this batch is the last.
      finish = finishing_;
      row = row_;
    }
    if (!batch.empty()) {
      const absl::Status written = WriteBatch(batch, row);
      std::lock_guard<std::mutex> lock(mu_);
      if (written.ok()) {
        row_ = row;
      } else {
        // The client hears what happened and what to do, not where: the
        // folder is the server's business (and in its log).
        log::Error("take_write_failed", {{"take_id", take_id_}, {"error", written.message()}},
                   absl::StrCat("take ", take_id_, ": ", written.message()));
        if (IsDiskFull(written)) {
          metrics::DefaultRegistry()
              .GetCounter("reenact_disk_full_total",
                          "Writes refused because the data folder's disk was full")
              .Increment();
          write_error_ = absl::ResourceExhaustedError(absl::StrCat(
              "the server's disk is full: take ", take_id_, " stopped at frame set ",
              row_.take.durable_sequence(), "; delete takes or reenactments to free space"));
        } else {
          write_error_ = absl::UnavailableError(
              absl::StrCat("the server could not store take ", take_id_, " (its log says why)"));
        }
        if (!finishing_) {
          finishing_ = true;
          finish_ = {false, 0, write_error_};
        }
        finish = true;
      }
    }
    if (!finish && !batch.empty()) observer_->OnDurable(row.take.durable_sequence());
    if (finish) break;
  }
  FinishRequest request;
  {
    std::lock_guard<std::mutex> lock(mu_);
    request = finish_;
  }
  RecordingResult result = FinishFile(request);
  if (hook_) hook_(result);
  observer_->OnFinished(result);
}

RecordingResult TakeRecorder::FinishFile(const FinishRequest& request) {
  RecordingResult result;
  absl::Status write_error;
  {
    std::lock_guard<std::mutex> lock(mu_);
    result.row = row_;
    write_error = write_error_;
  }
  result.reason = request.reason;
  bool complete = request.complete;
  if (complete && request.last_sequence != result.row.take.durable_sequence()) {
    complete = false;
    result.reason = absl::InvalidArgumentError(
        absl::StrCat("CloseTake.last_sequence is ", request.last_sequence, " but take ", take_id_,
                     " holds 1..", result.row.take.durable_sequence()));
  }
  absl::Status closed = write_error.ok() ? writer_->Close() : writer_->Abort();
  if (!write_error.ok() || !closed.ok()) {
    // The file ends somewhere after its last durable frame set: cut it there.
    McapAppendReport report;
    absl::StatusOr<TakeFileSummary> recovered =
        RecoverTakeFile(path_, McapWriterOptions{}, &report);
    if (recovered.ok()) ApplyTakeFileSummary(*recovered, result.row);
    complete = false;
    if (result.reason.ok()) result.reason = !closed.ok() ? closed : write_error;
    if (!recovered.ok() && IsDiskFull(recovered.status())) {
      // Nothing durable is lost: the file still ends in its last whole
      // chunk, and it is summarised at the next resume or start. The client
      // hears the disk-full reason it already has.
      log::Warn("take_summary_deferred",
                {{"take_id", take_id_}, {"error", recovered.status().message()}},
                "the take's summary waits for disk space");
    } else if (!recovered.ok()) {
      result.reason = absl::DataLossError(
          absl::StrCat(result.reason.message(),
                       "; recovering the file failed too: ", recovered.status().message()));
    }
  } else {
    result.row.take.set_size_bytes(static_cast<int64_t>(writer_->bytes_written()));
  }
  result.row.take.set_state(complete ? v1::TAKE_STATE_COMPLETE : v1::TAKE_STATE_INTERRUPTED);
  result.row.take.set_updated_unix_ns(WallNowNs());
  return result;
}

}  // namespace reenact::server
