// End-to-end scale-out benchmark (a command, not a Google Benchmark): the
// real reenact-server with no workers of its own (--workers none) and 1, 2,
// ... real reenact-worker --server processes on this machine, a synthetic
// 2-sensor take played in by the real reenactd. For each worker count it
// measures:
//   * throughput: --jobs whole jobs of the take submitted at once, from the
//     first submit to the last end (jobs per hour, instants per second);
//   * latency of one job split across the workers (--segments = workers),
//     when there are two or more;
//   * the protocol's overhead: time from submit to the first lease, and the
//     bytes the Work service streamed per job (JobAttempt.read_bytes: the
//     take, or the frames each phase of a split job reads, and part inputs;
//     part uploads).
//
//   build/bench/scale_out_e2e [--seconds 60] [--workers 1,2] [--jobs 2]
//                             [--method body] [--option k=v,...]
//                             [--source take.mcap] [--work DIR] [--bin DIR]
//                             [--json FILE]
//
// Without --source it synthesises a `--seconds` 2-sensor Kinect v2 take
// (512x424 depth, 1920x1080 colour, a CMU dance when the test data has it)
// once and caches it in --work.
#include <signal.h>

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <memory>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include <nlohmann/json.hpp>

#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "absl/strings/str_split.h"
#include "bench/e2e_util.h"
#include "common/base/flags.h"
#include "common/base/subprocess.h"
#include "common/synth/synthesizer.h"

