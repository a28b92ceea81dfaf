// reenact-worker: runs reconstruction jobs, in one of two modes.
//
// On the network (server/worker/work_agent.h): leases jobs from a server's
// Work service, anywhere the server can be reached, and runs each in a
// scratch folder of its own:
//
//   reenact-worker --server HOST:PORT [--token-file F] [--tls-ca PEM]
//                  [--once | --loop] [--methods a,b] [--scratch DIR]
//                  [--name NAME] [--wait S] [--assets DIR[,DIR...]]
//                  [--memory-limit-mb N]
//
// One job (what the network mode runs as a child for each job, and what a
// person can run by hand): server/worker/worker_protocol.h describes the
// protocol; server/recon/methods.h the methods.
//
//   reenact-worker --take FILE --method METHOD --out FILE
//                  [--options-json '{"key":"value"}'] [--reenactment-id RID]
//                  [--take-id T] [--job-id J] [--assets DIR[,DIR...]]
//                  [--log-format text|json] [--log-level debug|info|warn|error]
//                  [--memory-limit-mb N]
//                  [--part prepare | --part segment-K --segments N --prepared F
//                   | --part stitch --segments N --prepared F
//                     --segment-files F1,...,FN]
//
// --memory-limit-mb N: the job may allocate at most N MiB (its RLIMIT_DATA,
// common/base/memory_limit.h); past it the job fails with a clear error
// (exit 1) instead of taking the machine's memory. A network worker passes
// its own to each job it runs: by default three quarters of its machine's
// memory. A server's own workers pass the server's --job-memory-mb.
//
// --part runs one phase of a segmented job (one take split across several
// workers; server/recon/methods.h MethodPhase): prepare writes the method's
// part file from the whole take, segment-K (1-based) that of segment K of N
// from the prepared file, stitch the reenactment from the prepared file and
// every segment's.
//
// stdout carries one JSON object per line: progress
// {"stage":"register","fraction":0.42,"frames_done":120,"frames_total":300}
// (about ten a second at most, plus every stage change and the end), log
// lines {"log":"..."}, and at the end {"result":{...}} or {"error":"..."}.
// Exit codes: 0 success, 1 failure, 2 usage error, 3 stopped by SIGTERM or
// SIGINT (the method stops at its next progress callback). stderr (the job's
// worker.log) carries the worker's events in the structured log format
// (common/log/log.h): worker_started, worker_finished, worker_failed.
//
// reenact-server blocks SIGTERM/SIGINT in every thread (it takes them with
// sigwait) and a signal mask survives fork and exec, so the worker unblocks
// them first. It also asks for SIGTERM when its parent dies, so a crashed
// server leaves no worker running on.
#include <signal.h>
#include <sys/prctl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <atomic>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <filesystem>
#include <map>
#include <mutex>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "absl/strings/match.h"
#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_split.h"
#include "common/base/flags.h"
#include "common/base/json_text.h"
#include "common/base/memory_limit.h"
#include "common/base/status_macros.h"
#include "common/base/time.h"
#include "common/log/log.h"
#include "common/rpc/channel.h"
#include "server/recon/methods.h"
#include "server/worker/work_agent.h"

