// End-to-end reconstruction benchmark (a command, not a Google Benchmark):
// runs the real reenact-worker on a synthetic 2-sensor take, as the server
// launches it, and reports take frames (instants) processed per second and
// the worker's peak resident memory.
//
//   build/bench/recon_e2e [--method rigid-carved] [--seconds 10] [--source take.mcap]
//                         [--work DIR] [--json FILE] [--bin DIR] [--option k=v,...]
//
// Without --source it synthesises a `--seconds` 2-sensor Kinect v2 take
// (512x424 depth, 1920x1080 colour, front kick) once and caches it in --work.
#include <sys/resource.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <string>

#include <nlohmann/json.hpp>

#include "absl/strings/str_format.h"
#include "absl/strings/str_split.h"
#include "common/base/flags.h"
#include "common/base/subprocess.h"
#include "common/io/reenactment_file.h"
#include "common/io/take.h"
#include "common/synth/synthesizer.h"

namespace reenact {
namespace {

namespace fs = std::filesystem;

int Run(int argc, char** argv) {
  std::vector<std::string> args(argv + 1, argv + argc);
  auto flags =
      Flags::Parse(args, {"method", "seconds", "source", "work", "json", "bin", "option"}, {});
  if (!flags.ok()) {
    std::cerr << "recon_e2e: " << flags.status().message() << "\n";
    return 2;
  }
  const std::string method = flags->GetOr("method", "rigid-carved");
  auto seconds = flags->GetDouble("seconds", 10.0);
  if (!seconds.ok()) {
    std::cerr << "recon_e2e: " << seconds.status().message() << "\n";
    return 2;
  }
  const std::string work = flags->GetOr("work", "/tmp/reenact_recon_e2e");
  const std::string bin =
      flags->GetOr("bin", (fs::path(argv[0]).parent_path().parent_path() / "bin").string());
  fs::create_directories(work);
  std::string source = flags->GetOr("source", "");
  if (source.empty()) {
    source = absl::StrFormat("%s/source-%gs-1080p.mcap", work, *seconds);
    if (!fs::exists(source)) {
      std::cerr << "recon_e2e: synthesising a " << *seconds << " s 2-sensor take into " << source
                << "\n";
      synth::SynthOptions options;
      // The sensors carry the jittered true skeleton (a device SDK stand-in):
      // these floors are the methods' own, apart from the tracker's accuracy.
      options.sensor_skeleton = synth::SynthOptions::SensorSkeleton::kTruth;
      options.motion = "builtin:front-kick";
      options.num_sensors = 2;
      options.seconds = *seconds;
      auto summary = synth::SynthesizeTake(options, source);
      if (!summary.ok()) {
        std::cerr << "recon_e2e: " << summary.status().message() << "\n";
        return 1;
      }
    }
  }
  auto take = TakeReader::Open(source);
  if (!take.ok()) {
    std::cerr << "recon_e2e: " << take.status().message() << "\n";
    return 1;
  }
  nlohmann::json options_json = nlohmann::json::object();
  for (absl::string_view kv : absl::StrSplit(flags->GetOr("option", ""), ',', absl::SkipEmpty())) {
    const auto eq = kv.find('=');
    if (eq == std::string::npos) {
      std::cerr << "recon_e2e: --option wants k=v[,k=v...]\n";
      return 2;
    }
    options_json[std::string(kv.substr(0, eq))] = std::string(kv.substr(eq + 1));
  }

  const std::string out = work + "/bench.reen";
  const std::vector<std::string> worker_argv = {bin + "/reenact-worker",
                                                "--take",
                                                source,
                                                "--method",
                                                method,
                                                "--options-json",
                                                options_json.dump(),
                                                "--out",
                                                out,
                                                "--reenactment-id",
                                                "r-bench",
                                                "--take-id",
                                                "bench",
                                                "--job-id",
                                                "bench"};
  SubprocessOptions sub;
  sub.stdout_path = work + "/progress.jsonl";
  sub.stderr_path = work + "/worker.log";
  fs::remove(sub.stdout_path);
  fs::remove(sub.stderr_path);
  const auto start = std::chrono::steady_clock::now();
  auto worker = Subprocess::Start(worker_argv, sub);
  if (!worker.ok()) {
    std::cerr << "recon_e2e: " << worker.status().message() << "\n";
    return 1;
  }
  auto exit = (*worker)->Wait();
  const double wall_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  if (!exit.ok() || !exit->exited || exit->exit_code != 0) {
    std::cerr << "recon_e2e: the worker failed ("
              << (exit.ok() ? exit->ToString() : std::string(exit.status().message())) << "); see "
              << sub.stderr_path << "\n";
    return 1;
  }
  struct rusage usage {};
  getrusage(RUSAGE_CHILDREN, &usage);
  const double peak_mib = usage.ru_maxrss / 1024.0;  // Linux: kilobytes.
  const double cpu_s = usage.ru_utime.tv_sec + usage.ru_utime.tv_usec * 1e-6 +
                       usage.ru_stime.tv_sec + usage.ru_stime.tv_usec * 1e-6;
  auto reenactment = ReadReenactmentFile(out, /*skip_keyframes=*/true);
  if (!reenactment.ok()) {
    std::cerr << "recon_e2e: " << reenactment.status().message() << "\n";
    return 1;
  }
  const int instants = static_cast<int>(reenactment->frames.size());
  const int sensors = static_cast<int>((*take)->sensors().size());
  nlohmann::json result = {
      {"method", method},
      {"take", source},
      {"sensors", sensors},
      {"instants", instants},
      {"sensor_frames", instants * sensors},
      {"wall_s", wall_s},
      {"instants_per_s", instants / wall_s},
      {"sensor_frames_per_s", instants * sensors / wall_s},
      {"worker_cpu_s", cpu_s},
      {"peak_rss_mib", peak_mib},
      {"reenactment_bytes", static_cast<int64_t>(fs::file_size(out))},
  };
  for (const auto& [key, value] : reenactment->info.figures()) result["figures"][key] = value;
  std::cout << result.dump(2) << "\n";
  if (flags->Has("json")) std::ofstream(flags->GetOr("json", "")) << result.dump(2) << "\n";
  return 0;
}

}  // namespace
}  // namespace reenact

int main(int argc, char** argv) { return reenact::Run(argc, argv); }
