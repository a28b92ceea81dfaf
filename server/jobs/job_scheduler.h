// The active half of the job queue: hands QUEUED jobs (server/jobs/
// job_store.h) to workers, oldest first, and tells watchers about every
// change.
//
// Every job runs under a Work lease (proto/reenact/v1/work_service.proto;
// job_leases.cc), whoever its worker is: one of the server's own
// (--workers local:N: LocalWorkers, server/jobs/local_workers.h, at most
// `concurrency` at a time, sharing the slots with live follows) or a network
// worker (reenact-worker --server on any machine, a Slurm batch job started
// by a WorkerLauncher, a Kubernetes pod). Both run the same agent
// (server/worker/work_agent.h): it leases the job (RUNNING, attempts + 1, a
// new entry in attempt_history), runs it as a child process in a scratch
// folder of its own, with the worker's one-job command line and JSON lines
// (worker_protocol.h), and relays progress and log lines by heartbeat. The
// scheduler computes the ETA (eta.h), stores the progress (the store
// throttles its writes), appends the log lines to DATA/jobs/<job_id>/
// worker.log and publishes a JobEvent.
//
// The end of an attempt: an upload -> ReenactmentStore::Add(rid) ->
// SUCCEEDED with reenactment_id (FAILED when the file does not validate); a
// Fail -> FAILED with the worker's reason ("worker killed by signal 11
// (SIGSEGV); last log: ..."), or queued again when the worker gives the job
// back; no heartbeat within `lease_ttl_s` -> queued again, first in line
// (FAILED after store.max_attempts attempts). An upload of an attempt whose
// lease ended is refused, so each attempt stores at most one reenactment.
//
// Cancel: a QUEUED job is CANCELLED at once; so is a RUNNING one, whose
// lease ends: its worker stops the job at its next heartbeat (SIGTERM,
// SIGKILL after the grace period) and a launcher's batch job is cancelled.
// Shutdown: the server's own workers stop their jobs, which stay RUNNING in
// the store, so that the next start queues them again (JobStore::
// RequeueUnfinished, attempts kept); network workers find their leases gone.
//
// Live jobs (SubmitJobRequest.live, a method whose spec says live) on a
// take still RECORDING: the
// job becomes RUNNING at once, in stage "following", and the live hub
// (server/live/live_hub.h) follows the take for it; its progress counts the
// frame sets followed (frames_done). When the take stops recording the
// same job is leased to a worker on the stored take, before the queued jobs
// (a new attempt; the method's live-only options, MethodSpec, are not
// passed to the worker), and ends SUCCEEDED with its reenactment as usual.
// A live fit that cannot start fails the job. A live job of a take that is
// not recording simply runs offline. Cancel stops the follow at once. After
// a restart a live job left RUNNING runs offline.
//
// Segmented jobs (SubmitJobRequest.segments = N > 1, a method whose spec is
// segmentable; server/jobs/job_parts.cc): one take split across several
// workers. The job's parts (Job.parts) are queued and leased like jobs, each
// with its own attempts: "prepare" first (the method's state from the whole
// take, e.g. the body's shape), then "segment-1" .. "segment-N" all at once,
// then "stitch", whose upload is the job's reenactment. A part's upload is
// kept in DATA/jobs/<job_id>/parts/<part>.part and streamed to the parts
// after it as their inputs (ReadTake with `input`). A part that fails fails
// the job (and ends its other parts' leases); one whose lease expires is
// queued again, first in line, up to store.max_attempts attempts. Cancel
// ends every lease of the job. After a restart the parts that ran are
// queued again and the parts that finished are kept.
//
// Thread-safe. One scheduler thread serves waiting Lease calls, expires
// leases, asks the launcher for workers and sweeps old jobs; a second one
// indexes finished reenactments and publishes lease events.
#pragma once

