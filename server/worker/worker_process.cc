#include "server/worker/worker_process.h"

#include <signal.h>
#include <string.h>

#include <filesystem>
#include <fstream>
#include <utility>

#include "absl/strings/str_cat.h"
#include "common/base/time.h"

namespace reenact::server {
namespace fs = std::filesystem;

namespace {

// "SIGSEGV" for 11.
std::string SignalName(int signal) {
  const char* abbrev = sigabbrev_np(signal);
  return abbrev != nullptr ? absl::StrCat("SIG", abbrev) : absl::StrCat("signal ", signal);
}

}  // namespace

absl::StatusOr<std::unique_ptr<WorkerProcess>> WorkerProcess::Start(
    const std::vector<std::string>& args, const std::string& dir, const std::string& log_header,
    v1::JobProgress progress, double eta_window_s) {
  const std::string progress_path = (fs::path(dir) / "progress.jsonl").string();
  const std::string log_path = (fs::path(dir) / "worker.log").string();
  std::error_code error;
  fs::remove(progress_path, error);
  {
    std::ofstream log(log_path, std::ios::app);
    log << log_header << "\n";
  }
  int64_t log_offset = static_cast<int64_t>(fs::file_size(log_path, error));
  if (error) log_offset = 0;
  SubprocessOptions options;
  options.stdout_path = progress_path;
  options.stderr_path = log_path;
  options.working_dir = dir;
  absl::StatusOr<std::unique_ptr<Subprocess>> process = Subprocess::Start(args, options);
  if (!process.ok()) return process.status();
  return std::unique_ptr<WorkerProcess>(
      new WorkerProcess(std::move(*process), log_path, log_offset,
                        WorkerOutputReader(progress_path, std::move(progress)), eta_window_s));
}

WorkerProcess::WorkerProcess(std::unique_ptr<Subprocess> process, std::string log_path,
                             int64_t log_offset, WorkerOutputReader output, double eta_window_s)
    : process_(std::move(process)),
      log_path_(std::move(log_path)),
      log_offset_(log_offset),
      output_(std::move(output)),
      eta_(eta_window_s) {}

bool WorkerProcess::ReadOutput(std::vector<std::string>* logs) {
  if (!output_.Read(logs)) return false;
  // One sample per read: lines read together arrived together.
  v1::JobProgress& p = output_.report().progress;
  p.set_eta_s(eta_.Update(SteadyNowNs(), p.fraction()));
  return true;
}

void WorkerProcess::Cancel(double grace_s) {
  if (!term_sent_) {
    (void)process_->Signal(SIGTERM);
    term_sent_ = true;
    kill_at_ns_ = SteadyNowNs() + SecondsToNs(grace_s);
  } else if (!kill_sent_ && SteadyNowNs() >= kill_at_ns_) {
    (void)process_->Signal(SIGKILL);
    kill_sent_ = true;
  }
}

std::string WorkerProcess::LastLog() const {
  return LastWorkerLog(log_path_, log_offset_, output_.report().last_log);
}

std::string WorkerProcess::FailureText(const ExitInfo& exit) const {
  if (!exit.exited) {
    return absl::StrCat("worker killed by signal ", exit.signal, " (", SignalName(exit.signal),
                        "); last log: ", LastLog());
  }
  if (exit.exit_code == 1 && !error().empty()) return error();
  if (exit.exit_code == 2) {
    return absl::StrCat("the worker refused its command line (exit code 2): ", LastLog());
  }
  if (exit.exit_code == 3) {
    return absl::StrCat("the worker stopped early without a cancel (exit code 3); last log: ",
                        LastLog());
  }
  return absl::StrCat("worker failed (exit code ", exit.exit_code, "); last log: ", LastLog());
}

}  // namespace reenact::server
