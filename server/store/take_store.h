// The server's take store: one MCAP file per take in DATA/takes/<take_id>.mcap
// (written with TakeWriter, the channels of common/io/take.h plus the ingest
// records) and the SQLite catalog DATA/catalog.sqlite over them.
//
// Life of a take: OpenTake creates its file (info and calibrations, fsync'ed)
// and its RECORDING row, and hands out a TakeRecorder; frame sets become
// durable batch by batch; the recorder finishes the file as COMPLETE
// (CloseTake) or INTERRUPTED (stream gone, bad message, shutdown). The same
// daemon resumes an INTERRUPTED take by opening it again: the file is
// continued in place (TakeWriter::OpenForAppend: its summary is cut off and
// new chunks follow the old ones), which costs a scan of record headers and
// no copy, however long the take.
//
// Crashes: the catalog is updated about once a second while a take records;
// the file is the source of truth. Open() finds the takes the catalog still
// calls RECORDING, cuts each file after its last intact chunk, finishes it,
// and makes the row INTERRUPTED with the counts read from the file.
//
// Thread-safe.
#pragma once

#include <condition_variable>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "common/io/mcap_writer.h"
#include "reenact/v1/takes_service.pb.h"
#include "server/store/catalog.h"
#include "server/store/frame_set_validation.h"
#include "server/store/take_recorder.h"

namespace reenact::server {

struct TakeStoreOptions {
  // Folder of the catalog and takes/; created when missing.
  std::string data_dir;
  // Compression of new chunks: "" (none) or "zstd". JPEG colour and
  // RVL+zstd depth barely shrink further, so none is the default.
  std::string chunk_compression;
  int zstd_level = 1;
  // A chunk ends at the first frame-set boundary past this many bytes (and
  // after every fsync'ed batch).
  uint64_t chunk_target_bytes = uint64_t{8} << 20;
  // How often the catalog gets the progress of recording takes, seconds.
  double catalog_update_period_s = 1.0;
  // Limits of what a take may hold (sensor image sizes are checked at
  // OpenTake; the ingest checks frame sets against them).
  FrameSetLimits limits;
  // Told true when a write fails for want of space on the data folder's
  // disk and false once writes succeed again; reenact-server makes its
  // health NOT_SERVING meanwhile (Server::SetDiskFull). Empty: nobody.
  std::function<void(bool full)> disk_full_changed{};

  // InvalidArgument naming the first bad field.
  absl::Status Validate() const;
};

// What Open() did to the takes a crash left RECORDING.
struct RecoveredTake {
  std::string take_id;
  uint64_t durable_sequence = 0;
  // File bytes cut off (torn chunk, unfinished tail), and the file's size.
  uint64_t dropped_bytes = 0;
  int64_t size_bytes = 0;
  double elapsed_s = 0;
  // Empty, or what went wrong (e.g. the file was unreadable and set aside).
  std::string problem;
};

// OpenTake's question.
struct TakeOpenRequest {
  std::string take_id;
  v1::TakeInfo info;
  std::vector<v1::SensorCalibration> sensors;
  std::string daemon_id;
  // The credential opening the take (common/rpc/auth.h; empty without
  // tokens). A new take is bound to it; only it, or an admin, may resume
  // or add to the take.
  std::string owner{};
  bool owner_is_admin = false;
};

// OpenTake's answer.
struct TakeOpenResult {
  // The recording; null when the take is already COMPLETE (only a repeated
  // CloseTake is then answered).
  std::shared_ptr<TakeRecorder> recorder;
  // Highest durable sequence: the daemon sends durable_sequence + 1 next.
  uint64_t durable_sequence = 0;
  bool resumed = false;
  // The take's row at the time of opening.
  TakeRow row;
};

class TakeStore {
 public:
  // Opens (creating) the data folder, locks it against a second server,
  // opens the catalog and recovers takes left RECORDING. Unavailable or
  // PermissionDenied when the folder is unusable, FailedPrecondition when
  // another process holds it, or the catalog's errors.
  static absl::StatusOr<std::unique_ptr<TakeStore>> Open(
      const TakeStoreOptions& options, std::vector<RecoveredTake>* recovered = nullptr);
  // Shutdown(), then closes the catalog.
  ~TakeStore();
  TakeStore(const TakeStore&) = delete;
  TakeStore& operator=(const TakeStore&) = delete;

