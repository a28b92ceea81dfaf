// End-to-end capture benchmark: the real reenactd streams 2 sensors at 30 fps
// at Kinect v2 resolution (512x424 RVL depth, 1920x1080 JPEG colour) into the
// real reenact-server over loopback for a given time, then reports sustained
// frames/s, drops, the daemon's CPU as a share of one core, latency from a
// FrameSet's capture stamp to the acknowledgement that made it durable on the
// server, and bytes per FrameSet.
//
//   build/bench/capture_e2e [--seconds 60] [--source take.mcap] [--work DIR] [--json FILE]
//                           [--tracker auto|on|off] [--tracker-refine on|off] [--tls]
//
// --tls: the uplink over TLS (certificates from deploy/make-certs.sh, made
// once in --work), to measure what encryption costs the capture path.
//
// The synthesised source carries no skeleton, so reenactd's body tracker
// runs on every frame of both sensors (--tracker auto), as with real depth
// cameras.
//
// Without --source it synthesises a 2 s 2-sensor take once (cached in
// --work) and the daemon loops it in real time.
#include <unistd.h>

#include <signal.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <nlohmann/json.hpp>

#include "absl/strings/str_format.h"
#include "bench/e2e_util.h"
#include "common/base/flags.h"
#include "common/base/subprocess.h"
#include "common/io/take.h"
#include "common/synth/synthesizer.h"