namespace reenact {
namespace {

namespace fs = std::filesystem;
using bench::ReadText;

// Runs a command to its end; its stdout, or nullopt (the reason on stderr).
std::optional<std::string> Command(const std::string& work, const std::string& name,
                                   const std::vector<std::string>& argv, double timeout_s) {
  SubprocessOptions options;
  options.stdout_path = work + "/" + name + ".out";
  options.stderr_path = work + "/" + name + ".err";
  fs::remove(options.stdout_path);
  fs::remove(options.stderr_path);
  auto child = Subprocess::Start(argv, options);
  if (!child.ok()) {
    std::cerr << "scale_out_e2e: " << child.status().message() << "\n";
    return std::nullopt;
  }
  auto exit = (*child)->Wait(timeout_s);
  if (!exit.ok() || !exit->exited || exit->exit_code != 0) {
    std::cerr << "scale_out_e2e: " << name << " failed; see " << options.stderr_path << "\n"
              << ReadText(options.stderr_path);
    return std::nullopt;
  }
  return ReadText(options.stdout_path);
}

std::unique_ptr<Subprocess> Background(const std::string& work, const std::string& name,
                                       const std::vector<std::string>& argv) {
  SubprocessOptions options;
  options.stdout_path = work + "/" + name + ".out";
  options.stderr_path = work + "/" + name + ".err";
  auto child = Subprocess::Start(argv, options);
  if (!child.ok()) {
    std::cerr << "scale_out_e2e: " << child.status().message() << "\n";
    return nullptr;
  }
  return std::move(*child);
}

void Stop(std::unique_ptr<Subprocess>& process) {
  if (process == nullptr) return;
  (void)process->Signal(SIGTERM);
  (void)process->Wait(30);
  process.reset();
}

struct JobTimes {
  double first_lease_s = 0.0;  // Submit to the job's (or its first part's) start.
  double seconds = 0.0;        // Submit to the end.
  int64_t input_bytes = 0;     // Part files streamed to later parts.
  int64_t upload_bytes = 0;    // Part files uploaded (the reenactment not counted).
  int64_t read_bytes = 0;      // Streamed by the server: take, selections, inputs.
};

// JobAttempt.read_bytes of the last attempt in `history`.
int64_t LastRead(const nlohmann::json& history) {
  return history.is_array() && !history.empty() ? history.back().value("read_bytes", int64_t{0})
                                                : 0;
}

JobTimes TimesOf(const nlohmann::json& job) {
  JobTimes t;
  const double submitted = job["submitted_unix_ns"].get<double>();
  double started = job["started_unix_ns"].get<double>();
  int segments = job.value("segments", 0);
  t.read_bytes = LastRead(job["attempt_history"]);
  for (const auto& part : job["parts"]) {
    t.read_bytes += LastRead(part["attempt_history"]);
    const int64_t bytes = part.value("file_bytes", int64_t{0});
    const std::string name = part["name"].get<std::string>();
    if (name == "stitch") continue;
    t.upload_bytes += bytes;
    // The prepared file goes to every segment and the stitch, each
    // segment's to the stitch.
    t.input_bytes += name == "prepare" ? bytes * (segments + 1) : bytes;
  }
  t.first_lease_s = 1e-9 * (started - submitted);
  t.seconds = 1e-9 * (job["finished_unix_ns"].get<double>() - submitted);
  return t;
}

int Run(int argc, char** argv) {
  std::vector<std::string> args(argv + 1, argv + argc);
  auto flags = Flags::Parse(
      args, {"seconds", "workers", "jobs", "method", "option", "source", "work", "bin", "json"},
      {});
  if (!flags.ok()) {
    std::cerr << "scale_out_e2e: " << flags.status().message() << "\n";
    return 2;
  }
  auto seconds = flags->GetDouble("seconds", 60.0);
  auto jobs_per_run = flags->GetInt("jobs", 2);
  if (!seconds.ok() || !jobs_per_run.ok() || *jobs_per_run < 1) {
    std::cerr << "scale_out_e2e: --seconds and --jobs take positive numbers\n";
    return 2;
  }
  std::vector<int> worker_counts;
  for (absl::string_view w : absl::StrSplit(flags->GetOr("workers", "1,2"), ',')) {
    int n = 0;
    if (!absl::SimpleAtoi(w, &n) || n < 1 || n > 64) {
      std::cerr << "scale_out_e2e: --workers takes counts 1..64, e.g. 1,2\n";
      return 2;
    }
    worker_counts.push_back(n);
  }
  const std::string method = flags->GetOr("method", "body");
  const std::string work = flags->GetOr("work", "/tmp/reenact_scale_out_e2e");
  const std::string bin =
      flags->GetOr("bin", (fs::path(argv[0]).parent_path().parent_path() / "bin").string());
  fs::create_directories(work);

  std::string source = flags->GetOr("source", "");
  if (source.empty()) {
    source = absl::StrFormat("%s/source-%gs-1080p.mcap", work, *seconds);
    if (!fs::exists(source)) {
      std::cerr << "scale_out_e2e: synthesising a " << *seconds << " s 2-sensor take into "
                << source << "\n";
      synth::SynthOptions options;
      options.sensor_skeleton = synth::SynthOptions::SensorSkeleton::kTruth;
      const fs::path dance = fs::path("../shared/data/mocap/cmu/01_01.bvh");
      options.motion = fs::exists(dance) ? dance.string() : "builtin:front-kick";
      options.num_sensors = 2;
      options.seconds = *seconds;
      auto summary = synth::SynthesizeTake(options, source);
      if (!summary.ok()) {
        std::cerr << "scale_out_e2e: " << summary.status().message() << "\n";
        return 1;
      }
    }
  }
  const int64_t take_bytes = static_cast<int64_t>(fs::file_size(source));

  // The server, and the take played into it once.
  const std::string data = work + "/data";
  fs::remove_all(data);
  // A port file left by an earlier run would name a server that is gone.
  fs::remove(work + "/server.port");
  fs::remove_all(work + "/spool");
  std::unique_ptr<Subprocess> server =
      Background(work, "server",
                 {bin + "/reenact-server", "--data", data, "--listen", "127.0.0.1:0", "--port-file",
                  work + "/server.port", "--workers", "none"});
  if (server == nullptr) return 1;
  std::string address;
  for (int i = 0; i < 400 && address.empty(); ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
    const std::string text = ReadText(work + "/server.port");
    if (const auto nl = text.find('\n'); nl != std::string::npos) address = text.substr(0, nl);
  }
  if (address.empty()) {
    std::cerr << "scale_out_e2e: the server did not start; see " << work << "/server.err\n";
    return 1;
  }
  if (!Command(work, "reenactd",
               {bin + "/reenactd", "--server", address, "--source", "playback:" + source, "--fast",
                "--once", "--take-name", "scale-out", "--spool", work + "/spool"},
               3600)) {
    return 1;
  }
  const auto listed = Command(
      work, "takes", {bin + "/reenact", "takes", "list", "--server", address, "--json"}, 60);
  const auto takes = nlohmann::json::parse(listed.value_or(""), nullptr, false);
  if (!takes.is_array() || takes.empty()) {
    std::cerr << "scale_out_e2e: the take did not arrive\n";
    return 1;
  }
  const std::string take_id = takes[0]["take_id"].get<std::string>();
  std::vector<std::string> option_args;
  for (absl::string_view kv : absl::StrSplit(flags->GetOr("option", ""), ',', absl::SkipEmpty())) {
    option_args.insert(option_args.end(), {"--option", std::string(kv)});
  }

  auto submit = [&](const std::string& name, int segments) -> std::optional<std::string> {
    std::vector<std::string> argv = {bin + "/reenact", "jobs",  "submit",   "--server", address,
                                     "--take",         take_id, "--method", method,     "--json"};
    argv.insert(argv.end(), option_args.begin(), option_args.end());
    if (segments > 1) argv.insert(argv.end(), {"--segments", std::to_string(segments)});
    const auto out = Command(work, name, argv, 60);
    const auto job = nlohmann::json::parse(out.value_or(""), nullptr, false);
    if (!job.is_object() || !job.contains("job_id")) return std::nullopt;
    return job["job_id"].get<std::string>();
  };
  auto wait_for = [&](const std::string& job_id) -> std::optional<nlohmann::json> {
    while (true) {
      const auto out =
          Command(work, "show",
                  {bin + "/reenact", "jobs", "show", job_id, "--server", address, "--json"}, 60);
      const auto job = nlohmann::json::parse(out.value_or(""), nullptr, false);
      if (!job.is_object()) return std::nullopt;
      const std::string state = job["state"].get<std::string>();
      if (state == "succeeded") return job;
      if (state == "failed" || state == "cancelled") {
        std::cerr << "scale_out_e2e: job " << job_id << " " << state << ": " << job["error"]
                  << "\n";
        return std::nullopt;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(500));
    }
  };

  nlohmann::json runs = nlohmann::json::array();
  for (const int workers : worker_counts) {
    std::vector<std::unique_ptr<Subprocess>> agents;
    for (int w = 0; w < workers; ++w) {
      const std::string scratch = absl::StrCat(work, "/scratch-", w);
      fs::create_directories(scratch);
      agents.push_back(Background(work, absl::StrCat("worker-", w),
                                  {bin + "/reenact-worker", "--server", address, "--loop", "--name",
                                   absl::StrCat("bench-", w), "--scratch", scratch}));
      if (agents.back() == nullptr) return 1;
    }
    nlohmann::json run = {{"workers", workers}};

    // Throughput: whole jobs, all submitted at once.
    const auto start = std::chrono::steady_clock::now();
    std::vector<std::string> ids;
    for (int j = 0; j < *jobs_per_run; ++j) {
      const auto id = submit(absl::StrCat("submit-", workers, "-", j), 0);
      if (!id) return 1;
      ids.push_back(*id);
    }
    double first_lease_sum = 0.0;
    int64_t read_sum = 0;
    for (const std::string& id : ids) {
      const auto job = wait_for(id);
      if (!job) return 1;
      first_lease_sum += TimesOf(*job).first_lease_s;
      read_sum += TimesOf(*job).read_bytes;
    }
    const double wall_s =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    const double jobs_per_hour = 3600.0 * *jobs_per_run / wall_s;
    run["throughput"] = {{"jobs", *jobs_per_run},
                         {"wall_s", wall_s},
                         {"jobs_per_hour", jobs_per_hour},
                         {"first_lease_s_mean", first_lease_sum / *jobs_per_run},
                         {"bytes_streamed_per_job", read_sum / *jobs_per_run}};

    // Latency: one job split across the workers.
    if (workers > 1) {
      const auto id = submit(absl::StrCat("submit-segmented-", workers), workers);
      if (!id) return 1;
      const auto job = wait_for(*id);
      if (!job) return 1;
      const JobTimes t = TimesOf(*job);
      run["segmented"] = {{"segments", workers},
                          {"seconds", t.seconds},
                          {"first_lease_s", t.first_lease_s},
                          {"bytes_streamed", t.read_bytes},
                          {"take_bytes_streamed", t.read_bytes - t.input_bytes},
                          {"part_input_bytes", t.input_bytes},
                          {"part_upload_bytes", t.upload_bytes}};
    }
    for (auto& agent : agents) Stop(agent);
    std::cerr << "scale_out_e2e: " << run.dump() << "\n";
    runs.push_back(run);
  }
  Stop(server);

  nlohmann::json result = {{"method", method},
                           {"take", source},
                           {"take_seconds", *seconds},
                           {"take_bytes", take_bytes},
                           {"hardware_threads", std::thread::hardware_concurrency()},
                           {"runs", runs}};
  if (runs.size() >= 2) {
    result["throughput_speedup"] = runs.back()["throughput"]["jobs_per_hour"].get<double>() /
                                   runs.front()["throughput"]["jobs_per_hour"].get<double>();
  }
  std::cout << result.dump(2) << "\n";
  if (flags->Has("json")) std::ofstream(flags->GetOr("json", "")) << result.dump(2) << "\n";
  return 0;
}

}  // namespace
}  // namespace reenact

int main(int argc, char** argv) { return reenact::Run(argc, argv); }
