// The persistent half of the job queue: every job of the server, held in
// memory and written through to the catalog's jobs table
// (server/store/catalog.h, schema version 2). A state change is written at
// once (fsync'ed like every catalog commit); a running job's progress at most
// once per `progress_write_period_s`, so that a worker reporting ten times a
// second costs the disk about one commit a second. Get and List answer from
// memory, with the live progress.
//
// Restarts: RequeueUnfinished() (called once when the server starts) makes
// every job a stopped or crashed server left RUNNING QUEUED again, keeping
// its attempts count; a job that already had `max_attempts` workers is
// FAILED instead, so that a job that brings its machine down is not retried
// for ever.
//
// Thread-safe.
#pragma once

#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <set>
#include <string>
#include <string_view>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "common/base/time.h"
#include "reenact/v1/jobs_service.pb.h"
#include "server/store/catalog.h"

namespace reenact::server {

struct JobStoreOptions {
  // Longest time a running job's progress stays in memory only, seconds.
  double progress_write_period_s = 1.0;
  // Worker starts a job may have; RequeueUnfinished fails it beyond that.
  int max_attempts = 3;

  // InvalidArgument naming the first bad field.
  absl::Status Validate() const;
};

// [A-Za-z0-9_-], 1..64 characters; InvalidArgument otherwise, quoting the id.
absl::Status ValidateJobId(std::string_view job_id);

// True for SUCCEEDED, FAILED and CANCELLED.
bool IsFinished(v1::JobState state);

// Most attempts a job's attempt_history keeps (the oldest go first).
inline constexpr int kMaxAttemptHistory = 16;

// Ends the attempt that runs, if one does, with `outcome` now. `Record` is
// v1::Job or v1::JobPart (a part of a segmented job).
template <typename Record>
void EndAttempt(Record& record, const std::string& outcome) {
  if (record.attempt_history().empty()) return;
  v1::JobAttempt* last =
      record.mutable_attempt_history()->Mutable(record.attempt_history_size() - 1);
  if (last->ended_unix_ns() != 0) return;
  last->set_ended_unix_ns(WallNowNs());
  last->set_outcome(outcome);
}

// Notes a new attempt (number record.attempts(), which the caller has just
// counted) by `worker`, started now.
template <typename Record>
void BeginAttempt(Record& record, const std::string& worker) {
  EndAttempt(record, "ended unseen");
  auto* history = record.mutable_attempt_history();
  if (history->size() >= kMaxAttemptHistory) history->erase(history->begin());
  v1::JobAttempt* attempt = history->Add();
  attempt->set_number(record.attempts());
  attempt->set_worker(worker);
  attempt->set_started_unix_ns(WallNowNs());
}

class JobStore {
 public:
  // Loads the jobs of `catalog`, which must outlive the store. The catalog's
  // errors when it cannot be read.
  static absl::StatusOr<std::unique_ptr<JobStore>> Open(Catalog* catalog,
                                                        const JobStoreOptions& options = {});

  // Stores `job` as a new QUEUED job: assigns job_id ("j-YYYYMMDD-HHMMSS-xxxx",
  // UTC and 4 random hex digits), submitted_unix_ns (now) and clears what a
  // new job cannot have (progress, times, result, attempts). Returns it.
  absl::StatusOr<v1::Job> Insert(v1::Job job);
  // Applies `change` to the stored job atomically and writes the result.
  // NotFound for an unknown id; the catalog's errors leave the job as it was,
  // but for a full disk: then the change holds in memory (so that a job can
  // still fail, visibly, when nothing can be written) and is written with
  // the next write that succeeds; a restart before that forgets it.
  absl::StatusOr<v1::Job> Mutate(const std::string& job_id,
                                 const std::function<void(v1::Job&)>& change);
  // Sets the progress of a job; written to the catalog when the last write
  // of this job is older than the period. NotFound for an unknown id.
  absl::StatusOr<v1::Job> UpdateProgress(const std::string& job_id,
                                         const v1::JobProgress& progress);

  // NotFound for an unknown id.
  absl::StatusOr<v1::Job> Get(const std::string& job_id) const;
  // Removes a finished job from the catalog and the store. NotFound for an
  // unknown id, FailedPrecondition for a job that is not finished.
  absl::Status Delete(const std::string& job_id);
  // Newest first (submitted_unix_ns); `state` UNSPECIFIED and an empty
  // `take_id` do not filter.
  std::vector<v1::Job> List(v1::JobState state = v1::JOB_STATE_UNSPECIFIED,
                            const std::string& take_id = "") const;
  // QUEUED jobs in the order they run: oldest first.
  std::vector<v1::Job> Queued() const;
  // How many jobs are in each state (the metrics endpoint reads it at every
  // scrape, so it copies no job).
  std::map<v1::JobState, int64_t> CountByState() const;
  // QUEUED jobs submitted by `submitter` (Job.submitted_by).
  int64_t CountQueuedBy(const std::string& submitter) const;
  // RUNNING -> QUEUED (attempts kept), or FAILED past max_attempts. Returns
  // the ids queued again, oldest first.
  absl::StatusOr<std::vector<std::string>> RequeueUnfinished();

 private:
  JobStore(Catalog* catalog, const JobStoreOptions& options)
      : catalog_(catalog), options_(options) {}
  std::string NewIdLocked() const;

  Catalog* const catalog_;
  const JobStoreOptions options_;
  mutable std::mutex mu_;
  std::map<std::string, v1::Job> jobs_;
  // Steady-clock time of the last catalog write, per job.
  std::map<std::string, int64_t> written_ns_;
  // Jobs changed in memory that the catalog could not take (a full disk).
  std::set<std::string> unsaved_;
};

}  // namespace reenact::server
