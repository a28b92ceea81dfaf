// The take catalog: an SQLite database in WAL mode beside the take files
// (DATA/catalog.sqlite), indexing them for the Takes service. The files are
// the source of truth: after a crash the take store rebuilds a recording
// take's row from its file. Schema (version Catalog::kSchemaVersion, kept in
// PRAGMA user_version):
//   takes    take_id (key), name, state ('recording' | 'complete' |
//            'interrupted'), daemon_id, created_unix_ns, updated_unix_ns,
//            durable_sequence, frame_set_count, first_stamp_ns,
//            last_stamp_ns, duration_ns, size_bytes, path (relative to the
//            data folder), generator, synthetic, fps
//   sensors  (take_id, sensor_id) key, model, frame_count, lost_stamp_ns,
//            lost_reason; rows go with their take (ON DELETE CASCADE)
//   jobs     job_id (key), take_id, method, options_json (a JSON object of
//            strings), state ('queued' | 'running' | 'succeeded' | 'failed' |
//            'cancelled'), stage, fraction, frames_done, frames_total, eta_s,
//            submitted_unix_ns, started_unix_ns, finished_unix_ns,
//            reenactment_id, error, attempts (version 2; no foreign key: a
//            job's history outlives a deleted take), attempts_json (version
//            4: a JSON list of {number, worker, started_unix_ns,
//            ended_unix_ns, outcome}), segments and parts_json (version 5:
//            a JSON list of {name, state ('waiting' or a job state),
//            attempts, attempt_history, fraction, stage, file_bytes}),
//            submitted_by (version 6: the submitting token's name)
// Every commit is fsync'ed (synchronous=FULL); the store writes a recording
// take's progress about once a second and every state change at once.
#pragma once

#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "proto/state_names.h"
#include "reenact/v1/jobs_service.pb.h"
#include "reenact/v1/takes_service.pb.h"

struct sqlite3;

namespace reenact::server {

// One take as the catalog holds it.
struct TakeRow {
  // What the Takes service lists (ids, state, counts, sensors).
  v1::Take take;
  // The take file, relative to the data folder (e.g. "takes/<id>.mcap").
  std::string path;
  // Stamps of the first and last stored frame sets, host clock, ns (both 0
  // while there are none).
  int64_t first_stamp_ns = 0;
  int64_t last_stamp_ns = 0;
  // The credential that created the take (TakeOpenRequest::owner).
  std::string owner{};
};

// State names: proto/state_names.h (TakeStateName, JobStateName).

class Catalog {
 public:
  static constexpr int kSchemaVersion = 6;

  // Opens (creating when missing) the catalog at `path` and brings its schema
  // to kSchemaVersion. Unavailable when the file cannot be opened or WAL mode
  // cannot be turned on; FailedPrecondition when the file's schema is newer
  // than this build's; DataLoss when it is not a catalog.
  static absl::StatusOr<std::unique_ptr<Catalog>> Open(const std::string& path);
  ~Catalog();
  Catalog(const Catalog&) = delete;
  Catalog& operator=(const Catalog&) = delete;

  // Inserts or replaces the take and its sensors in one transaction.
  absl::Status Put(const TakeRow& row);
  // NotFound when the catalog has no such take.
  absl::StatusOr<TakeRow> Get(std::string_view take_id) const;
  // Takes in `state` (UNSPECIFIED: all), newest first (created_unix_ns).
  absl::StatusOr<std::vector<TakeRow>> List(v1::TakeState state) const;
  // Removes the take and its sensors. NotFound when unknown.
  absl::Status Delete(std::string_view take_id);

  // Inserts or replaces a job (server/jobs/job_store.h writes through here).
  absl::Status PutJob(const v1::Job& job);
  // NotFound when the catalog has no such job.
  absl::StatusOr<v1::Job> GetJob(std::string_view job_id) const;
  // NotFound when there is no such job.
  absl::Status DeleteJob(std::string_view job_id);
  // Every job, newest first (submitted_unix_ns).
  absl::StatusOr<std::vector<v1::Job>> ListJobs() const;

  // PRAGMA user_version and journal_mode as the database reports them.
  absl::StatusOr<int> SchemaVersion() const;
  absl::StatusOr<std::string> JournalMode() const;

 private:
  Catalog(std::string path, sqlite3* db) : path_(std::move(path)), db_(db) {}
  absl::Status Migrate();
  absl::Status Exec(const std::string& sql) const;
  absl::Status Error(const std::string& what) const;
  // Rows matching `where` (binding ?1 to `arg`), newest first, with sensors.
  absl::StatusOr<std::vector<TakeRow>> Query(const std::string& where,
                                             std::optional<std::string_view> arg) const;
  absl::Status LoadSensors(TakeRow* row) const;
  // Jobs matching `where` (binding ?1 to `arg`), newest first.
  absl::StatusOr<std::vector<v1::Job>> QueryJobs(const std::string& where,
                                                 std::optional<std::string_view> arg) const;

  std::string path_;
  sqlite3* db_;
  mutable std::mutex mu_;  // One connection, one statement at a time.
};

}  // namespace reenact::server