#include <array>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <set>
#include <string>
#include <string_view>
#include <thread>
#include <utility>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "common/base/thread_pool.h"
#include "common/methods/method_spec.h"
#include "reenact/v1/jobs_service.pb.h"
#include "reenact/v1/work_service.pb.h"
#include "server/jobs/job_store.h"
#include "server/jobs/live_jobs.h"
#include "server/jobs/worker_launcher.h"
#include "server/live/live_hub.h"
#include "server/store/reenactment_store.h"
#include "server/store/take_store.h"
#include "server/worker/eta.h"

namespace reenact::server {

struct JobSchedulerOptions {
  // The worker program; empty: reenact-worker beside the running program
  // (dirname(/proc/self/exe)/reenact-worker).
  std::string worker_path;
  // Workers running at a time; 0: std::thread::hardware_concurrency().
  int concurrency = 0;
  // The methods Submit accepts, with their options (reenact-server: the
  // registry, server/recon/registry.h). Submit checks a job's options
  // against them (names, types, bounds). Empty: no job is accepted.
  std::vector<methods::MethodSpec> methods;
  // A deeper check of a job that Submit runs after the spec's (reenact-
  // server: recon::CheckJob, the method's Validate() and its CheckAssets
  // against the server's --assets, so that a model no worker could find
  // fails now, not after the queue); empty: none.
  std::function<absl::Status(const std::string& method,
                             const std::map<std::string, std::string>& options)>
      check_job;
  // How often the scheduler looks at leases and waiting Lease calls, and
  // the server's own workers at their jobs' processes, seconds.
  double poll_period_s = 0.1;
  // The server's own workers: a cancelled job's process gets SIGTERM, then
  // SIGKILL after this long, seconds.
  double cancel_grace_s = 5.0;
  // The same at server shutdown.
  double shutdown_grace_s = 2.0;
  // Window over which the ETA measures the rate of progress, seconds.
  double eta_window_s = 10.0;
  // Finished jobs older than this (by finish time) lose their folder (the
  // worker's log and progress) and their row; their reenactments stay.
  // Looked at on start and every retention_sweep_period_s. 0: kept forever.
  double job_retention_days = 30.0;
  double retention_sweep_period_s = 3600.0;
  // The store's throttle and retry limit.
  JobStoreOptions store;
  // Folders of body-model assets (reenact-server --assets): the option
  // model=makehuman:NAME names a folder in one of them. Passed on to the
  // workers (check_job checks a job's options against them at Submit).
  std::vector<std::string> asset_roots;
  // Submit refuses a job (RESOURCE_EXHAUSTED, "disk is full") while the
  // jobs folder's file system has fewer free bytes than this: a job needs
  // its row, its folder, its log and then its reenactment. 0: no check
  // beyond the store's own write errors.
  int64_t min_free_bytes = int64_t{1} << 20;
  // Submit refuses a job (RESOURCE_EXHAUSTED) while this many wait in the
  // queue (--max-queued-jobs): a client in a loop cannot grow the catalog
  // and the jobs folder without bound.
  int max_queued_jobs = 1000;
  // The same for the jobs of one token (--max-queued-jobs-per-token), so
  // that one coach's loop cannot fill the queue for every other; the
  // anonymous caller of a server without tokens has only the bound above.
  int max_queued_jobs_per_token = 100;
  // The memory one job may take, MiB (--job-memory-mb): Submit refuses a
  // job whose estimate (`job_memory`) is over it (RESOURCE_EXHAUSTED,
  // naming both), and the server's own workers run every job under it
  // (reenact-worker --memory-limit-mb). -1: the jobs that run at once share
  // three quarters of the machine's memory, at least 1024 MiB each; 0: no
  // budget.
  int64_t job_memory_mb = -1;
  // A job's estimated memory, bytes, on take `take` (reenact-server:
  // recon::JobMemoryBytes); empty: no estimate, only the workers' limit.
  std::function<absl::StatusOr<int64_t>(const std::string& method,
                                        const std::map<std::string, std::string>& options,
                                        const v1::Take& take)>
      job_memory;
  // Whether the server runs workers of its own (reenact-server --workers
  // local:N; the N is `concurrency`). False (--workers none): queued jobs
  // wait for workers that lease them over the Work service; `concurrency`
  // then only bounds live jobs.
  bool local_workers = true;
  // A Work lease ends this long after its worker's last heartbeat (or
  // upload chunk), seconds; the job is then queued again (FAILED once it
  // had store.max_attempts attempts). Workers are asked to beat six times
  // as often, and at least every 2 s.
  double lease_ttl_s = 30.0;
  // Starts network workers for queued jobs (with local_workers false);
  // null: workers come by themselves.
  std::shared_ptr<WorkerLauncher> launcher;

