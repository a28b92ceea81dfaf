// Workers as Slurm batch jobs (reenact-server --workers slurm): rather than
// starting worker processes itself, the server submits batch jobs that each
// run one `reenact-worker --once`, which leases one job over the Work service,
// runs it and exits. The launcher keeps enough batch jobs pending for the
// queued jobs, within the limits of its options, and learns from squeue when
// they start and end.
//
// Each batch job is submitted as
//
//   sbatch --parsable --job-name=reenact-worker --output=LOG_DIR/slurm-%j.out
//          [--partition=P] [--account=A] [--time=T] [--mem=M] [--qos=Q]
//          [--cpus-per-task=N] [EXTRA...] --wrap 'COMMAND'
//   COMMAND: exec WORKER --server ADDR --once --wait S
//                 --name "slurm-job-$SLURM_JOB_ID" [--token-file F]
//                 [--tls-ca F] [--scratch D]
//
// with every value shell-quoted (the batch script runs COMMAND through
// /bin/sh, which expands only $SLURM_JOB_ID). A worker's name thus says which
// batch job runs it (BatchJobOf), so that cancelling a job can end its batch
// job.
//
// sbatch, squeue and scancel run as child processes, each for at most
// kSlurmCommandTimeoutS seconds. Their failures are logged and retried
// later with a back-off; none is fatal to the server.
//
// Thread-safe: Reconcile runs on the scheduler's thread; Cancel, the counts
// and Shutdown may come from any thread.
#pragma once

#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "server/jobs/worker_launcher.h"

namespace reenact::server {

// Longest run of one sbatch, squeue or scancel before it is killed.
inline constexpr double kSlurmCommandTimeoutS = 10;
// Shortest time between two squeue runs of Reconcile.
inline constexpr double kSlurmPollPeriodS = 1;
// Longest wait before retrying a command that failed (the wait doubles from
// kSlurmPollPeriodS with each failure in a row).
inline constexpr double kSlurmMaxBackoffS = 60;
// The prefix of the worker names BatchJobOf understands.
inline constexpr char kSlurmWorkerNamePrefix[] = "slurm-job-";

struct SlurmLauncherOptions {
  // sbatch's flags, from the config file; empty (0): not given.
  std::string partition;
  std::string account;
  std::string time_limit;  // --time, e.g. "02:00:00".
  std::string mem;         // --mem, e.g. "8G".
  std::string qos;
  int cpus_per_task = 0;
  // More sbatch flags, one per entry, e.g. "--gres=gpu:1".
  std::vector<std::string> extra_sbatch_args;

  // What the batch job runs, as paths and addresses seen from the nodes.
  std::string worker;          // reenact-worker (required).
  std::string server_address;  // HOST:PORT of the server (required).
  std::string token_file;      // --token-file; empty: none.
  std::string tls_ca;          // --tls-ca; empty: none.
  std::string scratch;         // --scratch; empty: the worker's default.
  double worker_wait_s = 60;   // --wait: how long a worker waits for a job.

  // Where the batch jobs' output goes (slurm-<id>.out); required, made when
  // missing. It must be reachable from the nodes (a shared file system).
  std::string log_dir;

  // Batch jobs submitted and not yet running, and batch jobs in all
  // (pending and running), at most.
  int max_pending = 4;
  int max_jobs = 16;
  // How long a batch job that started running still stands for one of the
  // queued jobs: until its worker has leased that job, the job still counts
  // as queued, and a new batch job for it would be one too many.
  double start_grace_s = 10;

  // The Slurm programs (looked up in PATH when they hold no '/') and extra
  // environment for them (e.g. SLURM_CONF).
  std::string sbatch = "sbatch";
  std::string squeue = "squeue";
  std::string scancel = "scancel";
  std::map<std::string, std::string> env;