  // Opens a new take or resumes one (see ingest_service.proto). `observer`
  // hears the recording's progress and end. Errors: InvalidArgument (bad id,
  // sensors, info; a resume naming other sensors), PermissionDenied (the
  // take belongs to another daemon), Aborted (another stream records it),
  // Unavailable (shutting down, or the disk), DataLoss (the file of an
  // interrupted take cannot be continued).
  absl::StatusOr<TakeOpenResult> OpenTake(const TakeOpenRequest& request,
                                          RecorderObserver* observer);

  // One take, with live progress while it records. NotFound when unknown.
  absl::StatusOr<v1::Take> GetTake(const std::string& take_id) const;
  // Takes in `state` (UNSPECIFIED: all), newest first.
  absl::StatusOr<std::vector<v1::Take>> ListTakes(v1::TakeState state) const;
  // Removes the take's row, then its file; returns the bytes freed.
  // NotFound, or FailedPrecondition while the take records.
  absl::StatusOr<int64_t> DeleteTake(const std::string& take_id);
  // Absolute path of a take's file for reading. NotFound, or
  // FailedPrecondition while the take records.
  absl::StatusOr<std::string> TakeFileForReading(const std::string& take_id) const;
  // Bumped whenever a take's file is reopened for writing; a reader that
  // sees it change knows the bytes it read may mix old and new.
  uint64_t FileGeneration(const std::string& take_id) const;

  // Refuses new takes and interrupts every recording with `reason`, waiting
  // until their files are finished. Idempotent.
  void Shutdown(const absl::Status& reason);

  const std::string& data_dir() const { return options_.data_dir; }
  const FrameSetLimits& limits() const { return options_.limits; }
  Catalog& catalog() { return *catalog_; }

 private:
  TakeStore(TakeStoreOptions options, std::unique_ptr<Catalog> catalog, int lock_fd);
  absl::Status Recover(std::vector<RecoveredTake>* recovered);
  RecoveredTake RecoverTake(TakeRow row);
  absl::StatusOr<TakeOpenResult> CreateTake(const TakeOpenRequest& request,
                                            RecorderObserver* observer);
  absl::StatusOr<TakeOpenResult> ResumeTake(const TakeOpenRequest& request, TakeRow row,
                                            RecorderObserver* observer);
  std::shared_ptr<TakeRecorder> StartRecorder(std::unique_ptr<TakeWriter> writer, TakeRow row,
                                              RecorderObserver* observer);
  void OnRecordingFinished(RecordingResult& result);
  void CatalogLoop();
  // Writes the rows of recording takes that changed since the last call.
  void UpdateCatalog();
  std::string AbsolutePath(const std::string& relative) const;
  TakeWriterOptions WriterOptions() const;
  // The catalog's view overlaid with live progress.
  v1::Take Live(TakeRow row) const;

  const TakeStoreOptions options_;
  std::unique_ptr<Catalog> catalog_;
  int lock_fd_;

  mutable std::mutex mu_;
  std::condition_variable recordings_changed_;
  std::map<std::string, std::shared_ptr<TakeRecorder>> recording_;
  std::set<std::string> opening_;
  std::map<std::string, uint64_t> generations_;
  // updated_unix_ns of the row the catalog last got, per recording take.
  std::map<std::string, int64_t> catalog_updated_ns_;
  // Final rows of takes that ended while the catalog could not be written
  // (a full disk): what readers see instead of the stale row, written by the
  // catalog thread once it can be.
  std::map<std::string, TakeRow> unsaved_;
  // A write failed for want of space and no write has succeeded since
  // (TakeStoreOptions::disk_full_changed).
  bool disk_full_ = false;
  void SetDiskFull(bool full);
  bool shutting_down_ = false;
  bool stop_catalog_ = false;
  std::condition_variable catalog_wake_;
  // Held while writing a recording take's row, so that a periodic update
  // never lands after the final one.
  std::mutex catalog_write_mu_;
  std::thread catalog_thread_;
};

}  // namespace reenact::server