  // InvalidArgument naming the first bad field.
  absl::Status Validate() const;
};

// Gets a watched job's events. `last` is true on the final call: the job
// ended (`end` OK) or the scheduler shut down (`end` Unavailable). Called
// from the scheduler's threads (and once from Watch itself) with a lock held
// that Unwatch takes: it must not block, nor call Watch or Unwatch.
using JobEventCallback =
    std::function<void(const v1::JobEvent& event, bool last, const absl::Status& end)>;

// Most segments a job may be split into.
inline constexpr int kMaxSegments = 64;
// The unit of work of a job's part ("JOB/PART"), and the job's own (its id,
// `part` empty); SplitUnit undoes it.
std::string UnitId(const std::string& job_id, const std::string& part);
std::pair<std::string, std::string> SplitUnit(const std::string& unit);
// The parts of a job split into `segments`: prepare (QUEUED), segment-1 ..
// segment-N and stitch (waiting).
std::vector<v1::JobPart> NewParts(int segments);

// Worker names this server gives its own workers ("local-1", ...): their
// leases share the --jobs slots with live follows.
inline constexpr char kLocalWorkerPrefix[] = "local-";
bool IsLocalWorkerName(std::string_view name);

class JobScheduler {
 public:
  // Makes `jobs_dir`, queues again what a previous server left RUNNING, and
  // starts running QUEUED jobs. The stores must outlive the scheduler; the
  // live hub (null: no live jobs of recording takes) too, and it must be
  // shut down before the scheduler is destroyed.
  static absl::StatusOr<std::unique_ptr<JobScheduler>> Start(const JobSchedulerOptions& options,
                                                             const std::string& jobs_dir,
                                                             JobStore* jobs, TakeStore* takes,
                                                             ReenactmentStore* reenactments,
                                                             LiveHub* live = nullptr);
  // Shutdown().
  ~JobScheduler();
  JobScheduler(const JobScheduler&) = delete;
  JobScheduler& operator=(const JobScheduler&) = delete;

  // Queues a job (a live job of a recording take starts following it).
  // InvalidArgument for a malformed take id, an unknown method or bad
  // options (an option "live", or live with a method that cannot follow a
  // take); NotFound for an unknown take; FailedPrecondition for a take still
  // recording, unless the job is live and the server has a live hub;
  // Unavailable after Shutdown, or while the take is being opened.
  // `submitter`: the caller's token name (Job.submitted_by; empty: the
  // anonymous caller of a server without tokens). ResourceExhausted past
  // max_queued_jobs, past max_queued_jobs_per_token for a named submitter,
  // or for a job estimated over the memory budget.
  absl::StatusOr<v1::Job> Submit(const v1::SubmitJobRequest& request,
                                 const std::string& submitter = {});
  // Cancels a QUEUED job, a live job that follows its take, or a RUNNING
  // job, whose lease ends (its worker stops it at its next heartbeat; a
  // launcher's batch job is cancelled too); returned CANCELLED. A finished job is returned as it
  // is. NotFound / InvalidArgument for unknown or malformed ids.
  absl::StatusOr<v1::Job> Cancel(const std::string& job_id);
  absl::StatusOr<v1::Job> Get(const std::string& job_id) const;
  std::vector<v1::Job> List(v1::JobState state, const std::string& take_id) const;
  // The methods Submit accepts (JobSchedulerOptions::methods).
  const std::vector<methods::MethodSpec>& methods() const { return options_.methods; }
  // FailedPrecondition naming a job of `take_id` that is queued or running
  // (a take is not deleted under a job that reads it).
  absl::Status CheckNoUnfinishedJobs(const std::string& take_id) const;
  // Deletes every finished job of `take_id`: its worker folder and its row.
  // Returns the bytes freed.
  absl::StatusOr<int64_t> DeleteJobsOfTake(const std::string& take_id);
  // Deletes the folder and row of every job that finished before
  // `cutoff_unix_ns`. Returns how many went; the first error ends the sweep.
  absl::StatusOr<int> DeleteJobsFinishedBefore(int64_t cutoff_unix_ns);