  // InvalidArgument naming the first option that is missing or out of
  // range.
  absl::Status Validate() const;
};

// Reads a config file of `key = value` lines; blank lines and lines whose
// first non-blank character is '#' are skipped (a '#' after a value is part
// of it). Keys: partition, account, time, mem, qos, cpus_per_task,
// sbatch_arg (repeatable, one flag each), worker, server, token_file,
// tls_ca, scratch, worker_wait_s, log_dir, max_pending, max_jobs,
// start_grace_s; worker, server and log_dir are required. InvalidArgument
// naming the line and key for an unknown or repeated key or a bad value,
// naming the key for a missing one; NotFound when the file does not exist.
absl::StatusOr<SlurmLauncherOptions> ParseSlurmConfig(const std::string& path);
// As above for the text of a config file; `origin` (the file's path) starts
// every error message.
absl::StatusOr<SlurmLauncherOptions> ParseSlurmConfigText(std::string_view text,
                                                          std::string_view origin);

// `text` as one word for /bin/sh: as it is when it holds only characters
// that need no quoting, else in single quotes (a single quote as '\'').
std::string ShellQuote(std::string_view text);

// The command a batch job runs (COMMAND above).
std::string SlurmWorkerCommand(const SlurmLauncherOptions& options);
// sbatch's arguments, without the program, for one batch job.
std::vector<std::string> SbatchArgs(const SlurmLauncherOptions& options);

class SlurmLauncher final : public WorkerLauncher {
 public:
  // Validates `options`, makes log_dir and checks that sbatch runs
  // (sbatch --version). FailedPrecondition when it does not.
  static absl::StatusOr<std::unique_ptr<SlurmLauncher>> Create(const SlurmLauncherOptions& options);
  // Leaves the batch jobs as they are (Shutdown cancels the pending ones).
  ~SlurmLauncher() override = default;
  SlurmLauncher(const SlurmLauncher&) = delete;
  SlurmLauncher& operator=(const SlurmLauncher&) = delete;

  // Called often (about 10 times a second) from the scheduler's loop with
  // the number of jobs waiting for a worker. At most every kSlurmPollPeriodS
  // it learns the states of its batch jobs from squeue (a batch job squeue
  // no longer lists has ended); then it submits batch jobs while fewer than
  // min(queued, max_pending) are pending and fewer than max_jobs exist. For
  // the comparison with `queued`, batch jobs that started less than
  // start_grace_s ago count as pending. Failures are logged and retried
  // after a back-off. After Shutdown it only follows the batch jobs left,
  // and submits none.
  void Reconcile(int queued) override;

  // The batch job id in a worker name "slurm-job-<id>"; none for other
  // names.
  static std::optional<std::string> BatchJobOf(const std::string& worker_name);

  // scancel of one of this launcher's batch jobs, which then no longer
  // counts. NotFound when `batch_job_id` is not one of them (or it ended
  // already); Unavailable when scancel fails.
  absl::Status Cancel(const std::string& batch_job_id);

  // Batch jobs waiting for a node, running, and submitted since Create.
  int pending() const;
  int running() const;
  int64_t submitted_total() const;

  // scancel of every batch job still pending (a running one finishes or
  // hands its job back), and no submits from then on. Idempotent; a call
  // after a failed scancel tries again.
  void Shutdown() override;

  // Cancel of the batch job of a worker named "slurm-job-<id>" (the
  // scheduler's call when the job it leased is cancelled); others are left.
  void CancelWorker(const std::string& worker_name) override;

 private:
  enum class BatchState { kPending, kRunning };
  struct Batch {
    BatchState state = BatchState::kPending;
    int64_t started_ns = 0;  // When first seen running (steady clock).
  };

  // When to next run a command of one kind, and how long after a failure.
  struct Backoff {
    int64_t next_ns = 0;
    int failures = 0;
    void Succeeded(int64_t now_ns, double period_s);
    // The seconds until the next try.
    double Failed(int64_t now_ns);
  };

  explicit SlurmLauncher(const SlurmLauncherOptions& options) : options_(options) {}

  // squeue for the batch jobs, whose states it updates (an ended one is
  // dropped).
  absl::Status Poll();
  // sbatch of one batch job, which then counts as pending.
  absl::Status Submit();
  // How many batch jobs are in `state`; mu_ is held.
  int CountLocked(BatchState state) const;
  // How many started running less than start_grace_s before `now_ns`; mu_
  // is held.
  int StartingLocked(int64_t now_ns) const;
  // Whether one more batch job is wanted for `queued` jobs; mu_ is held.
  bool WantsBatchLocked(int queued, int64_t now_ns) const;

  const SlurmLauncherOptions options_;
  // Held by Reconcile and Shutdown, so that no submit races the end.
  std::mutex reconcile_mu_;
  Backoff poll_backoff_;    // Guarded by reconcile_mu_.
  Backoff submit_backoff_;  // Guarded by reconcile_mu_.

  mutable std::mutex mu_;
  // Guarded by mu_: the batch jobs that have not ended, by id.
  std::map<std::string, Batch> batches_;
  int64_t submitted_total_ = 0;
  bool shut_down_ = false;
};

}  // namespace reenact::server
