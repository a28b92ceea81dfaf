// The active half of the job queue: runs QUEUED jobs (server/jobs/job_store.h)
// in worker processes, at most `concurrency` at a time, oldest first, and
// tells watchers about every change.
//
// A job's run: the scheduler marks it RUNNING (attempts + 1), makes
// DATA/jobs/<job_id>/ and starts (common/base/subprocess.h)
//
//   WORKER --take <take file> --method M --options-json '{"k":"v"}'
//          --out <ReenactmentStore::PathFor(rid)> --reenactment-id rid
//          --take-id T --job-id J
//
// with stdout into DATA/jobs/<job_id>/progress.jsonl (new for each attempt)
// and stderr appended to DATA/jobs/<job_id>/worker.log. The worker writes one
// JSON object per line on stdout:
//   {"stage":"register","fraction":0.42,"frames_done":120,"frames_total":300}
//   {"log":"text"}                       a log line for watchers
//   {"result":{...figures...}}           at the end of a success
//   {"error":"message"}                  at the end of a failure
// and exits 0 (success), 1 (failure), 2 (usage) or 3 (stopped by SIGTERM).
// Any other line is passed on as a log line. Every `poll_period_s` the
// scheduler reads what the running workers appended, updates the store (the
// store throttles its writes) and publishes a JobEvent (the job and the new
// log lines). ETA: the rate of the fraction over the last `eta_window_s`
// seconds, (1 - fraction) / rate; -1 while unknown.
//
// The end of a worker: exit 0 -> ReenactmentStore::Add(rid) -> SUCCEEDED with
// reenactment_id (FAILED when the file does not validate); exit 1 -> FAILED
// with the worker's {"error"}; killed by a signal -> FAILED "worker killed by
// signal 11 (SIGSEGV); last log: ..."; any other end -> FAILED naming it. A
// failed worker's output file is removed. A worker never affects the server.
//
// Cancel: a QUEUED job is CANCELLED at once; a RUNNING one gets SIGTERM, and
// SIGKILL after `cancel_grace_s`, then is CANCELLED. Shutdown: every worker
// gets SIGTERM, SIGKILL after `shutdown_grace_s`, and its job stays RUNNING
// in the store, so that the next start queues it again (JobStore::
// RequeueUnfinished, attempts kept: the new run counts one more).
//
// Thread-safe. One scheduler thread polls and starts workers; a second one
// indexes finished reenactments so that a large file does not hold up the
// progress of the other jobs.
#pragma once

#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "common/base/subprocess.h"
#include "common/base/thread_pool.h"
#include "reenact/v1/jobs_service.pb.h"
#include "server/jobs/job_store.h"
#include "server/jobs/methods_list.h"
#include "server/store/reenactment_store.h"
#include "server/store/take_store.h"

namespace reenact::server {

struct JobSchedulerOptions {
  // The worker program; empty: reenact-worker beside the running program
  // (dirname(/proc/self/exe)/reenact-worker).
  std::string worker_path;
  // Workers running at a time; 0: std::thread::hardware_concurrency().
  int concurrency = 0;
  // Method names Submit accepts (server/jobs/methods_list.h).
  std::vector<std::string> methods = JobMethodNames();
  // How often running workers' output and exits are looked at, seconds.
  double poll_period_s = 0.1;
  // Cancel of a running job: SIGTERM, then SIGKILL after this long, seconds.
  double cancel_grace_s = 5.0;
  // Server shutdown: SIGTERM to every worker, SIGKILL after this long.
  double shutdown_grace_s = 2.0;
  // Window over which the ETA measures the rate of progress, seconds.
  double eta_window_s = 10.0;
  // The store's throttle and retry limit.
  JobStoreOptions store;

  // InvalidArgument naming the first bad field.
  absl::Status Validate() const;
};

// Gets a watched job's events. `last` is true on the final call: the job
// ended (`end` OK) or the scheduler shut down (`end` Unavailable). Called
// from the scheduler's threads (and once from Watch itself) with a lock held
// that Unwatch takes: it must not block, nor call Watch or Unwatch.
using JobEventCallback =
    std::function<void(const v1::JobEvent& event, bool last, const absl::Status& end)>;

class JobScheduler {
 public:
  // Makes `jobs_dir`, queues again what a previous server left RUNNING, and
  // starts running QUEUED jobs. The stores must outlive the scheduler.
  static absl::StatusOr<std::unique_ptr<JobScheduler>> Start(const JobSchedulerOptions& options,
                                                             const std::string& jobs_dir,
                                                             JobStore* jobs, TakeStore* takes,
                                                             ReenactmentStore* reenactments);
  // Shutdown().
  ~JobScheduler();
  JobScheduler(const JobScheduler&) = delete;
  JobScheduler& operator=(const JobScheduler&) = delete;