  // Calls `callback` with the job now, then on every change until the job
  // ends. Returns a watch id for Unwatch (0 when the job had already ended:
  // the one call had last = true). NotFound / InvalidArgument as Get.
  absl::StatusOr<uint64_t> Watch(const std::string& job_id, JobEventCallback callback);
  // Stops the calls of a watch; none is running or comes once it returns.
  void Unwatch(uint64_t watch_id);

  // Stops the workers (their jobs stay RUNNING for the next start), ends
  // every watch with Unavailable, refuses new jobs. Idempotent.
  void Shutdown();

  // The Work service (proto/reenact/v1/work_service.proto), for workers that
  // connect over the network (server/jobs/job_leases.cc). A lease is one
  // attempt of a job: it holds a job slot of its own, not one of the local
  // ones, until the upload is committed, the worker fails it, the job is
  // cancelled or the lease expires. Every call but Lease answers Aborted
  // for a lease that no longer holds (the worker stops and forgets the job).
  using LeaseDone = std::function<void(absl::StatusOr<v1::LeaseResponse>)>;
  // Leases the oldest queued job of one of request.methods (all when empty):
  // at once, or when one is queued within wait_s (at most 60 s); else an
  // empty response. Calls `done` exactly once, from this thread or the
  // scheduler's, without a lock held. FailedPrecondition for an unknown
  // protocol version, Unavailable while shutting down. `holder` names the
  // worker's credential (its token's name; empty: the anonymous caller of a
  // server without tokens): the lease is bound to it (CheckLeaseHolder).
  void Lease(const v1::LeaseRequest& request, const std::string& holder, LeaseDone done);
  // OK when lease `lease_id` is held and was given to credential `holder`;
  // PermissionDenied when another credential holds it (a worker may not
  // beat, read, upload or fail another's lease, whatever its id), Aborted
  // when it is not held. The Work service asks before every call that
  // names a lease.
  absl::Status CheckLeaseHolder(const std::string& lease_id, const std::string& holder) const;
  // No more leases from now on (the server stops its own workers before
  // the rest); the other Work calls still answer.
  void StopLeasing();
  // The take file of a lease's job (`input` empty) or one of the lease's
  // inputs (WorkLease.inputs: parts of a segmented job), to stream to its
  // worker. NotFound for an input the lease does not list.
  absl::StatusOr<std::string> LeasedTakePath(const std::string& lease_id,
                                             const std::string& input = "") const;
  // A folder for files the server makes for one of the lease's reads (a
  // take selection): the job's own folder, made if missing, deleted with
  // the job. Aborted when the lease is not held.
  absl::StatusOr<std::string> LeaseScratchDir(const std::string& lease_id) const;
  // Adds `bytes` streamed to the lease's worker to its attempt
  // (JobAttempt.read_bytes); nothing when the lease is no longer held.
  void CountRead(const std::string& lease_id, int64_t bytes);
  // Renews the lease, sets the job's progress (with the ETA) and passes the
  // log lines to its watchers.
  absl::StatusOr<v1::HeartbeatResponse> Heartbeat(const v1::HeartbeatRequest& request);
  // Claims the attempt's one upload and renews the lease: the path to write
  // the reenactment to (beside where it is stored). Aborted when the lease
  // does not hold or an upload was already claimed.
  absl::StatusOr<std::string> BeginUpload(const std::string& lease_id);
  // Renews the lease of an upload under way; Aborted when it expired.
  absl::Status ContinueUpload(const std::string& lease_id);
  // Stores the uploaded file as the job's reenactment (it is read and
  // validated) and ends the lease: the job SUCCEEDED, or FAILED with
  // InvalidArgument when the file is no valid reenactment. Aborted when the
  // lease expired meanwhile (the file is deleted, nothing is stored).
  absl::StatusOr<v1::Job> CommitUpload(const std::string& lease_id);
  // Gives a claimed upload back (the stream broke): the worker may upload
  // again while the lease holds. Deletes what was written.
  void AbortUpload(const std::string& lease_id);
  // Ends the lease with the job FAILED (CANCELLED when a cancel was asked).
  absl::StatusOr<v1::Job> FailLease(const v1::FailRequest& request);

