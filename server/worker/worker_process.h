// One attempt of a job's worker process (server/jobs/job_scheduler.h): its
// files in the job's folder, its progress as it writes it (worker_protocol.h,
// eta.h), its exit, and its stop with a grace period. Used by one thread.
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "common/base/subprocess.h"
#include "reenact/v1/jobs_service.pb.h"
#include "server/worker/eta.h"
#include "server/worker/worker_protocol.h"

namespace reenact::server {

class WorkerProcess {
 public:
  // Starts `args` in the job's folder `dir` with stdout into
  // dir/progress.jsonl (new for each attempt) and stderr appended to
  // dir/worker.log, after the line `log_header` (earlier attempts' lines
  // are not quoted: LastLog reads from there). `progress`: the job's
  // progress, which the worker's lines then change; `eta_window_s`: the
  // ETA's window. The error of Subprocess::Start when it cannot start.
  static absl::StatusOr<std::unique_ptr<WorkerProcess>> Start(const std::vector<std::string>& args,
                                                              const std::string& dir,
                                                              const std::string& log_header,
                                                              v1::JobProgress progress,
                                                              double eta_window_s);
  WorkerProcess(const WorkerProcess&) = delete;
  WorkerProcess& operator=(const WorkerProcess&) = delete;

  // The exit once the worker ended, without blocking.
  std::optional<ExitInfo> Poll() { return process_->Poll(); }
  // Reads what the worker appended to its stdout; true when the progress
  // changed (its ETA then too). New log lines go to `logs`.
  bool ReadOutput(std::vector<std::string>* logs);

  // Cancel, called at every poll while it is under way: SIGTERM at the
  // first call, SIGKILL at the first one `grace_s` after it.
  void Cancel(double grace_s);

  // The job's progress with the worker's lines and the ETA.
  const v1::JobProgress& progress() const { return output_.report().progress; }
  // The worker's {"error"} message; empty when it gave none.
  const std::string& error() const { return output_.report().error; }
  // All its lines said (progress, error, result).
  const WorkerReport& report() const { return output_.report(); }
  // The line a failed job quotes: the worker's last stderr line of this
  // attempt, else its last log line (LastWorkerLog).
  std::string LastLog() const;
  // Why a worker that exited with `exit` (not 0) failed, for the job's
  // error: its {"error"} message, else what its exit says with LastLog().
  std::string FailureText(const ExitInfo& exit) const;

 private:
  WorkerProcess(std::unique_ptr<Subprocess> process, std::string log_path, int64_t log_offset,
                WorkerOutputReader output, double eta_window_s);

  std::unique_ptr<Subprocess> process_;
  const std::string log_path_;
  // Size of worker.log when this attempt began.
  const int64_t log_offset_;
  WorkerOutputReader output_;
  EtaEstimator eta_;
  bool term_sent_ = false;
  bool kill_sent_ = false;
  int64_t kill_at_ns_ = 0;
};

}  // namespace reenact::server