namespace reenact {
namespace {

namespace fs = std::filesystem;

using bench::ProcessCpuSeconds;
using bench::ReadText;

int Run(int argc, char** argv) {
  std::vector<std::string> args(argv + 1, argv + argc);
  auto flags = Flags::Parse(
      args, {"seconds", "source", "work", "json", "bin", "tracker", "tracker-refine"}, {"tls"});
  if (!flags.ok()) {
    std::cerr << "capture_e2e: " << flags.status().message() << "\n";
    return 2;
  }
  const double seconds = *flags->GetDouble("seconds", 60.0);
  const std::string work = flags->GetOr("work", "/tmp/reenact_capture_e2e");
  const std::string bin =
      flags->GetOr("bin", (fs::path(argv[0]).parent_path().parent_path() / "bin").string());
  fs::create_directories(work);
  std::string source = flags->GetOr("source", "");
  if (source.empty()) {
    source = work + "/source-2s-1080p.mcap";
    if (!fs::exists(source)) {
      std::cerr << "capture_e2e: synthesising a 2 s 2-sensor 1080p take into " << source << "\n";
      synth::SynthOptions options;
      options.motion = "builtin:front-kick";
      options.num_sensors = 2;
      options.seconds = 2.0;
      options.ground_truth_mesh = false;
      auto summary = synth::SynthesizeTake(options, source);
      if (!summary.ok()) {
        std::cerr << "capture_e2e: " << summary.status().message() << "\n";
        return 1;
      }
    }
  }
  auto take = TakeReader::Open(source);
  if (!take.ok()) {
    std::cerr << "capture_e2e: " << take.status().message() << "\n";
    return 1;
  }
  const int sensors = static_cast<int>((*take)->sensors().size());
  const double fps = (*take)->info().fps();

  fs::remove_all(work + "/server");
  fs::remove_all(work + "/spool");
  fs::remove(work + "/server.port");
  fs::remove(work + "/stats.json");
  const bool tls = flags->Has("tls");
  if (tls && !fs::exists(work + "/tls/server.pem")) {
    const std::string script =
        (fs::path(bin).parent_path().parent_path() / "deploy" / "make-certs.sh").string();
    if (std::system(("bash " + script + " " + work + "/tls >/dev/null").c_str()) != 0) {
      std::cerr << "capture_e2e: " << script << " failed\n";
      return 1;
    }
  }
  SubprocessOptions server_options;
  server_options.stderr_path = work + "/server.log";
  std::vector<std::string> server_args = {
      bin + "/reenact-server", "--data",      work + "/server",     "--listen",
      "127.0.0.1:0",           "--port-file", work + "/server.port"};
  if (tls) {
    server_args.insert(server_args.end(), {"--tls-cert", work + "/tls/server.pem", "--tls-key",
                                           work + "/tls/server.key"});
  }
  auto server = Subprocess::Start(server_args, server_options);
  if (!server.ok()) {
    std::cerr << "capture_e2e: " << server.status().message() << "\n";
    return 1;
  }
  std::string address;
  for (int i = 0; i < 200 && address.empty(); ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
    const std::string text = ReadText(work + "/server.port");
    if (text.find('\n') != std::string::npos) address = text.substr(0, text.find('\n'));
  }
  if (address.empty()) {
    std::cerr << "capture_e2e: reenact-server did not start; see " << work << "/server.log\n";
    return 1;
  }
  SubprocessOptions daemon_options;
  daemon_options.stderr_path = work + "/daemon.log";
  const double server_cpu_before = ProcessCpuSeconds((*server)->pid());
  std::vector<std::string> daemon_args = {bin + "/reenactd",
                                          "--server",
                                          address,
                                          "--source",
                                          "playback:" + source,
                                          "--loop",
                                          "--max-seconds",
                                          absl::StrFormat("%g", seconds),
                                          "--once",
                                          "--spool",
                                          work + "/spool",
                                          "--control",
                                          "127.0.0.1:0",
                                          "--stats-json",
                                          work + "/stats.json",
                                          "--tracker",
                                          flags->GetOr("tracker", "auto"),
                                          "--tracker-refine",
                                          flags->GetOr("tracker-refine", "off")};
  if (tls) daemon_args.insert(daemon_args.end(), {"--tls-ca", work + "/tls/ca.pem"});
  auto daemon = Subprocess::Start(daemon_args, daemon_options);
  if (!daemon.ok()) {
    std::cerr << "capture_e2e: " << daemon.status().message() << "\n";
    return 1;
  }
  auto exit = (*daemon)->Wait(seconds + 120);
  const double server_cpu = ProcessCpuSeconds((*server)->pid()) - server_cpu_before;
  (void)(*server)->Signal(SIGTERM);
  (void)(*server)->Wait(30);
  if (!exit.ok() || !exit->exited || exit->exit_code != 0) {
    std::cerr << "capture_e2e: reenactd failed ("
              << (exit.ok() ? exit->ToString() : std::string(exit.status().message())) << "); see "
              << work << "/daemon.log\n";
    return 1;
  }
  const auto stats = nlohmann::json::parse(ReadText(work + "/stats.json"), nullptr, false);
  if (stats.is_discarded()) {
    std::cerr << "capture_e2e: no stats in " << work << "/stats.json\n";
    return 1;
  }
  const double frame_sets = stats.value("frame_sets_durable", 0.0);
  int64_t frames = 0;
  for (const auto& [id, n] : stats["frames_per_sensor"].items()) frames += n.get<int64_t>();
  const double cpu_s = stats.value("cpu_s", 0.0);
  const double wall_s = stats.value("wall_s", 0.0);
  const double drops = stats.value("frames_dropped", 0.0) + stats.value("frame_sets_refused", 0.0);
  nlohmann::json report = {
      {"tls", tls},
      {"sensors", sensors},
      {"source_fps", fps},
      {"seconds", seconds},
      {"frame_sets_durable", frame_sets},
      {"frames", frames},
      {"frame_sets_per_s", frame_sets / seconds},
      {"frames_per_s", static_cast<double>(frames) / seconds},
      {"expected_frames_per_s", sensors * fps},
      {"drops", drops},
      {"frames_duplicate", stats.value("frames_duplicate", 0.0)},
      {"daemon_cpu_s", cpu_s},
      {"daemon_wall_s", wall_s},
      {"daemon_cpu_share_of_one_core", cpu_s / seconds},
      {"server_cpu_share_of_one_core", server_cpu / seconds},
      {"latency_ms", stats["latency_ms"]},
      {"skew_p50_ms", stats.value("skew_p50_ms", 0.0)},
      {"skew_p99_ms", stats.value("skew_p99_ms", 0.0)},
      {"bytes_per_frame_set", stats.value("frame_set_bytes_mean", 0.0)},
      {"reconnects", stats.value("reconnects", 0)},
  };
  std::cout << absl::StrFormat(
      "capture_e2e: %d sensors x %.0f fps, %.0f s on loopback\n"
      "  sustained        %.2f frame sets/s, %.2f frames/s (source: %.0f frames/s)\n"
      "  drops            %.0f (duplicates %.0f)\n"
      "  daemon CPU       %.1f%% of one core (%.1f s CPU in %.1f s)\n"
      "  server CPU       %.1f%% of one core\n"
      "  capture->durable p50 %.1f ms, p99 %.1f ms, max %.1f ms\n"
      "  sync skew        p50 %.2f ms, p99 %.2f ms\n"
      "  bytes/FrameSet   %.0f (%.2f MB/s)\n",
      sensors, fps, seconds, frame_sets / seconds, static_cast<double>(frames) / seconds,
      sensors * fps, drops, stats.value("frames_duplicate", 0.0), 100.0 * cpu_s / seconds, cpu_s,
      wall_s, 100.0 * server_cpu / seconds, stats["latency_ms"].value("p50", 0.0),
      stats["latency_ms"].value("p99", 0.0), stats["latency_ms"].value("max", 0.0),
      stats.value("skew_p50_ms", 0.0), stats.value("skew_p99_ms", 0.0),
      stats.value("frame_set_bytes_mean", 0.0),
      stats.value("frame_set_bytes_mean", 0.0) * frame_sets / seconds / 1e6);
  if (auto json_path = flags->Get("json")) {
    std::ofstream(*json_path) << report.dump(2) << "\n";
  }
  return 0;
}

}  // namespace
}  // namespace reenact

int main(int argc, char** argv) { return reenact::Run(argc, argv); }