  int concurrency() const { return concurrency_; }
  // The memory budget of one job, MiB (JobSchedulerOptions::job_memory_mb
  // resolved); 0: none.
  int64_t job_memory_mb() const { return job_memory_mb_; }
  const std::string& worker_path() const { return worker_path_; }

 private:
  // A leased job: one attempt, held by one worker (the server's own or one
  // over the network).
  struct Running {
    std::string job_id;
    // A part of a segmented job (JobPart.name); empty: the whole job. Its
    // unit (the key of running_ and the queue): UnitId(job_id, part).
    std::string part;
    // The names of the parts the lease reads (WorkLease.inputs).
    std::vector<std::string> inputs;
    // Its last reported fraction (a segmented job's progress sums them).
    double fraction = 0.0;
    std::string reenactment_id;
    std::string out_path;
    // The Work lease; all guarded by mu_.
    std::string lease_id;
    // One of this server's own workers (they share its job slots).
    bool local = false;
    std::string worker_name;
    // The credential the lease was given to (CheckLeaseHolder).
    std::string holder;
    // Steady time the lease ends unless renewed.
    int64_t expires_ns = 0;
    // The ETA from the worker's heartbeats.
    std::optional<EtaEstimator> eta;
    // The upload claimed (BeginUpload), and where it is written.
    bool uploading = false;
    std::string upload_path;
  };