  // Queues a job. InvalidArgument for a malformed take id, an unknown
  // method or bad options; NotFound for an unknown take; FailedPrecondition
  // for a take still recording; Unavailable after Shutdown.
  absl::StatusOr<v1::Job> Submit(const v1::SubmitJobRequest& request);
  // Cancels a QUEUED job (returned CANCELLED) or starts stopping a RUNNING
  // one (returned RUNNING; Watch tells when it is CANCELLED). A finished job
  // is returned as it is. NotFound / InvalidArgument for unknown or
  // malformed ids.
  absl::StatusOr<v1::Job> Cancel(const std::string& job_id);
  absl::StatusOr<v1::Job> Get(const std::string& job_id) const;
  std::vector<v1::Job> List(v1::JobState state, const std::string& take_id) const;

  // Calls `callback` with the job now, then on every change until the job
  // ends. Returns a watch id for Unwatch (0 when the job had already ended:
  // the one call had last = true). NotFound / InvalidArgument as Get.
  absl::StatusOr<uint64_t> Watch(const std::string& job_id, JobEventCallback callback);
  // Stops the calls of a watch; none is running or comes once it returns.
  void Unwatch(uint64_t watch_id);

  // Stops the workers (their jobs stay RUNNING for the next start), ends
  // every watch with Unavailable, refuses new jobs. Idempotent.
  void Shutdown();

  int concurrency() const { return concurrency_; }
  const std::string& worker_path() const { return worker_path_; }

 private:
  struct Running;

  JobScheduler(const JobSchedulerOptions& options, std::string jobs_dir, JobStore* jobs,
               TakeStore* takes, ReenactmentStore* reenactments);
  void Loop();
  // Starts queued jobs while slots are free.
  void StartQueued();
  // Starts the worker of `job_id`, which StartQueued marked RUNNING.
  void Launch(const std::string& job_id);
  // Reads the workers' output, publishes progress, signals cancelled ones
  // and ends those that exited.
  void PollRunning();
  // Reads what `run` appended to its progress file; true when the progress
  // changed. New log lines go to `logs`.
  bool ReadOutput(Running& run, std::vector<std::string>* logs);
  // One line of worker output; true when it was progress.
  bool HandleLine(Running& run, const std::string& line, std::vector<std::string>* logs);
  void UpdateEta(Running& run) const;
  // Ends the job of a worker that exited (`logs`: its last log lines).
  void Finish(std::unique_ptr<Running> run, const ExitInfo& exit, std::vector<std::string> logs);
  // Indexes the reenactment of a worker that exited 0 and ends its job.
  void Succeed(const std::string& job_id, const std::string& reenactment_id);
  // Writes the job's end and tells its watchers (their last event).
  void EndJob(const std::string& job_id, v1::JobState state, const std::string& error,
              const std::string& reenactment_id = "", std::vector<std::string> logs = {});
  // Stops every worker at shutdown, leaving their jobs RUNNING (CANCELLED
  // when a cancel was under way; SUCCEEDED when it finished meanwhile).
  void StopWorkers();
  // Tells the job's watchers; `last` ends their watches.
  void Publish(const v1::Job& job, std::vector<std::string> logs, bool last);
  // The worker's last stderr line of this attempt (else its last log line),
  // quoted in a failed job's error.
  std::string LastLog(const Running& run) const;

  const JobSchedulerOptions options_;
  const std::string jobs_dir_;
  JobStore* const jobs_;
  TakeStore* const takes_;
  ReenactmentStore* const reenactments_;
  int concurrency_ = 1;
  std::string worker_path_;

  mutable std::mutex mu_;
  std::condition_variable wake_;
  bool wake_pending_ = false;
  bool stopping_ = false;
  std::deque<std::string> queue_;
  std::map<std::string, std::unique_ptr<Running>> running_;
  std::thread thread_;
  // Indexes finished reenactments (ReenactmentStore::Add reads the file).
  std::unique_ptr<ThreadPool> finisher_;

  // Held while calling watch callbacks (see JobEventCallback).
  std::mutex watch_mu_;
  struct Watcher {
    std::string job_id;
    JobEventCallback callback;
  };
  std::map<uint64_t, Watcher> watchers_;
  uint64_t next_watch_id_ = 1;
  bool watches_closed_ = false;
  std::once_flag shutdown_once_;
};

}  // namespace reenact::server
