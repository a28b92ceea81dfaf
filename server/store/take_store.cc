#include "server/store/take_store.h"

#include <fcntl.h>
#include <sys/file.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <utility>

#include "absl/strings/ascii.h"
#include "absl/strings/match.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "common/base/files.h"
#include "common/base/status_macros.h"
#include "common/base/time.h"
#include "common/log/log.h"
#include "server/metrics/server_metrics.h"
#include "server/store/take_file.h"

namespace reenact::server {
namespace {

// The highest frame rate a take may state (depth sensors run at 5-90 Hz).
constexpr double kMaxTakeFps = 1000.0;

namespace fs = std::filesystem;

constexpr size_t kMaxDaemonIdLength = 128;

std::string TakeRelativePath(const std::string& take_id) {
  return absl::StrCat("takes/", take_id, ".mcap");
}

std::set<std::string> SensorIds(const v1::Take& take) {
  std::set<std::string> ids;
  for (const v1::TakeSensor& s : take.sensors()) ids.insert(s.sensor_id());
  return ids;
}

void ClearCounts(TakeRow& row) { ApplyTakeFileSummary(TakeFileSummary{}, row); }

// "complete" for TAKE_STATE_COMPLETE: the short form logs carry.
std::string StateName(v1::TakeState state) {
  std::string name = absl::AsciiStrToLower(v1::TakeState_Name(state));
  if (absl::StartsWith(name, "take_state_")) name = name.substr(11);
  return name;
}

}  // namespace

absl::Status TakeStoreOptions::Validate() const {
  if (data_dir.empty()) return absl::InvalidArgumentError("TakeStoreOptions.data_dir is empty");
  if (!chunk_compression.empty() && chunk_compression != "zstd") {
    return absl::InvalidArgumentError(
        absl::StrCat("TakeStoreOptions.chunk_compression must be \"\" or \"zstd\", got \"",
                     chunk_compression, "\""));
  }
  if (chunk_target_bytes == 0 || chunk_target_bytes > (uint64_t{1} << 30)) {
    return absl::InvalidArgumentError("TakeStoreOptions.chunk_target_bytes must be in 1..1 GiB");
  }
  if (!(catalog_update_period_s > 0)) {
    return absl::InvalidArgumentError("TakeStoreOptions.catalog_update_period_s must be > 0");
  }
  return limits.Validate();
}

TakeStore::TakeStore(TakeStoreOptions options, std::unique_ptr<Catalog> catalog, int lock_fd)
    : options_(std::move(options)), catalog_(std::move(catalog)), lock_fd_(lock_fd) {}

absl::StatusOr<std::unique_ptr<TakeStore>> TakeStore::Open(const TakeStoreOptions& options,
                                                           std::vector<RecoveredTake>* recovered) {
  RETURN_IF_ERROR(options.Validate());
  if (absl::Status made = CreateDirectories((fs::path(options.data_dir) / "takes").string());
      !made.ok()) {
    return absl::PermissionDeniedError(
        absl::StrCat("data folder ", options.data_dir, " is unusable: ", made.message()));
  }
  const std::string lock_path = (fs::path(options.data_dir) / "lock").string();
  const int lock_fd = ::open(lock_path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
  if (lock_fd < 0) {
    return absl::PermissionDeniedError(absl::StrCat("data folder ", options.data_dir,
                                                    " is not writable: ", lock_path, ": ",
                                                    std::strerror(errno)));
  }
  if (::flock(lock_fd, LOCK_EX | LOCK_NB) != 0) {
    ::close(lock_fd);
    return absl::FailedPreconditionError(absl::StrCat("data folder ", options.data_dir,
                                                      " is in use by another reenact-server (",
                                                      lock_path, ")"));
  }
  absl::StatusOr<std::unique_ptr<Catalog>> catalog =
      Catalog::Open((fs::path(options.data_dir) / "catalog.sqlite").string());
  if (!catalog.ok()) {
    ::close(lock_fd);
    return catalog.status();
  }
  std::unique_ptr<TakeStore> store(new TakeStore(options, std::move(*catalog), lock_fd));
  std::vector<RecoveredTake> local;
  RETURN_IF_ERROR(store->Recover(recovered != nullptr ? recovered : &local));
  store->catalog_thread_ = std::thread([s = store.get()] { s->CatalogLoop(); });
  return store;
}

TakeStore::~TakeStore() {
  Shutdown(absl::UnavailableError("the take store closed"));
  { std::lock_guard<std::mutex> wait_for_last_hook(catalog_write_mu_); }
  {
    std::lock_guard<std::mutex> lock(mu_);
    stop_catalog_ = true;
  }
  catalog_wake_.notify_all();
  if (catalog_thread_.joinable()) catalog_thread_.join();
  ::close(lock_fd_);
}

std::string TakeStore::AbsolutePath(const std::string& relative) const {
  return (fs::path(options_.data_dir) / relative).string();
}

TakeWriterOptions TakeStore::WriterOptions() const {
  TakeWriterOptions writer;
  writer.mcap.compression = options_.chunk_compression;
  writer.mcap.zstd_level = options_.zstd_level;
  // Chunks end where the recorder says (between frame sets), never on size.
  writer.mcap.chunk_size_bytes = uint64_t{2} << 30;
  writer.mcap.durable = true;
  writer.mcap.library = "reenact-server";
  return writer;
}

// ------------------------------------------------------------------ recovery

absl::Status TakeStore::Recover(std::vector<RecoveredTake>* recovered) {
  ASSIGN_OR_RETURN(std::vector<TakeRow> rows, catalog_->List(v1::TAKE_STATE_RECORDING));
  for (TakeRow& row : rows) recovered->push_back(RecoverTake(std::move(row)));
  return absl::OkStatus();
}

RecoveredTake TakeStore::RecoverTake(TakeRow row) {
  const int64_t start_ns = SteadyNowNs();
  RecoveredTake out;
  out.take_id = row.take.take_id();
  const std::string path = AbsolutePath(row.path);
  std::error_code ec;
  if (!fs::exists(path, ec)) {
    out.problem = "the take file is missing";
    ClearCounts(row);
  } else {
    McapAppendReport report;
    absl::StatusOr<TakeFileSummary> summary = RecoverTakeFile(path, WriterOptions().mcap, &report);
    out.dropped_bytes = report.dropped_bytes;
    if (summary.ok()) {
      ApplyTakeFileSummary(*summary, row);
    } else {
      // Keep the bytes for inspection; the take restarts from nothing.
      const std::string aside = absl::StrCat(path, ".damaged-", WallNowNs());
      fs::rename(path, aside, ec);
      out.problem = absl::StrCat(summary.status().message(), "; file moved to ", aside);
      ClearCounts(row);
    }
  }
  row.take.set_state(v1::TAKE_STATE_INTERRUPTED);
  row.take.set_updated_unix_ns(WallNowNs());
  if (absl::Status put = catalog_->Put(row); !put.ok()) {
    out.problem = absl::StrCat(out.problem, out.problem.empty() ? "" : "; ", put.message());
  }
  out.durable_sequence = row.take.durable_sequence();
  out.size_bytes = row.take.size_bytes();
  out.elapsed_s = NsToSeconds(SteadyNowNs() - start_ns);
  log::Log(out.problem.empty() ? log::Level::kInfo : log::Level::kWarn, "take_recovered",
           {{"take_id", out.take_id},
            {"frame_sets", out.durable_sequence},
            {"bytes", out.size_bytes},
            {"dropped_bytes", out.dropped_bytes},
            {"elapsed_s", out.elapsed_s},
            {"problem", out.problem}},
           absl::StrCat("recovered take ", out.take_id, ": ", out.durable_sequence, " frame sets, ",
                        out.size_bytes, " bytes (", out.dropped_bytes, " cut) in ", out.elapsed_s,
                        " s", out.problem.empty() ? "" : "; ", out.problem));
  return out;
}

// ------------------------------------------------------------------- opening

absl::StatusOr<TakeOpenResult> TakeStore::OpenTake(const TakeOpenRequest& request,
                                                   RecorderObserver* observer) {
  RETURN_IF_ERROR(ValidateTakeId(request.take_id));
  if (absl::Status info = ValidateTakeInfo(request.info, options_.limits); !info.ok()) {
    const bool notes =
        request.info.notes().size() > static_cast<size_t>(options_.limits.max_notes_bytes);
    LimitHit(notes ? "notes_bytes" : "name_bytes",
             {{"take_id", request.take_id}, {"daemon_id", request.daemon_id}}, info.message());
    return info;
  }
  if (request.daemon_id.empty() || request.daemon_id.size() > kMaxDaemonIdLength) {
    return absl::InvalidArgumentError(
        absl::StrCat("OpenTake.daemon_id must be 1..", kMaxDaemonIdLength, " characters"));
  }
  if (request.info.start_stamp_ns() < 0) {
    return absl::InvalidArgumentError(
        absl::StrCat("OpenTake.info.start_stamp_ns is negative: ", request.info.start_stamp_ns()));
  }
  // 0: not stated; otherwise a frame rate a sensor can have.
  if (!std::isfinite(request.info.fps()) || request.info.fps() < 0 ||
      request.info.fps() > kMaxTakeFps) {
    return absl::InvalidArgumentError(
        absl::StrCat("OpenTake.info.fps must be 0 (not stated) or in (0, ", kMaxTakeFps, "]; got ",
                     request.info.fps()));
  }
  const std::string& id = request.take_id;
  {
    std::lock_guard<std::mutex> lock(mu_);
    if (shutting_down_) return absl::UnavailableError("the server is shutting down");
    if (const auto active = recording_.find(id); active != recording_.end()) {
      const TakeRow snapshot = active->second->Snapshot();
      const std::string& owner = snapshot.take.daemon_id();
      if (!request.owner_is_admin && snapshot.owner != request.owner) {
        return absl::PermissionDeniedError(
            absl::StrCat("take ", id,
                         " belongs to another credential; only it or an admin may "
                         "add to it"));
      }
      if (owner != request.daemon_id) {
        return absl::PermissionDeniedError(absl::StrCat(
            "take ", id, " is being recorded by daemon \"", owner, "\"; only it may add to it"));
      }
    }
    if (recording_.contains(id) || opening_.contains(id)) {
      return absl::AbortedError(absl::StrCat("take ", id,
                                             " is being recorded by another stream; retry once "
                                             "that stream has ended"));
    }
    opening_.insert(id);
  }
  absl::StatusOr<TakeOpenResult> result = [&]() -> absl::StatusOr<TakeOpenResult> {
    absl::StatusOr<TakeRow> row = catalog_->Get(id);
    if (absl::IsNotFound(row.status())) return CreateTake(request, observer);
    if (!row.ok()) return row.status();
    if (!request.owner_is_admin && row->owner != request.owner) {
      return absl::PermissionDeniedError(absl::StrCat(
          "take ", id, " belongs to another credential; only it or an admin may resume it"));
    }
    if (row->take.daemon_id() != request.daemon_id) {
      return absl::PermissionDeniedError(absl::StrCat("take ", id, " was recorded by daemon \"",
                                                      row->take.daemon_id(),
                                                      "\"; only that daemon may resume it"));
    }
    if (row->take.state() == v1::TAKE_STATE_COMPLETE) {
      return TakeOpenResult{nullptr, row->take.durable_sequence(), true, *row};
    }
    if (row->take.state() == v1::TAKE_STATE_RECORDING) {  // Left by a failed catalog update.
      RecoverTake(*row);
      ASSIGN_OR_RETURN(*row, catalog_->Get(id));
    }
    return ResumeTake(request, std::move(*row), observer);
  }();
  {
    std::lock_guard<std::mutex> lock(mu_);
    opening_.erase(id);
    recordings_changed_.notify_all();
  }
  if (result.ok() && result->recorder != nullptr) {
    log::Info("take_opened",
              {{"take_id", id},
               {"daemon_id", request.daemon_id},
               {"owner", request.owner},
               {"sensors", result->row.take.sensors_size()},
               {"resumed", result->resumed},
               {"durable_sequence", result->durable_sequence}},
              absl::StrCat(result->resumed ? "resumed take " : "opened take ", id));
  }
  return result;
}

absl::StatusOr<TakeOpenResult> TakeStore::CreateTake(const TakeOpenRequest& request,
                                                     RecorderObserver* observer) {
  RETURN_IF_ERROR(ValidateSensors(request.sensors, options_.limits));
  TakeRow row;
  row.path = TakeRelativePath(request.take_id);
  const std::string path = AbsolutePath(row.path);
  {
    std::lock_guard<std::mutex> lock(mu_);
    ++generations_[request.take_id];
  }
  auto writer = TakeWriter::Open(path, request.info, WriterOptions());
  if (!writer.ok()) return absl::UnavailableError(writer.status().message());
  absl::Status status;
  for (const v1::SensorCalibration& sensor : request.sensors) {
    if (status.ok()) status = (*writer)->AddSensor(sensor);
  }
  if (status.ok()) status = (*writer)->Sync();
  if (status.ok()) status = SyncDirectory(AbsolutePath("takes"));
  v1::Take& t = row.take;
  t.set_take_id(request.take_id);
  t.set_name(request.info.name());
  t.set_state(v1::TAKE_STATE_RECORDING);
  t.set_created_unix_ns(WallNowNs());
  t.set_updated_unix_ns(t.created_unix_ns());
  t.set_size_bytes(static_cast<int64_t>((*writer)->bytes_written()));
  t.set_generator(request.info.generator());
  t.set_synthetic(request.info.synthetic());
  t.set_fps(request.info.fps());
  t.set_daemon_id(request.daemon_id);
  row.owner = request.owner;
  for (const v1::SensorCalibration& sensor : request.sensors) {
    v1::TakeSensor* s = t.add_sensors();
    s->set_sensor_id(sensor.sensor_id());
    s->set_model(sensor.model());
  }
  if (status.ok()) status = catalog_->Put(row);
  if (!status.ok()) {
    (*writer)->Abort().IgnoreError();
    std::error_code ec;
    fs::remove(path, ec);
    return status;
  }
  TakeOpenResult result;
  result.row = row;
  result.recorder = StartRecorder(std::move(*writer), std::move(row), observer);
  return result;
}

absl::StatusOr<TakeOpenResult> TakeStore::ResumeTake(const TakeOpenRequest& request, TakeRow row,
                                                     RecorderObserver* observer) {
  const std::string& id = request.take_id;
  if (!request.sensors.empty()) {
    std::set<std::string> asked;
    for (const v1::SensorCalibration& s : request.sensors) asked.insert(s.sensor_id());
    if (asked != SensorIds(row.take)) {
      return absl::InvalidArgumentError(
          absl::StrCat("take ", id, " has sensors {", absl::StrJoin(SensorIds(row.take), ", "),
                       "}; the resuming OpenTake names {", absl::StrJoin(asked, ", "), "}"));
    }
  }
  const std::string path = AbsolutePath(row.path);
  std::error_code ec;
  if (!fs::exists(path, ec)) {
    if (row.take.durable_sequence() != 0) {
      return absl::DataLossError(absl::StrCat("take ", id, " held ", row.take.durable_sequence(),
                                              " frame sets but its file is gone"));
    }
    // Nothing durable was lost with the file: start the take over.
    RETURN_IF_ERROR(catalog_->Delete(id));
    return CreateTake(request, observer);
  }
  const TakeRow interrupted = row;
  row.take.set_state(v1::TAKE_STATE_RECORDING);
  row.take.set_updated_unix_ns(WallNowNs());
  RETURN_IF_ERROR(catalog_->Put(row));  // Before the file changes: a crash now is recovered.
  {
    std::lock_guard<std::mutex> lock(mu_);
    ++generations_[id];
  }
  auto writer = TakeWriter::OpenForAppend(path, WriterOptions());
  if (!writer.ok()) {
    catalog_->Put(interrupted).IgnoreError();
    return absl::DataLossError(
        absl::StrCat("take ", id, " cannot be continued: ", writer.status().message()));
  }
  TakeOpenResult result;
  result.durable_sequence = row.take.durable_sequence();
  result.resumed = true;
  result.row = row;
  result.recorder = StartRecorder(std::move(*writer), std::move(row), observer);
  return result;
}

std::shared_ptr<TakeRecorder> TakeStore::StartRecorder(std::unique_ptr<TakeWriter> writer,
                                                       TakeRow row, RecorderObserver* observer) {
  const std::string id = row.take.take_id();
  const std::string path = AbsolutePath(row.path);
  const int64_t updated_ns = row.take.updated_unix_ns();
  auto recorder = std::make_shared<TakeRecorder>(
      std::move(writer), path, std::move(row), TakeRecorder::Options{options_.chunk_target_bytes},
      observer, [this](RecordingResult& result) { OnRecordingFinished(result); });
  bool shutting_down = false;
  TakesOpenGauge().Add(1);  // Down again in OnRecordingFinished.
  {
    std::lock_guard<std::mutex> lock(mu_);
    recording_[id] = recorder;
    catalog_updated_ns_[id] = updated_ns;
    shutting_down = shutting_down_;
  }
  recorder->Start();
  if (shutting_down)
    recorder->Finish(false, 0, absl::UnavailableError("the server is shutting down"));
  return recorder;
}

void TakeStore::OnRecordingFinished(RecordingResult& result) {
  std::lock_guard<std::mutex> write_lock(catalog_write_mu_);
  if (IsDiskFull(result.reason) || (absl::IsResourceExhausted(result.reason) &&
                                    absl::StrContains(result.reason.message(), "disk is full"))) {
    SetDiskFull(true);
  }
  bool saved = true;
  if (absl::Status put = catalog_->Put(result.row); !put.ok()) {
    if (IsDiskFull(put)) SetDiskFull(true);
    // The file is finished; the catalog's row says RECORDING. Readers see
    // this row instead until the catalog thread writes it; a restart before
    // that recovers the take from its file (INTERRUPTED either way).
    result.row.take.set_state(v1::TAKE_STATE_INTERRUPTED);
    if (result.reason.ok()) {
      result.reason = IsDiskFull(put) ? absl::ResourceExhaustedError(
                                            "the server's disk is full; the take could not be "
                                            "closed (delete takes or reenactments to free space)")
                                      : put;
    }
    saved = false;
  }
  TakesOpenGauge().Add(-1);
  const v1::Take& take = result.row.take;
  const bool complete = take.state() == v1::TAKE_STATE_COMPLETE;
  log::Log(complete ? log::Level::kInfo : log::Level::kWarn, "take_closed",
           {{"take_id", take.take_id()},
            {"state", StateName(take.state())},
            {"frame_sets", take.durable_sequence()},
            {"bytes", take.size_bytes()},
            {"reason", result.reason.message()}},
           absl::StrCat("take ", take.take_id(), " closed: ", StateName(take.state())));
  std::lock_guard<std::mutex> lock(mu_);
  if (!saved) unsaved_[result.row.take.take_id()] = result.row;
  recording_.erase(result.row.take.take_id());
  catalog_updated_ns_.erase(result.row.take.take_id());
  recordings_changed_.notify_all();
}

// ------------------------------------------------------------------- catalog

void TakeStore::UpdateCatalog() {
  std::lock_guard<std::mutex> write_lock(catalog_write_mu_);
  std::vector<std::shared_ptr<TakeRecorder>> active;
  {
    std::lock_guard<std::mutex> lock(mu_);
    for (const auto& [id, recorder] : recording_) active.push_back(recorder);
  }
  std::map<std::string, TakeRow> unsaved;
  {
    std::lock_guard<std::mutex> lock(mu_);
    unsaved = unsaved_;
  }
  for (const auto& [id, row] : unsaved) {
    if (!catalog_->Put(row).ok()) continue;  // Still full: next period.
    SetDiskFull(false);
    std::lock_guard<std::mutex> lock(mu_);
    if (auto it = unsaved_.find(id);
        it != unsaved_.end() && it->second.take.updated_unix_ns() == row.take.updated_unix_ns()) {
      unsaved_.erase(it);
    }
  }
  for (const auto& recorder : active) {
    const TakeRow row = recorder->Snapshot();
    {
      std::lock_guard<std::mutex> lock(mu_);
      int64_t& last = catalog_updated_ns_[recorder->take_id()];
      if (last == row.take.updated_unix_ns()) continue;
      last = row.take.updated_unix_ns();
    }
    catalog_->Put(row).IgnoreError();  // Retried with the next change.
  }
}

void TakeStore::CatalogLoop() {
  const auto period = std::chrono::duration<double>(options_.catalog_update_period_s);
  std::unique_lock<std::mutex> lock(mu_);
  while (!stop_catalog_) {
    catalog_wake_.wait_for(lock, period, [this] { return stop_catalog_; });
    if (stop_catalog_) break;
    lock.unlock();
    UpdateCatalog();
    lock.lock();
  }
}

// ------------------------------------------------------------------- reading

v1::Take TakeStore::Live(TakeRow row) const {
  std::shared_ptr<TakeRecorder> recorder;
  {
    std::lock_guard<std::mutex> lock(mu_);
    if (auto it = recording_.find(row.take.take_id()); it != recording_.end()) {
      recorder = it->second;
    } else if (auto saved = unsaved_.find(row.take.take_id()); saved != unsaved_.end()) {
      return saved->second.take;
    }
  }
  return recorder ? recorder->Snapshot().take : std::move(row.take);
}

absl::StatusOr<v1::Take> TakeStore::GetTake(const std::string& take_id) const {
  ASSIGN_OR_RETURN(TakeRow row, catalog_->Get(take_id));
  return Live(std::move(row));
}

absl::StatusOr<std::vector<v1::Take>> TakeStore::ListTakes(v1::TakeState state) const {
  bool any_unsaved = false;
  {
    std::lock_guard<std::mutex> lock(mu_);
    any_unsaved = !unsaved_.empty();
  }
  // An unsaved row's state differs from the catalog's: filter after Live.
  ASSIGN_OR_RETURN(std::vector<TakeRow> rows,
                   catalog_->List(any_unsaved ? v1::TAKE_STATE_UNSPECIFIED : state));
  std::vector<v1::Take> takes;
  takes.reserve(rows.size());
  for (TakeRow& row : rows) {
    v1::Take take = Live(std::move(row));
    if (state == v1::TAKE_STATE_UNSPECIFIED || take.state() == state) {
      takes.push_back(std::move(take));
    }
  }
  return takes;
}

absl::StatusOr<int64_t> TakeStore::DeleteTake(const std::string& take_id) {
  {
    std::lock_guard<std::mutex> lock(mu_);
    if (recording_.contains(take_id) || opening_.contains(take_id)) {
      return absl::FailedPreconditionError(
          absl::StrCat("take ", take_id, " is being recorded; it can be deleted once it ends"));
    }
    opening_.insert(take_id);  // Keeps OpenTake away while the take goes.
  }
  absl::StatusOr<int64_t> freed = [&]() -> absl::StatusOr<int64_t> {
    ASSIGN_OR_RETURN(const TakeRow row, catalog_->Get(take_id));
    const std::string path = AbsolutePath(row.path);
    std::error_code ec;
    const auto size = fs::file_size(path, ec);
    const int64_t bytes = ec ? 0 : static_cast<int64_t>(size);
    auto remove_file = [&]() -> absl::Status {
      fs::remove(path, ec);
      if (ec) {
        return absl::UnavailableError(
            absl::StrCat("take ", take_id, ": its file could not be removed: ", ec.message()));
      }
      // The skeletons a job tracked from the take's depth and kept beside it
      // (TrackedSkeletonsPath, server/recon/take_tracking.h) go with it; a
      // file left there would be ignored anyway, as made from another take.
      std::error_code ignored;
      fs::remove(path + ".skeletons", ignored);
      return SyncDirectory(fs::path(path).parent_path().string());
    };
    if (absl::Status forgotten = catalog_->Delete(take_id); !forgotten.ok()) {
      // On a full disk the catalog cannot even log the deletion: free the
      // file's space first, then forget it. A take whose file is gone and
      // whose row stays is deleted again next time (removing nothing).
      if (!IsDiskFull(forgotten)) return forgotten;
      RETURN_IF_ERROR(remove_file());
      RETURN_IF_ERROR(catalog_->Delete(take_id));
      return bytes;
    }
    RETURN_IF_ERROR(remove_file());
    return bytes;
  }();
  if (freed.ok() && *freed > 0) SetDiskFull(false);  // Space came back.
  std::lock_guard<std::mutex> lock(mu_);
  if (freed.ok()) unsaved_.erase(take_id);
  opening_.erase(take_id);
  recordings_changed_.notify_all();
  return freed;
}

void TakeStore::SetDiskFull(bool full) {
  {
    std::lock_guard<std::mutex> lock(mu_);
    if (disk_full_ == full) return;
    disk_full_ = full;
  }
  // The server logs the change and turns its health (server.cc).
  if (options_.disk_full_changed) options_.disk_full_changed(full);
}

absl::StatusOr<std::string> TakeStore::TakeFileForReading(const std::string& take_id) const {
  {
    std::lock_guard<std::mutex> lock(mu_);
    if (recording_.contains(take_id) || opening_.contains(take_id)) {
      return absl::FailedPreconditionError(
          absl::StrCat("take ", take_id, " is being recorded; its file is not finished"));
    }
  }
  ASSIGN_OR_RETURN(const TakeRow row, catalog_->Get(take_id));
  if (row.take.state() == v1::TAKE_STATE_RECORDING) {
    return absl::FailedPreconditionError(absl::StrCat("take ", take_id, " is being recorded"));
  }
  return AbsolutePath(row.path);
}

uint64_t TakeStore::FileGeneration(const std::string& take_id) const {
  std::lock_guard<std::mutex> lock(mu_);
  const auto it = generations_.find(take_id);
  return it == generations_.end() ? 0 : it->second;
}

// ------------------------------------------------------------------ shutdown

void TakeStore::Shutdown(const absl::Status& reason) {
  std::vector<std::shared_ptr<TakeRecorder>> active;
  {
    std::lock_guard<std::mutex> lock(mu_);
    shutting_down_ = true;
    for (const auto& [id, recorder] : recording_) active.push_back(recorder);
  }
  for (const auto& recorder : active) recorder->Finish(false, 0, reason);
  active.clear();
  std::unique_lock<std::mutex> lock(mu_);
  recordings_changed_.wait(lock, [this] { return recording_.empty() && opening_.empty(); });
}

}  // namespace reenact::server