  JobScheduler(const JobSchedulerOptions& options, std::string jobs_dir, JobStore* jobs,
               TakeStore* takes, ReenactmentStore* reenactments, LiveHub* live);
  void Loop();
  // DeleteJobsFinishedBefore(now - job_retention_days), at most once a
  // retention_sweep_period_s.
  void SweepRetention();
  // The folder and row of one finished job; the bytes freed.
  absl::StatusOr<int64_t> DeleteFinishedJob(const v1::Job& job);
  // Job slots in use: leases of this server's own workers and live follows
  // (leases to workers over the network hold slots of their own).
  int BusyLocked() const { return local_leases_ + live_jobs_.FollowingLocked(); }
  // Work leases (job_leases.cc). Answers waiting Lease calls with queued
  // jobs, and empty ones past their wait.
  void ServeLeaseWaiters();
  // Takes the first queued job (a handoff first when this server has no
  // local workers) that one of `methods` runs, RUNNING under a new lease.
  // mu_ held.
  std::optional<v1::WorkLease> LeaseQueuedLocked(const std::set<std::string>& methods,
                                                 const std::string& worker_name,
                                                 const std::string& holder);
  // Queues again (or fails) the jobs of leases past their time.
  void ExpireLeases();
  // Queues a released lease's job again, first in line, or fails it when it
  // had store.max_attempts attempts (`outcome`: how this attempt ended, in
  // its history; `why`: what stopped it, for the error).
  void Requeue(const Running& run, const std::string& outcome, const std::string& why);
  // The Running of a lease that holds; Aborted otherwise. mu_ held.
  absl::StatusOr<Running*> HeldLeaseLocked(const std::string& lease_id) const;
  // Removes a lease and its Running. mu_ held.
  std::unique_ptr<Running> ReleaseLocked(const std::string& lease_id);
  // Answers the waiting Lease calls with Unavailable at shutdown.
  void EndLeaseWaiters();
  // Appends to the job's worker.log (in its folder, made when missing).
  void AppendWorkerLog(const std::string& job_id, const std::vector<std::string>& lines);
  // Marks a queued job RUNNING with a Running entry; false when it is no
  // longer queued. mu_ held.
  bool StartQueuedLocked(const std::string& job_id, const std::string& worker = "local");
  // The same for a live job whose follow ended (it is RUNNING already).
  bool StartHandoffLocked(const std::string& job_id, const std::string& worker = "local");
  // Segmented jobs (job_parts.cc). A part's lease: marks the QUEUED part
  // RUNNING (the job too), with a Running under its unit; false when it is
  // no longer queued. mu_ held.
  bool StartPartLocked(const std::string& job_id, const std::string& part,
                       const std::string& worker);
  // The WorkLease fields of a part: its name and inputs (names and sizes);
  // fills run.inputs and run.out_path. mu_ held.
  absl::Status FillPartLeaseLocked(const v1::Job& job, Running& run, v1::WorkLease& lease);
  // Where a part's upload is kept.
  std::string PartPath(const std::string& job_id, const std::string& part) const;
  // Queues the parts whose predecessors all succeeded (the segments after
  // prepare, the stitch after every segment), first in line. mu_ held.
  void AdvancePartsLocked(const std::string& job_id);
  // A part's upload was stored at its path: the part SUCCEEDED, the next
  // parts queued.
  absl::StatusOr<v1::Job> CompletePart(const Running& run, int64_t file_bytes);
  // Queues a released part again (or fails the job past max_attempts).
  void RequeuePart(const Running& run, const std::string& outcome, const std::string& why);
  // The part failed on its worker: it FAILED, and the job with it.
  void FailPart(const Running& run, const std::string& error, std::vector<std::string> logs);
  // The job's progress from its parts' states and running fractions.
  v1::JobProgress SegmentedProgressLocked(const v1::Job& job) const;
  // Takes every unit of the job out of the queue and ends the leases of
  // its running ones; returns their workers. mu_ held.
  std::vector<std::string> DropUnitsLocked(const std::string& job_id);
  // Indexes the reenactment of a worker that exited 0 and ends its job.
  void Succeed(const std::string& job_id, const std::string& reenactment_id);
  // Writes the job's end and tells its watchers (their last event).
  void EndJob(const std::string& job_id, v1::JobState state, const std::string& error,
              const std::string& reenactment_id = "", std::vector<std::string> logs = {});
  // Tells the job's watchers; `last` ends their watches.
  void Publish(const v1::Job& job, std::vector<std::string> logs, bool last);

  const JobSchedulerOptions options_;
  // `text` with the server's data folder written "DATA" (job errors and
  // worker log lines reach clients).
  std::string WithoutServerPaths(std::string text) const;
  const std::string jobs_dir_;
  JobStore* const jobs_;
  TakeStore* const takes_;
  ReenactmentStore* const reenactments_;
  int concurrency_ = 1;
  int64_t job_memory_mb_ = 0;
  std::string worker_path_;

  mutable std::mutex mu_;
  std::condition_variable wake_;
  bool wake_pending_ = false;
  // Steady time of the last retention sweep (0: none yet).
  int64_t last_sweep_ns_ = 0;
  bool stopping_ = false;
  // Units waiting for a worker: job ids, and UnitId(job, part) for the
  // parts of segmented jobs.
  std::deque<std::string> queue_;
  // Live jobs following their take, and those whose take ended, waiting
  // for a worker slot (guarded by mu_).
  LiveJobs live_jobs_;
  // Leased units (see queue_) -> their attempt.
  std::map<std::string, std::unique_ptr<Running>> running_;
  // Work leases: lease id -> unit (their Running is in running_).
  std::map<std::string, std::string> leases_;
  // Leases held by this server's own workers (guarded by mu_).
  int local_leases_ = 0;
  bool leasing_stopped_ = false;
  // Lease calls waiting for a job, oldest first.
  struct LeaseWaiter {
    std::set<std::string> methods;
    std::string worker_name;
    std::string holder;
    int64_t deadline_ns = 0;
    LeaseDone done;
  };
  std::deque<LeaseWaiter> lease_waiters_;
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
