#include "server/jobs/slurm_launcher.h"

#include <signal.h>
#include <stdlib.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <set>
#include <utility>

#include "absl/strings/ascii.h"
#include "absl/strings/match.h"
#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "absl/strings/str_split.h"
#include "absl/strings/strip.h"
#include "common/base/files.h"
#include "common/base/status_macros.h"
#include "common/base/subprocess.h"
#include "common/base/time.h"
#include "common/log/log.h"

namespace reenact::server {
namespace {

// ---- Running the Slurm programs ----------------------------------------

// A file for a child's output, removed with this object.
class TempFile {
 public:
  static absl::StatusOr<TempFile> Make() {
    std::string path = (std::filesystem::temp_directory_path() / "reenact-slurm-XXXXXX").string();
    const int fd = ::mkstemp(path.data());
    if (fd < 0) return FileError("mkstemp " + path, errno);
    ::close(fd);
    return TempFile(std::move(path));
  }
  TempFile(TempFile&& other) noexcept : path_(std::exchange(other.path_, "")) {}
  TempFile& operator=(TempFile&&) = delete;
  ~TempFile() {
    if (!path_.empty()) ::unlink(path_.c_str());
  }
  const std::string& path() const { return path_; }
  std::string Read() const { return ReadFileToString(path_).value_or(""); }

 private:
  explicit TempFile(std::string path) : path_(std::move(path)) {}
  std::string path_;
};

struct CommandResult {
  ExitInfo exit;
  std::string out;
  std::string err;

