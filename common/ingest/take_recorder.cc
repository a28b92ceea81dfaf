#include "common/ingest/take_recorder.h"

#include <time.h>

#include <algorithm>
#include <cctype>
#include <filesystem>
#include <random>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "common/base/status_macros.h"
#include "common/base/time.h"

namespace reenact::ingest {

namespace {

constexpr char kOpenMeta[] = "open.pb";
constexpr char kCloseMeta[] = "close.pb";

int64_t NewestHostStamp(const v1::FrameSet& set) {
  int64_t newest = 0;
  for (const v1::Frame& frame : set.frames()) newest = std::max(newest, frame.host_stamp_ns());
  return newest;
}

int64_t OldestHostStamp(const v1::FrameSet& set) {
  int64_t oldest = INT64_MAX;
  for (const v1::Frame& frame : set.frames()) oldest = std::min(oldest, frame.host_stamp_ns());
  return oldest == INT64_MAX ? set.stamp_ns() : oldest;
}

SpoolOptions MakeSpoolOptions(const TakeRecorderOptions& options, const std::string& dir) {
  SpoolOptions spool;
  spool.dir = dir;
  spool.max_bytes = options.spool_max_bytes;
  return spool;
}

}  // namespace

std::string MakeTakeId(const std::string& name) {
  const int64_t now_ns = WallNowNs();
  const time_t seconds = static_cast<time_t>(now_ns / kNanosPerSecond);
  struct tm utc {};
  gmtime_r(&seconds, &utc);
  std::string clean;
  for (char c : name) {
    if (clean.size() >= 24) break;
    const bool ok = std::isalnum(static_cast<unsigned char>(c)) || c == '-' || c == '_';
    clean.push_back(ok ? c : '_');
  }
  std::random_device random;
  const unsigned suffix = random() & 0xffff;
  return absl::StrFormat("%04d%02d%02dT%02d%02d%02d-%s%s%04x", utc.tm_year + 1900, utc.tm_mon + 1,
                         utc.tm_mday, utc.tm_hour, utc.tm_min, utc.tm_sec, clean,
                         clean.empty() ? "" : "-", suffix);
}

std::vector<std::string> ListUnfinishedTakes(const std::string& spool_root) {
  std::vector<std::string> out;
  std::error_code ec;
  for (const auto& entry : std::filesystem::directory_iterator(spool_root, ec)) {
    if (entry.is_directory(ec) && std::filesystem::exists(entry.path() / kOpenMeta, ec)) {
      out.push_back(entry.path().string());
    }
  }
  std::sort(out.begin(), out.end());
  return out;
}

TakeRecorder::TakeRecorder(const TakeRecorderOptions& options, std::string take_id)
    : options_(options), take_id_(std::move(take_id)) {}

TakeRecorder::~TakeRecorder() {
  Abort();
  uplink_.reset();  // Joins its threads before the spool goes.
}

absl::StatusOr<std::unique_ptr<TakeRecorder>> TakeRecorder::Start(
    const std::shared_ptr<grpc::Channel>& channel, const TakeRecorderOptions& options,
    const std::string& take_id, const std::string& daemon_id, const v1::TakeInfo& info,
    const std::vector<v1::SensorCalibration>& sensors) {
  RETURN_IF_ERROR(options.uplink.Validate());
  const std::string dir = (std::filesystem::path(options.spool_root) / take_id).string();
  if (std::filesystem::exists(dir)) {
    return absl::AlreadyExistsError(absl::StrCat("spool folder ", dir, " exists already"));
  }
  std::unique_ptr<TakeRecorder> recorder(new TakeRecorder(options, take_id));
  ASSIGN_OR_RETURN(recorder->spool_, Spool::Open(MakeSpoolOptions(options, dir)));
  v1::OpenTake open;
  open.set_take_id(take_id);
  *open.mutable_info() = info;
  open.mutable_info()->set_sensor_count(static_cast<int32_t>(sensors.size()));
  for (const v1::SensorCalibration& calibration : sensors) {
    *open.add_sensors() = calibration;
    recorder->sensor_ids_.insert(calibration.sensor_id());
  }
  open.set_daemon_id(daemon_id);
  recorder->open_ = std::move(open);
  TakeRecorder* raw = recorder.get();
  recorder->uplink_ = std::make_unique<TakeUplink>(
      channel, options.uplink, recorder->spool_.get(),
      [raw](uint64_t durable, int64_t arrival_ns) { raw->OnAck(durable, arrival_ns); });
  return recorder;
}

absl::StatusOr<std::unique_ptr<TakeRecorder>> TakeRecorder::ResumeUnfinished(
    const std::shared_ptr<grpc::Channel>& channel, const TakeRecorderOptions& options,
    const std::string& dir) {
  RETURN_IF_ERROR(options.uplink.Validate());
  SpoolOptions spool_options = MakeSpoolOptions(options, dir);
  // An unfinished take may hold more than today's bound; never refuse to
  // open what is already on disk.
  ASSIGN_OR_RETURN(std::unique_ptr<Spool> spool, Spool::Open(spool_options));
  ASSIGN_OR_RETURN(std::optional<std::string> open_bytes, spool->ReadMeta(kOpenMeta));
  v1::OpenTake open;
  if (!open_bytes || !open.ParseFromString(*open_bytes) || open.take_id().empty()) {
    return absl::DataLossError(absl::StrCat(dir, ": no readable ", kOpenMeta));
  }
  ASSIGN_OR_RETURN(std::optional<std::string> close_bytes, spool->ReadMeta(kCloseMeta));
  v1::CloseTake close;
  if (!close_bytes || !close.ParseFromString(*close_bytes)) {
    close.set_last_sequence(spool->last_sequence());
    close.set_reason("daemon restarted");
  }
  std::unique_ptr<TakeRecorder> recorder(new TakeRecorder(options, open.take_id()));
  recorder->spool_ = std::move(spool);
  recorder->last_sequence_ = close.last_sequence();
  recorder->stopped_ = true;
  recorder->open_sent_ = true;
  TakeRecorder* raw = recorder.get();
  recorder->uplink_ = std::make_unique<TakeUplink>(
      channel, options.uplink, recorder->spool_.get(),
      [raw](uint64_t durable, int64_t arrival_ns) { raw->OnAck(durable, arrival_ns); });
  recorder->uplink_->SetOpen(open);
  recorder->uplink_->Close(close);
  return recorder;
}

void TakeRecorder::HoldOpen() {
  std::lock_guard<std::mutex> lock(open_mutex_);
  if (!open_sent_) open_held_ = true;
}

void TakeRecorder::ReleaseOpen(const std::vector<v1::SensorCalibration>& sensors) {
  std::lock_guard<std::mutex> lock(open_mutex_);
  if (open_sent_ || !open_held_) return;
  open_held_ = false;
  for (v1::SensorCalibration& calibration : *open_->mutable_sensors()) {
    for (const v1::SensorCalibration& replacement : sensors) {
      if (replacement.sensor_id() == calibration.sensor_id()) calibration = replacement;
    }
  }
  if (held_start_stamp_ns_) SendOpenLocked(*held_start_stamp_ns_);
}

void TakeRecorder::SendOpen(int64_t start_stamp_ns) {
  std::lock_guard<std::mutex> lock(open_mutex_);
  if (open_sent_) return;
  if (open_held_) {
    if (!held_start_stamp_ns_) held_start_stamp_ns_ = start_stamp_ns;
    return;
  }
  SendOpenLocked(held_start_stamp_ns_.value_or(start_stamp_ns));
}

void TakeRecorder::SendOpenLocked(int64_t start_stamp_ns) {
  open_sent_ = true;
  open_->mutable_info()->set_start_stamp_ns(start_stamp_ns);
  // Without open.pb a restarted daemon could not resume the take; the
  // upload itself goes on either way.
  (void)spool_->WriteMeta(kOpenMeta, open_->SerializeAsString());
  uplink_->SetOpen(*open_);
}

absl::Status TakeRecorder::Add(v1::FrameSet set) {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (stopped_ || aborted_) {
      return absl::FailedPreconditionError(
          absl::StrCat("take ", take_id_, stopped_ ? " is stopped" : " was aborted"));
    }
  }
  // Keep only the take's sensors.
  auto* frames = set.mutable_frames();
  frames->erase(
      std::remove_if(frames->begin(), frames->end(),
                     [this](const v1::Frame& f) { return !sensor_ids_.count(f.sensor_id()); }),
      frames->end());
  auto* missing = set.mutable_missing_sensor_ids();
  missing->erase(std::remove_if(missing->begin(), missing->end(),
                                [this](const std::string& id) { return !sensor_ids_.count(id); }),
                 missing->end());
  if (set.frames_size() == 0) return absl::OkStatus();
  SendOpen(OldestHostStamp(set));