namespace {

constexpr int kExitOk = 0;
constexpr int kExitFailure = 1;
constexpr int kExitUsage = 2;
constexpr int kExitStopped = 3;
// Least time between two progress lines of the same stage, ns (~10/s).
constexpr int64_t kProgressPeriodNs = 100'000'000;

constexpr char kUsage[] =
    "usage: reenact-worker --server HOST:PORT [--token-file FILE (or REENACT_TOKEN)] "
    "[--tls-ca PEM (or REENACT_TLS_CA)] [--once (one job, then exit) | --loop (jobs until "
    "SIGTERM; the default)] [--methods a,b (only these methods)] [--scratch DIR (each job's "
    "folder; default $TMPDIR)] [--name NAME (in the server's logs)] [--wait S (--once: how "
    "long to wait for a job; default 60)] [--assets DIR[,DIR...]] [--log-format text|json] "
    "[--log-level debug|info|warn|error] [--memory-limit-mb N (each job's memory ceiling; "
    "default three quarters of the machine's)]\n"
    "   or: reenact-worker --take FILE --method METHOD --out FILE "
    "[--options-json '{\"key\":\"value\"}'] [--reenactment-id RID] [--take-id T] [--job-id J] "
    "[--assets DIR[,DIR...] (where model=makehuman:NAME is looked up)] "
    "[--log-format text|json (events on stderr; default text)] "
    "[--log-level debug|info|warn|error (default info)] "
    "[--memory-limit-mb N (the job fails past N MiB)] "
    "[--part prepare | --part segment-K --segments N --prepared FILE | --part stitch "
    "--segments N --prepared FILE --segment-files F1,...,FN (one phase of a job split across "
    "workers)]";

volatile sig_atomic_t g_stop_signal = 0;
// The job's --memory-limit-mb once in force (0: none).
std::atomic<int64_t> g_memory_limit_mb{0};

// The job's error when it ran out of memory under its limit.
std::string OverLimitError() {
  return "the job needed more memory than its limit of " +
         std::to_string(g_memory_limit_mb.load()) +
         " MiB (--memory-limit-mb; a server's --job-memory-mb); ask for smaller textures, meshes "
         "or voxels, or fewer frames (max_frames)";
}

// Whether `error` is an allocation that failed (new's, or OpenCV's and
// Eigen's words for it) while a limit is in force.
bool IsOverLimit(const std::string& error) {
  return g_memory_limit_mb.load() > 0 &&
         (absl::StrContains(error, "bad_alloc") || absl::StrContains(error, "Failed to allocate") ||
          absl::StrContains(error, "Insufficient memory") ||
          absl::StrContains(error, "out of memory"));
}

// --memory-limit-mb, or `fallback` without it; an error message for a bad
// value.
std::string ReadMemoryLimitMb(const reenact::Flags& flags, int64_t fallback, int64_t* mb) {
  *mb = fallback;
  if (!flags.Has("memory-limit-mb")) return "";
  const absl::StatusOr<int> value = flags.GetInt("memory-limit-mb", 0);
  if (!value.ok() || *value < 64) return "--memory-limit-mb takes MiB, at least 64";
  *mb = *value;
  return "";
}
std::atomic<bool> g_stop{false};

void OnStopSignal(int signal) {
  g_stop_signal = signal;
  g_stop.store(true);
}

void InstallSignals() {
  struct sigaction action {};
  action.sa_handler = OnStopSignal;
  sigemptyset(&action.sa_mask);
  sigaction(SIGTERM, &action, nullptr);
  sigaction(SIGINT, &action, nullptr);
  sigset_t signals;
  sigemptyset(&signals);
  sigaddset(&signals, SIGTERM);
  sigaddset(&signals, SIGINT);
  sigprocmask(SIG_UNBLOCK, &signals, nullptr);
}

// SIGTERM when the parent (a server, or a network worker) dies; it may have
// died before this call.
void StopWithParent() {
  const pid_t parent = getppid();
  prctl(PR_SET_PDEATHSIG, SIGTERM);
  if (getppid() != parent) OnStopSignal(SIGTERM);
}

// Writes one JSON line on stdout (whole lines, flushed, from any thread).
class Output {
 public:
  void Line(const nlohmann::json& j) {
    const std::string text = j.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
    std::lock_guard<std::mutex> lock(mu_);
    std::fwrite(text.data(), 1, text.size(), stdout);
    std::fputc('\n', stdout);
    std::fflush(stdout);
  }