  bool ok() const { return exit.exited && exit.exit_code == 0; }
  // How the command ended, with the last line of its stderr.
  std::string Describe() const {
    const std::vector<absl::string_view> lines =
        absl::StrSplit(absl::StripAsciiWhitespace(err), '\n', absl::SkipWhitespace());
    if (lines.empty()) return exit.ToString();
    return absl::StrCat(exit.ToString(), ": ", absl::StripAsciiWhitespace(lines.back()));
  }
};

// Runs `argv` with `env` added, for at most kSlurmCommandTimeoutS seconds.
// An error when it cannot start or runs too long; its exit otherwise.
absl::StatusOr<CommandResult> RunCommand(const std::vector<std::string>& argv,
                                         const std::map<std::string, std::string>& env) {
  ASSIGN_OR_RETURN(TempFile out, TempFile::Make());
  ASSIGN_OR_RETURN(TempFile err, TempFile::Make());
  SubprocessOptions options;
  options.env = env;
  options.stdout_path = out.path();
  options.stderr_path = err.path();
  ASSIGN_OR_RETURN(std::unique_ptr<Subprocess> child, Subprocess::Start(argv, options));
  absl::StatusOr<ExitInfo> exit = child->Wait(kSlurmCommandTimeoutS);
  if (!exit.ok()) {
    (void)child->Signal(SIGKILL);
    (void)child->Wait();
    return absl::DeadlineExceededError(
        absl::StrCat(argv[0], " ran longer than ", kSlurmCommandTimeoutS, " s"));
  }
  return CommandResult{*exit, out.Read(), err.Read()};
}

// RunCommand, with an exit other than 0 an Unavailable error too.
absl::StatusOr<CommandResult> RunCommandOk(const std::vector<std::string>& argv,
                                           const std::map<std::string, std::string>& env) {
  ASSIGN_OR_RETURN(CommandResult result, RunCommand(argv, env));
  if (!result.ok()) return absl::UnavailableError(absl::StrCat(argv[0], ": ", result.Describe()));
  return result;
}

// ---- squeue's job states -------------------------------------------------

// States of a batch job that waits for a node.
bool IsPendingState(absl::string_view state) {
  static const std::set<absl::string_view> kPending = {"PENDING", "REQUEUED", "REQUEUE_FED",
                                                       "REQUEUE_HOLD", "RESV_DEL_HOLD"};
  return kPending.count(state) > 0;
}

// States of a batch job whose worker has ended (COMPLETING: the batch
// script has exited and Slurm cleans up).
bool IsEndedState(absl::string_view state) {
  static const std::set<absl::string_view> kEnded = {
      "BOOT_FAIL", "CANCELLED",     "COMPLETED", "COMPLETING", "DEADLINE",     "FAILED",
      "NODE_FAIL", "OUT_OF_MEMORY", "PREEMPTED", "REVOKED",    "SPECIAL_EXIT", "TIMEOUT"};
  return kEnded.count(state) > 0;
}

// squeue's "%i %T" lines: job id -> state.
std::map<std::string, std::string> ParseSqueue(absl::string_view out) {
  std::map<std::string, std::string> states;
  for (absl::string_view line : absl::StrSplit(out, '\n', absl::SkipWhitespace())) {
    const std::vector<absl::string_view> words =
        absl::StrSplit(line, absl::ByAnyChar(" \t"), absl::SkipEmpty());
    if (words.size() >= 2) states[std::string(words[0])] = std::string(words[1]);
  }
  return states;
}

bool IsDigits(absl::string_view text) {
  return !text.empty() && std::all_of(text.begin(), text.end(), absl::ascii_isdigit);
}

// ---- The config file -----------------------------------------------------

// Keys whose value is a string as it is.
const std::map<absl::string_view, std::string SlurmLauncherOptions::*>& StringKeys() {
  static const auto* keys = new std::map<absl::string_view, std::string SlurmLauncherOptions::*>{
      {"partition", &SlurmLauncherOptions::partition},
      {"account", &SlurmLauncherOptions::account},
      {"time", &SlurmLauncherOptions::time_limit},
      {"mem", &SlurmLauncherOptions::mem},
      {"qos", &SlurmLauncherOptions::qos},
      {"worker", &SlurmLauncherOptions::worker},
      {"server", &SlurmLauncherOptions::server_address},
      {"token_file", &SlurmLauncherOptions::token_file},
      {"tls_ca", &SlurmLauncherOptions::tls_ca},
      {"scratch", &SlurmLauncherOptions::scratch},
      {"log_dir", &SlurmLauncherOptions::log_dir},
  };
  return *keys;
}

// Keys whose value is an integer, with its least value.
const std::map<absl::string_view, std::pair<int SlurmLauncherOptions::*, int>>& IntKeys() {
  static const auto* keys =
      new std::map<absl::string_view, std::pair<int SlurmLauncherOptions::*, int>>{
          {"cpus_per_task", {&SlurmLauncherOptions::cpus_per_task, 0}},
          {"max_pending", {&SlurmLauncherOptions::max_pending, 1}},
          {"max_jobs", {&SlurmLauncherOptions::max_jobs, 1}},
      };
  return *keys;
}

constexpr absl::string_view kRequiredKeys[] = {"worker", "server", "log_dir"};

// Applies `key = value` to `options`; the error's message says what is wrong
// with the value (the caller names line and key). NotFound for an unknown
// key.
absl::Status ApplyKey(absl::string_view key, absl::string_view value,
                      SlurmLauncherOptions& options) {
  if (value.empty()) return absl::InvalidArgumentError("no value");
  if (auto it = StringKeys().find(key); it != StringKeys().end()) {
    options.*(it->second) = std::string(value);
  } else if (auto it = IntKeys().find(key); it != IntKeys().end()) {
    int number;
    if (!absl::SimpleAtoi(value, &number) || number < it->second.second) {
      return absl::InvalidArgumentError(
          absl::StrCat("\"", value, "\" is not an integer >= ", it->second.second));
    }
    options.*(it->second.first) = number;
  } else if (key == "worker_wait_s" || key == "start_grace_s") {
    double seconds;
    if (!absl::SimpleAtod(value, &seconds) || !std::isfinite(seconds) || seconds < 0) {
      return absl::InvalidArgumentError(absl::StrCat("\"", value, "\" is not seconds >= 0"));
    }
    (key == "worker_wait_s" ? options.worker_wait_s : options.start_grace_s) = seconds;
  } else if (key == "sbatch_arg") {
    options.extra_sbatch_args.emplace_back(value);
  } else {
    return absl::NotFoundError("unknown key");
  }
  return absl::OkStatus();
}

// "HOST:PORT" with a port in 1..65535.
bool IsHostPort(absl::string_view address) {
  const size_t colon = address.rfind(':');
  if (colon == absl::string_view::npos || colon == 0) return false;
  int port;
  return IsDigits(address.substr(colon + 1)) &&
         absl::SimpleAtoi(address.substr(colon + 1), &port) && port >= 1 && port <= 65535;
}

std::string WithoutTrailingSlashes(std::string path) {
  while (path.size() > 1 && path.back() == '/') path.pop_back();
  return path;
}

}  // namespace

// ---- Options ---------------------------------------------------------------

absl::Status SlurmLauncherOptions::Validate() const {
  auto invalid = [](absl::string_view key, absl::string_view what) {
    return absl::InvalidArgumentError(absl::StrCat(key, ": ", what));
  };
  if (worker.empty()) return invalid("worker", "required (reenact-worker's path on the nodes)");
  if (server_address.empty()) return invalid("server", "required (HOST:PORT of the server)");
  if (!IsHostPort(server_address)) {
    return invalid("server", absl::StrCat("\"", server_address, "\" is not HOST:PORT"));
  }
  if (log_dir.empty()) return invalid("log_dir", "required (the batch jobs' output folder)");
  if (absl::StrContains(log_dir, '%')) {
    return invalid("log_dir", "must not contain '%' (sbatch reads it as a pattern)");
  }
  if (cpus_per_task < 0) return invalid("cpus_per_task", "must be >= 0");
  if (!std::isfinite(worker_wait_s) || worker_wait_s < 0) {
    return invalid("worker_wait_s", "must be seconds >= 0");
  }
  if (!std::isfinite(start_grace_s) || start_grace_s < 0) {
    return invalid("start_grace_s", "must be seconds >= 0");
  }
  if (max_pending < 1) return invalid("max_pending", "must be >= 1");
  if (max_jobs < 1) return invalid("max_jobs", "must be >= 1");
  for (const std::string& arg : extra_sbatch_args) {
    if (!absl::StartsWith(arg, "-")) {
      return invalid("sbatch_arg", absl::StrCat("\"", arg, "\" is not a flag (one per entry)"));
    }
  }
  if (sbatch.empty() || squeue.empty() || scancel.empty()) {
    return absl::InvalidArgumentError("the sbatch, squeue and scancel programs must be named");
  }
  return absl::OkStatus();
}

absl::StatusOr<SlurmLauncherOptions> ParseSlurmConfigText(std::string_view text_in,
                                                          std::string_view origin_in) {
  const absl::string_view text(text_in.data(), text_in.size());
  const absl::string_view origin(origin_in.data(), origin_in.size());
  SlurmLauncherOptions options;
  std::map<std::string, int> first_line;  // Key -> the line that set it.
  int line_number = 0;
  for (absl::string_view line : absl::StrSplit(text, '\n')) {
    ++line_number;
    line = absl::StripAsciiWhitespace(line);
    if (line.empty() || line.front() == '#') continue;
    const std::string where = absl::StrCat(origin, ":", line_number, ": ");
    const size_t equals = line.find('=');
    if (equals == absl::string_view::npos) {
      return absl::InvalidArgumentError(absl::StrCat(where, "expected `key = value`"));
    }
    const std::string key(absl::StripAsciiWhitespace(line.substr(0, equals)));
    const absl::string_view value = absl::StripAsciiWhitespace(line.substr(equals + 1));
    const absl::Status applied = ApplyKey(key, value, options);
    if (absl::IsNotFound(applied)) {
      return absl::InvalidArgumentError(absl::StrCat(where, "unknown key \"", key, "\""));
    }
    if (!applied.ok()) {
      return absl::InvalidArgumentError(absl::StrCat(where, key, ": ", applied.message()));
    }
    if (key != "sbatch_arg" && first_line.count(key) > 0) {
      return absl::InvalidArgumentError(
          absl::StrCat(where, key, ": given again (first on line ", first_line[key], ")"));
    }
    first_line.emplace(key, line_number);
  }
  for (absl::string_view key : kRequiredKeys) {
    if (first_line.count(std::string(key)) == 0) {
      return absl::InvalidArgumentError(
          absl::StrCat(origin, ": missing required key \"", key, "\""));
    }
  }
  if (absl::Status valid = options.Validate(); !valid.ok()) {
    return absl::InvalidArgumentError(absl::StrCat(origin, ": ", valid.message()));
  }
  return options;
}

absl::StatusOr<SlurmLauncherOptions> ParseSlurmConfig(const std::string& path) {
  ASSIGN_OR_RETURN(std::string text, ReadFileToString(path, /*max_bytes=*/1 << 20));
  return ParseSlurmConfigText(text, path);
}

// ---- The batch job -------------------------------------------------------------

std::string ShellQuote(std::string_view text) {
  auto plain = [](char c) {
    return absl::ascii_isalnum(static_cast<unsigned char>(c)) ||
           absl::string_view("_-./:@+,%").find(c) != absl::string_view::npos;
  };
  if (!text.empty() && std::all_of(text.begin(), text.end(), plain)) return std::string(text);
  std::string quoted = "'";
  for (char c : text) {
    if (c == '\'') {
      quoted += "'\\''";
    } else {
      quoted += c;
    }
  }
  quoted += "'";
  return quoted;
}

std::string SlurmWorkerCommand(const SlurmLauncherOptions& options) {
  std::string command = absl::StrCat("exec ", ShellQuote(options.worker), " --server ",
                                     ShellQuote(options.server_address), " --once --wait ",
                                     ShellQuote(absl::StrCat(options.worker_wait_s)), " --name \"",
                                     kSlurmWorkerNamePrefix, "$SLURM_JOB_ID\"");
  auto add = [&command](absl::string_view flag, const std::string& value) {
    if (!value.empty()) absl::StrAppend(&command, " ", flag, " ", ShellQuote(value));
  };
  add("--token-file", options.token_file);
  add("--tls-ca", options.tls_ca);
  add("--scratch", options.scratch);
  return command;
}

std::vector<std::string> SbatchArgs(const SlurmLauncherOptions& options) {
  std::vector<std::string> args = {
      "--parsable", "--job-name=reenact-worker",
      absl::StrCat("--output=", WithoutTrailingSlashes(options.log_dir), "/slurm-%j.out")};
  auto add = [&args](absl::string_view flag, const std::string& value) {
    if (!value.empty()) args.push_back(absl::StrCat(flag, "=", value));
  };
  add("--partition", options.partition);
  add("--account", options.account);
  add("--time", options.time_limit);
  add("--mem", options.mem);
  add("--qos", options.qos);
  if (options.cpus_per_task > 0) add("--cpus-per-task", absl::StrCat(options.cpus_per_task));
  args.insert(args.end(), options.extra_sbatch_args.begin(), options.extra_sbatch_args.end());
  args.push_back("--wrap");
  args.push_back(SlurmWorkerCommand(options));
  return args;
}

// ---- SlurmLauncher -----------------------------------------------------------

absl::StatusOr<std::unique_ptr<SlurmLauncher>> SlurmLauncher::Create(
    const SlurmLauncherOptions& options) {
  RETURN_IF_ERROR(options.Validate());
  SlurmLauncherOptions resolved = options;
  std::error_code error;
  const std::filesystem::path log_dir = std::filesystem::absolute(options.log_dir, error);
  if (error) return absl::InvalidArgumentError("log_dir: " + error.message());
  resolved.log_dir = WithoutTrailingSlashes(log_dir.lexically_normal().string());
  RETURN_IF_ERROR(CreateDirectories(resolved.log_dir));
  absl::StatusOr<CommandResult> version = RunCommandOk({options.sbatch, "--version"}, options.env);
  if (!version.ok()) {
    return absl::FailedPreconditionError(
        absl::StrCat("Slurm's sbatch does not run: ", version.status().message()));
  }
  log::Info("slurm_launcher_ready", {{"sbatch_version", absl::StripAsciiWhitespace(version->out)},
                                     {"log_dir", resolved.log_dir},
                                     {"max_pending", options.max_pending},
                                     {"max_jobs", options.max_jobs}});
  return std::unique_ptr<SlurmLauncher>(new SlurmLauncher(resolved));
}

void SlurmLauncher::Backoff::Succeeded(int64_t now_ns, double period_s) {
  failures = 0;
  next_ns = now_ns + SecondsToNs(period_s);
}

double SlurmLauncher::Backoff::Failed(int64_t now_ns) {
  ++failures;
  const double wait_s =
      std::min(kSlurmPollPeriodS * std::pow(2.0, std::min(failures - 1, 30)), kSlurmMaxBackoffS);
  next_ns = now_ns + SecondsToNs(wait_s);
  return wait_s;
}

void SlurmLauncher::Reconcile(int queued) {
  std::lock_guard<std::mutex> reconcile_lock(reconcile_mu_);
  int64_t now_ns = SteadyNowNs();
  if (now_ns >= poll_backoff_.next_ns) {
    if (absl::Status polled = Poll(); polled.ok()) {
      poll_backoff_.Succeeded(now_ns, kSlurmPollPeriodS);
    } else {
      log::Warn("squeue_failed",
                {{"error", polled.message()}, {"retry_in_s", poll_backoff_.Failed(now_ns)}});
    }
  }
  while ((now_ns = SteadyNowNs()) >= submit_backoff_.next_ns) {
    {
      std::lock_guard<std::mutex> lock(mu_);
      if (!WantsBatchLocked(queued, now_ns)) break;
    }
    if (absl::Status submitted = Submit(); submitted.ok()) {
      submit_backoff_.Succeeded(now_ns, 0);
    } else {
      log::Warn("sbatch_failed",
                {{"error", submitted.message()}, {"retry_in_s", submit_backoff_.Failed(now_ns)}});
    }
  }
}

absl::Status SlurmLauncher::Poll() {
  std::vector<std::string> ids;
  {
    std::lock_guard<std::mutex> lock(mu_);
    for (const auto& [id, batch] : batches_) ids.push_back(id);
  }
  if (ids.empty()) return absl::OkStatus();
  ASSIGN_OR_RETURN(CommandResult result,
                   RunCommand({options_.squeue, "-h", "-j", absl::StrJoin(ids, ","), "-o", "%i %T"},
                              options_.env));
  // squeue fails so when asked for one job it no longer knows (with several,
  // it lists the ones it knows): the job has ended.
  const bool all_unknown = ids.size() == 1 && absl::StrContains(result.err, "Invalid job id");
  if (!result.ok() && !all_unknown) {
    return absl::UnavailableError(absl::StrCat(options_.squeue, ": ", result.Describe()));
  }
  const std::map<std::string, std::string> states =
      result.ok() ? ParseSqueue(result.out) : std::map<std::string, std::string>{};
  const int64_t now_ns = SteadyNowNs();
  std::lock_guard<std::mutex> lock(mu_);
  for (const std::string& id : ids) {
    auto batch = batches_.find(id);
    if (batch == batches_.end()) continue;  // Cancelled meanwhile.
    auto state = states.find(id);
    if (state == states.end() || IsEndedState(state->second)) {
      log::Info("slurm_batch_ended",
                {{"batch_job_id", id}, {"state", state == states.end() ? "gone" : state->second}});
      batches_.erase(batch);
    } else if (IsPendingState(state->second)) {
      batch->second.state = BatchState::kPending;
    } else if (batch->second.state == BatchState::kPending) {
      batch->second = {BatchState::kRunning, now_ns};
      log::Info("slurm_batch_started", {{"batch_job_id", id}, {"state", state->second}});
    }
  }
  return absl::OkStatus();
}

absl::Status SlurmLauncher::Submit() {
  std::vector<std::string> argv = {options_.sbatch};
  for (std::string& arg : SbatchArgs(options_)) argv.push_back(std::move(arg));
  ASSIGN_OR_RETURN(CommandResult result, RunCommandOk(argv, options_.env));
  // --parsable prints "ID" or "ID;CLUSTER".
  const absl::string_view first_line =
      absl::StripAsciiWhitespace(absl::string_view(result.out).substr(0, result.out.find('\n')));
  const std::string id(first_line.substr(0, first_line.find(';')));
  if (!IsDigits(id)) {
    return absl::InternalError(
        absl::StrCat(options_.sbatch, " printed no job id: \"", first_line, "\""));
  }
  int64_t total;
  {
    std::lock_guard<std::mutex> lock(mu_);
    batches_[id] = Batch{};
    total = ++submitted_total_;
  }
  log::Info("slurm_batch_submitted", {{"batch_job_id", id}, {"submitted_total", total}});
  return absl::OkStatus();
}

std::optional<std::string> SlurmLauncher::BatchJobOf(const std::string& worker_name) {
  absl::string_view id = worker_name;
  if (!absl::ConsumePrefix(&id, kSlurmWorkerNamePrefix) || !IsDigits(id)) return std::nullopt;
  return std::string(id);
}

absl::Status SlurmLauncher::Cancel(const std::string& batch_job_id) {
  {
    std::lock_guard<std::mutex> lock(mu_);
    if (batches_.count(batch_job_id) == 0) {
      return absl::NotFoundError(
          absl::StrCat("batch job ", batch_job_id, " is not a running or pending worker of ours"));
    }
  }
  absl::StatusOr<CommandResult> result =
      RunCommandOk({options_.scancel, batch_job_id}, options_.env);
  if (!result.ok()) {
    log::Warn("scancel_failed",
              {{"batch_job_id", batch_job_id}, {"error", result.status().message()}});
    return absl::UnavailableError(result.status().message());
  }
  {
    std::lock_guard<std::mutex> lock(mu_);
    batches_.erase(batch_job_id);
  }
  log::Info("slurm_batch_cancelled", {{"batch_job_id", batch_job_id}});
  return absl::OkStatus();
}

void SlurmLauncher::Shutdown() {
  std::lock_guard<std::mutex> reconcile_lock(reconcile_mu_);
  std::vector<std::string> pending;
  {
    std::lock_guard<std::mutex> lock(mu_);
    shut_down_ = true;
    for (const auto& [id, batch] : batches_) {
      if (batch.state == BatchState::kPending) pending.push_back(id);
    }
  }
  if (pending.empty()) return;
  // --state=PENDING: a batch job that started meanwhile keeps running.
  std::vector<std::string> argv = {options_.scancel, "--state=PENDING"};
  argv.insert(argv.end(), pending.begin(), pending.end());
  if (absl::StatusOr<CommandResult> result = RunCommandOk(argv, options_.env); !result.ok()) {
    log::Warn("scancel_failed", {{"batch_job_ids", absl::StrJoin(pending, ",")},
                                 {"error", result.status().message()}});
  } else {
    log::Info("slurm_pending_cancelled", {{"batch_job_ids", absl::StrJoin(pending, ",")}});
  }
  // Learns which ended and which started, so that the counts are right.
  if (absl::Status polled = Poll(); !polled.ok()) {
    log::Warn("squeue_failed", {{"error", polled.message()}});
  }
}

int SlurmLauncher::CountLocked(BatchState state) const {
  return static_cast<int>(
      std::count_if(batches_.begin(), batches_.end(),
                    [state](const auto& batch) { return batch.second.state == state; }));
}

int SlurmLauncher::StartingLocked(int64_t now_ns) const {
  const int64_t since_ns = now_ns - SecondsToNs(options_.start_grace_s);
  return static_cast<int>(std::count_if(batches_.begin(), batches_.end(), [&](const auto& batch) {
    return batch.second.state == BatchState::kRunning && batch.second.started_ns > since_ns;
  }));
}

bool SlurmLauncher::WantsBatchLocked(int queued, int64_t now_ns) const {
  if (shut_down_ || static_cast<int>(batches_.size()) >= options_.max_jobs) return false;
  const int pending = CountLocked(BatchState::kPending);
  return pending < options_.max_pending && pending + StartingLocked(now_ns) < queued;
}

int SlurmLauncher::pending() const {
  std::lock_guard<std::mutex> lock(mu_);
  return CountLocked(BatchState::kPending);
}

int SlurmLauncher::running() const {
  std::lock_guard<std::mutex> lock(mu_);
  return CountLocked(BatchState::kRunning);
}

int64_t SlurmLauncher::submitted_total() const {
  std::lock_guard<std::mutex> lock(mu_);
  return submitted_total_;
}

void SlurmLauncher::CancelWorker(const std::string& worker_name) {
  const std::optional<std::string> batch = BatchJobOf(worker_name);
  if (!batch.has_value()) return;
  if (const absl::Status cancelled = Cancel(*batch); !cancelled.ok()) {
    log::Warn("scancel_failed", {{"batch_job", *batch}, {"error", cancelled.message()}},
              absl::StrCat("the batch job of worker ", worker_name,
                           " could not be cancelled: ", cancelled.message()));
  }
}

}  // namespace reenact::server