  const uint64_t sequence = last_sequence() + 1;
  set.set_sequence(sequence);
  const int64_t newest_ns = NewestHostStamp(set);
  std::vector<std::string> sensors;
  for (const v1::Frame& frame : set.frames()) sensors.push_back(frame.sensor_id());
  int64_t record_bytes = 0;
  while (true) {
    // A resumed take (the same take id sent again, as `reenact takes upload`
    // does) may already be durable past this set: the server said so when
    // it opened the take, and the spool has released everything up to there.
    if (sequence <= spool_->acked_sequence()) {
      std::lock_guard<std::mutex> lock(mutex_);
      last_sequence_ = sequence;
      return absl::OkStatus();
    }
    // Append moves from `set` only on success, so a retry sends it whole.
    // NOLINTNEXTLINE(bugprone-use-after-move)
    absl::Status appended = spool_->Append(std::move(set), &record_bytes);
    if (appended.ok()) break;
    // The server's durable sequence arrived between the check and the append.
    if (absl::IsInvalidArgument(appended) && sequence <= spool_->acked_sequence()) continue;
    std::unique_lock<std::mutex> lock(mutex_);
    if (!absl::IsResourceExhausted(appended) || !options_.wait_when_full || stopped_ || no_wait_ ||
        aborted_) {
      if (absl::IsResourceExhausted(appended)) ++refused_;
      return appended;
    }
    // Wait for an Ack to free space (or for the take to stop).
    const uint64_t acked = spool_->acked_sequence();
    cv_.wait_for(lock, std::chrono::milliseconds(200), [&] {
      return stopped_ || no_wait_ || aborted_ || spool_->acked_sequence() != acked;
    });
  }
  {
    std::lock_guard<std::mutex> lock(mutex_);
    last_sequence_ = sequence;
    ++frame_sets_;
    bytes_total_ += record_bytes;
    for (const std::string& id : sensors) ++frames_per_sensor_[id];
    newest_stamp_ns_.emplace_back(sequence, newest_ns);
  }
  uplink_->Notify();
  return absl::OkStatus();
}