  // The progress callback: throttled lines; false once a stop signal came.
  bool Progress(const reenact::Progress& p) {
    const int64_t now_ns = reenact::SteadyNowNs();
    bool emit = false;
    {
      std::lock_guard<std::mutex> lock(progress_mu_);
      if (p.stage != last_stage_ || p.fraction >= 1.0 || now_ns - last_ns_ >= kProgressPeriodNs) {
        emit = true;
        last_stage_ = p.stage;
        last_ns_ = now_ns;
      }
    }
    if (emit) {
      Line({{"stage", p.stage},
            {"fraction", p.fraction},
            {"frames_done", p.items_done},
            {"frames_total", p.items_total}});
    }
    return g_stop_signal == 0;
  }

 private:
  std::mutex mu_;
  std::mutex progress_mu_;
  std::string last_stage_;
  int64_t last_ns_ = 0;
};

int Usage(Output& out, const std::string& message) {
  out.Line({{"error", message}});
  std::fprintf(stderr, "reenact-worker: %s\n%s\n", message.c_str(), kUsage);
  return kExitUsage;
}

// --part and its companions into `input`; a usage error's message, or "".
std::string ReadPhase(const reenact::Flags& flags, reenact::recon::MethodInput& input) {
  using reenact::recon::MethodPhase;
  const std::string part = flags.GetOr("part", "");
  if (part.empty()) {
    for (const char* name : {"segments", "prepared", "segment-files"}) {
      if (flags.Has(name)) return std::string("--") + name + " needs --part";
    }
    return "";
  }
  if (part == "prepare") {
    input.phase = MethodPhase::kPrepare;
    return "";
  }
  const absl::StatusOr<int> count = flags.GetInt("segments", 0);
  if (!count.ok() || *count < 2 || *count > 64) return "--segments takes 2 to 64";
  input.segment_count = *count;
  input.prepared_path = flags.GetOr("prepared", "");
  if (input.prepared_path.empty()) return "--part " + part + " needs --prepared";
  if (part == "stitch") {
    input.phase = MethodPhase::kStitch;
    input.segment_paths = absl::StrSplit(flags.GetOr("segment-files", ""), ',', absl::SkipEmpty());
    if (static_cast<int>(input.segment_paths.size()) != *count) {
      return "--segment-files must name one file per segment";
    }
    return "";
  }
  int number = 0;
  if (!absl::StartsWith(part, "segment-") ||
      !absl::SimpleAtoi(part.substr(std::strlen("segment-")), &number) || number < 1 ||
      number > *count) {
    return "--part takes prepare, segment-K (1 <= K <= --segments) or stitch";
  }
  input.phase = MethodPhase::kSegment;
  input.segment_index = number - 1;
  return "";
}

// [first, end) runs of sorted, distinct frame indices.
void AddRuns(const std::string& sensor_id, const std::vector<int64_t>& frames,
             google::protobuf::RepeatedPtrField<reenact::v1::FrameRange>* ranges) {
  for (size_t i = 0; i < frames.size();) {
    size_t j = i + 1;
    while (j < frames.size() && frames[j] == frames[j - 1] + 1) ++j;
    reenact::v1::FrameRange* range = ranges->Add();
    range->set_sensor_id(sensor_id);
    range->set_first(frames[i]);
    range->set_end(frames[j - 1] + 1);
    i = j;
  }
}

// The frames a phase of a segmented job decodes (WorkAgentOptions::
// select_take): its method names them from the take without image bytes.
absl::StatusOr<reenact::v1::TakeSelection> SelectTake(const reenact::v1::WorkLease& lease,
                                                      const std::string& index_path) {
  using reenact::recon::MethodPhase;
  reenact::recon::MethodInput input;
  input.take_path = index_path;
  input.method = lease.job().method();
  input.options.insert(lease.job().options().begin(), lease.job().options().end());
  input.segment_count = lease.job().segments();
  const std::string& part = lease.part();
  int number = 0;
  if (part == "prepare") {
    input.phase = MethodPhase::kPrepare;
  } else if (part == "stitch") {
    input.phase = MethodPhase::kStitch;
  } else if (absl::StartsWith(part, "segment-") &&
             absl::SimpleAtoi(part.substr(std::strlen("segment-")), &number)) {
    input.phase = MethodPhase::kSegment;
    input.segment_index = number - 1;
  } else {
    return absl::InvalidArgumentError(
        absl::StrCat("the lease names part \"", part.substr(0, 64), "\", which is no phase"));
  }
  ASSIGN_OR_RETURN(const std::vector<reenact::recon::SensorFrameNeeds> needs,
                   reenact::recon::FramesNeeded(input));
  reenact::v1::TakeSelection selection;
  for (const reenact::recon::SensorFrameNeeds& sensor : needs) {
    AddRuns(sensor.sensor_id, sensor.depth_frames, selection.mutable_depth());
    AddRuns(sensor.sensor_id, sensor.color_frames, selection.mutable_color());
  }
  return selection;
}

// reenact-worker --server: jobs from a server's Work service, each run by
// this program in its one-job mode as a child.
int RunNetworkWorker(const reenact::Flags& flags, const char* argv0) {
  for (const char* name : {"take", "method", "out", "options-json", "reenactment-id", "take-id",
                           "job-id", "part", "segments", "prepared", "segment-files"}) {
    if (flags.Has(name)) {
      std::fprintf(stderr, "reenact-worker: --%s is for one job; --server leases jobs\n%s\n", name,
                   kUsage);
      return kExitUsage;
    }
  }
  if (flags.Has("once") && flags.Has("loop")) {
    std::fprintf(stderr, "reenact-worker: --once or --loop, not both\n");
    return kExitUsage;
  }
  const absl::StatusOr<reenact::log::Options> log_options = reenact::log::ParseOptions(
      flags.GetOr("log-format", "text"), flags.GetOr("log-level", "info"));
  if (!log_options.ok()) {
    std::fprintf(stderr, "reenact-worker: %s\n",
                 std::string(log_options.status().message()).c_str());
    return kExitUsage;
  }
  reenact::log::Configure(*log_options);
  reenact::server::WorkAgentOptions options;
  options.server = flags.GetOr("server", "");
  const absl::StatusOr<reenact::rpc::ClientSecurity> security =
      reenact::rpc::LoadClientSecurity(flags.GetOr("tls-ca", ""), flags.GetOr("token-file", ""));
  if (!security.ok()) {
    std::fprintf(stderr, "reenact-worker: %s\n", std::string(security.status().message()).c_str());
    return kExitUsage;
  }
  options.security = *security;
  std::error_code error;
  const std::filesystem::path self = std::filesystem::read_symlink("/proc/self/exe", error);
  options.job_program = error ? std::string(argv0) : self.string();
  if (const char* program = std::getenv("REENACT_WORKER_JOB_PROGRAM");
      program != nullptr && program[0] != '\0') {
    options.job_program = program;  // Tests: a stand-in that plays the protocol.
  }
  if (const std::string methods = flags.GetOr("methods", ""); !methods.empty()) {
    options.methods = absl::StrSplit(methods, ',', absl::SkipEmpty());
  }
  if (const std::string assets = flags.GetOr("assets", ""); !assets.empty()) {
    options.asset_roots = absl::StrSplit(assets, ',', absl::SkipEmpty());
  }
  options.select_take = &SelectTake;
  options.scratch_dir = flags.GetOr("scratch", "");
  options.name = flags.GetOr("name", "");
  options.once = flags.Has("once");
  const absl::StatusOr<double> wait = flags.GetDouble("wait", options.once_wait_s);
  if (!wait.ok() || !(*wait >= 0)) {
    std::fprintf(stderr, "reenact-worker: --wait takes seconds >= 0\n");
    return kExitUsage;
  }
  options.once_wait_s = *wait;
  // Each job's ceiling: its own flag, else three quarters of this machine.
  if (const std::string error = ReadMemoryLimitMb(
          flags, (reenact::PhysicalMemoryBytes() >> 20) * 3 / 4, &options.memory_limit_mb);
      !error.empty()) {
    std::fprintf(stderr, "reenact-worker: %s\n", error.c_str());
    return kExitUsage;
  }
  reenact::log::Info("worker_started",
                     {{"server", options.server},
                      {"once", options.once},
                      {"memory_limit_mb", options.memory_limit_mb},
                      {"methods", flags.GetOr("methods", "(all)")}},
                     "reenact-worker started: leasing jobs from " + options.server);
  const absl::StatusOr<reenact::server::WorkAgentSummary> summary =
      reenact::server::RunWorkAgent(options, g_stop);
  if (!summary.ok()) {
    reenact::log::Error("worker_refused", {{"error", summary.status().message()}},
                        "reenact-worker stops: " + std::string(summary.status().message()));
    return kExitFailure;
  }
  reenact::log::Info("worker_finished",
                     {{"jobs", summary->jobs},
                      {"succeeded", summary->succeeded},
                      {"not_succeeded", summary->not_succeeded}},
                     "reenact-worker finished");
  if (g_stop.load()) return kExitStopped;
  // --once: a job that did not succeed is an error for the batch system.
  return options.once && summary->jobs > 0 && summary->succeeded == 0 ? kExitFailure : kExitOk;
}

int WorkerMain(int argc, char** argv) {
  // Takes, spools, reenactments and logs hold images of people: everything
  // this process creates is its user's alone (files 0600, folders 0700).
  ::umask(077);
  InstallSignals();
  Output out;
  const absl::StatusOr<reenact::Flags> flags = reenact::Flags::Parse(
      std::vector<std::string>(argv + 1, argv + argc),
      {"take",          "method",         "options-json", "out",        "reenactment-id",
       "take-id",       "job-id",         "assets",       "log-format", "log-level",
       "server",        "token-file",     "tls-ca",       "methods",    "scratch",
       "name",          "wait",           "part",         "segments",   "prepared",
       "segment-files", "memory-limit-mb"},
      {"help", "once", "loop"});
  if (!flags.ok()) return Usage(out, std::string(flags.status().message()));
  if (flags->Has("help")) {
    std::printf("%s\n", kUsage);
    return kExitOk;
  }
  if (flags->Has("server")) return RunNetworkWorker(*flags, argv[0]);
  StopWithParent();
  if (!flags->positional().empty()) {
    return Usage(out, "unexpected argument \"" + flags->positional().front() + "\"");
  }
  reenact::recon::MethodInput input;
  for (const char* name : {"take", "method", "out"}) {
    if (flags->GetOr(name, "").empty()) return Usage(out, std::string("missing --") + name);
  }
  input.take_path = *flags->Get("take");
  input.method = *flags->Get("method");
  input.reenactment_id = flags->GetOr("reenactment-id", "");
  input.take_id = flags->GetOr("take-id", "");
  input.job_id = flags->GetOr("job-id", "");
  if (const std::string assets = flags->GetOr("assets", ""); !assets.empty()) {
    input.asset_roots = absl::StrSplit(assets, ',', absl::SkipEmpty());
  }
  const nlohmann::json options =
      nlohmann::json::parse(flags->GetOr("options-json", "{}"), nullptr, false);
  if (!options.is_object()) return Usage(out, "--options-json is not a JSON object");
  for (const auto& [key, value] : options.items()) {
    input.options[key] = value.is_string() ? value.get<std::string>() : reenact::JsonText(value);
  }
  if (const std::string error = ReadPhase(*flags, input); !error.empty()) return Usage(out, error);
  const std::string out_path = *flags->Get("out");
  const absl::StatusOr<reenact::log::Options> log_options = reenact::log::ParseOptions(
      flags->GetOr("log-format", "text"), flags->GetOr("log-level", "info"));
  if (!log_options.ok()) return Usage(out, std::string(log_options.status().message()));
  reenact::log::Configure(*log_options);
  int64_t memory_limit_mb = 0;
  if (const std::string error = ReadMemoryLimitMb(*flags, 0, &memory_limit_mb); !error.empty()) {
    return Usage(out, error);
  }
  if (memory_limit_mb > 0) {
    if (absl::Status limited = reenact::LimitDataMemory(memory_limit_mb << 20); !limited.ok()) {
      out.Line({{"error", std::string(limited.message())}});
      return kExitFailure;
    }
    g_memory_limit_mb.store(memory_limit_mb);
  }
  reenact::log::Info("worker_started",
                     {{"job_id", input.job_id},
                      {"take_id", input.take_id},
                      {"method", input.method},
                      {"take", input.take_path},
                      {"out", out_path},
                      {"reenactment_id", input.reenactment_id}},
                     "reenact-worker started");

  out.Line(
      {{"log", "reenact-worker: " + input.method + " on " + input.take_path + " -> " + out_path}});
  const absl::StatusOr<reenact::recon::MethodResult> result = reenact::recon::RunMethod(
      input, out_path, [&out](const reenact::Progress& p) { return out.Progress(p); },
      [&out](const std::string& line) {
        out.Line({{"log", line}});
      });
  if (!result.ok()) {
    const bool stopped = g_stop_signal != 0;
    std::string error =
        stopped ? "stopped by " + std::string(g_stop_signal == SIGINT ? "SIGINT" : "SIGTERM")
                : std::string(result.status().ToString());
    if (!stopped && IsOverLimit(error)) error = OverLimitError();
    out.Line({{"error", error}});
    reenact::log::Log(stopped ? reenact::log::Level::kInfo : reenact::log::Level::kError,
                      stopped ? "worker_stopped" : "worker_failed",
                      {{"job_id", input.job_id}, {"error", error}}, error);
    return stopped ? kExitStopped : kExitFailure;
  }
  nlohmann::json figures = nlohmann::json::object();
  for (const auto& [name, value] : result->figures) figures[name] = value;
  out.Line({{"result",
             {{"frames", result->frames},
              {"keyframes", result->keyframes},
              {"file_bytes", result->file_bytes},
              {"figures", figures}}}});
  reenact::log::Info("worker_finished",
                     {{"job_id", input.job_id},
                      {"frames", result->frames},
                      {"keyframes", result->keyframes},
                      {"file_bytes", result->file_bytes}},
                     "reenact-worker finished");
  return kExitOk;
}

// Reports an exception that escaped WorkerMain, as a failed job: a line on
// stdout and worker_failed in the log.
void ReportUncaught(const char* what) noexcept {
  try {
    std::string error = std::string("reenact-worker: uncaught exception: ") + what;
    if (IsOverLimit(error)) error = OverLimitError();
    Output().Line({{"error", error}});
    reenact::log::Error("worker_failed", {{"error", error}}, error);
  } catch (...) {
    // Reporting failed too: stderr is all that is left.
    std::fputs("reenact-worker: uncaught exception\n", stderr);
  }
}

// An exception that leaves a thread of the job (a decode or fit thread
// past the memory limit): reported as the main thread's would be, exit 1.
[[noreturn]] void OnTerminate() noexcept {
  if (const std::exception_ptr current = std::current_exception(); current != nullptr) {
    try {
      std::rethrow_exception(current);
    } catch (const std::exception& e) {
      ReportUncaught(e.what());
    } catch (...) {
      ReportUncaught("an exception of unknown type");
    }
    std::_Exit(kExitFailure);
  }
  std::abort();
}

}  // namespace

// An exception nothing else caught is a failed job (exit 1), not a
// std::terminate.
int main(int argc, char** argv) {
  std::set_terminate(OnTerminate);
  try {
    return WorkerMain(argc, argv);
  } catch (const std::exception& e) {
    ReportUncaught(e.what());
  } catch (...) {
    ReportUncaught("an exception of unknown type");
  }
  return kExitFailure;
}