void TakeRecorder::SensorLost(const std::string& sensor_id, int64_t stamp_ns,
                              const std::string& reason) {
  if (!sensor_ids_.count(sensor_id)) return;
  v1::SensorLost lost;
  lost.set_sensor_id(sensor_id);
  lost.set_stamp_ns(stamp_ns);
  lost.set_reason(reason);
  uplink_->SensorLost(lost);
}

void TakeRecorder::Stop(const std::string& reason) {
  uint64_t last = 0;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (stopped_) return;
    stopped_ = true;
    last = last_sequence_;
    cv_.notify_all();
  }
  {
    std::lock_guard<std::mutex> lock(open_mutex_);
    open_held_ = false;  // A take never stays unopened.
  }
  SendOpen(WallNowNs());
  v1::CloseTake close;
  close.set_last_sequence(last);
  close.set_reason(reason);
  (void)spool_->WriteMeta(kCloseMeta, close.SerializeAsString());
  uplink_->Close(close);
}

void TakeRecorder::StopWaiting() {
  std::lock_guard<std::mutex> lock(mutex_);
  no_wait_ = true;
  cv_.notify_all();
}

void TakeRecorder::Abort() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    aborted_ = true;
    cv_.notify_all();
  }
  if (uplink_) uplink_->Abort();
}

bool TakeRecorder::WaitDone(double timeout_s) {
  if (!uplink_->WaitDone(timeout_s)) return false;
  std::lock_guard<std::mutex> lock(mutex_);
  if (uplink_->result().ok() && !removed_) {
    removed_ = true;
    (void)spool_->RemoveAll();
  }
  return true;
}

bool TakeRecorder::done() const { return uplink_->stats().done; }
absl::Status TakeRecorder::result() const { return uplink_->result(); }
std::optional<v1::TakeClosed> TakeRecorder::closed() const { return uplink_->closed(); }

uint64_t TakeRecorder::last_sequence() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return last_sequence_;
}

void TakeRecorder::OnAck(uint64_t durable_sequence, int64_t arrival_ns) {
  std::lock_guard<std::mutex> lock(mutex_);
  while (!newest_stamp_ns_.empty() && newest_stamp_ns_.front().first <= durable_sequence) {
    latency_ns_.Add(arrival_ns - newest_stamp_ns_.front().second);
    newest_stamp_ns_.pop_front();
  }
  cv_.notify_all();
}

TakeStats TakeRecorder::Stats() const {
  TakeStats stats;
  stats.uplink = uplink_->stats();
  std::lock_guard<std::mutex> lock(mutex_);
  stats.take_id = take_id_;
  stats.frame_sets = frame_sets_;
  stats.frame_sets_refused = refused_;
  stats.frames_per_sensor = frames_per_sensor_;
  stats.bytes_total = bytes_total_;
  stats.durable_sequence = stats.uplink.durable_sequence;
  stats.acked_sets = static_cast<int64_t>(latency_ns_.count());
  stats.latency_p50_ns = latency_ns_.Quantile(0.5);
  stats.latency_p99_ns = latency_ns_.Quantile(0.99);
  stats.latency_max_ns = latency_ns_.max();
  if (!removed_) {
    stats.spool_frame_sets = spool_->frame_sets();
    stats.spool_bytes = spool_->bytes();
  }
  return stats;
}

}  // namespace reenact::ingest
