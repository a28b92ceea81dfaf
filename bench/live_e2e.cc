// End-to-end live benchmark (a command, not a Google Benchmark): the real
// reenactd plays a synthetic 2-sensor take in real time (30 fps) into the
// real reenact-server over loopback; as soon as the take is recording, a
// live body job follows it (jobs submit --method body --live)
// and a Follow subscriber in this process receives its preview. Reports the
// latency of each fitted frame from the FrameSet's arrival at the server's
// Ingest handler to its publication (published - arrived, server clock) and
// to its receipt here (received - arrived; same machine, same clock), the
// frame sets followed, skipped and unfitted, the fit time per frame and the
// server's CPU.
//
//   build/bench/live_e2e [--seconds 10] [--source take.mcap] [--work DIR]
//                        [--model procedural] [--json FILE] [--bin DIR]
//                        [--sensor-skeleton none|truth]
//
// Without --source it synthesises a `--seconds` 2-sensor Kinect v2 take
// (512x424 depth, 1920x1080 colour, front kick, procedural body) once and
// caches it in --work; its sensors carry no skeleton (reenactd tracks them)
// unless --sensor-skeleton truth. The offline half of the job (the worker
// run once the take is complete) is not waited for.
#include <unistd.h>

#include <signal.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <sstream>
#include <string>
#include <thread>

#include <nlohmann/json.hpp>

#include "absl/strings/str_format.h"
#include "bench/e2e_util.h"
#include "clients/sdk/follow_stats.h"
#include "clients/sdk/jobs_client.h"
#include "clients/sdk/reenactments_client.h"
#include "clients/sdk/takes_client.h"
#include "common/base/flags.h"
#include "common/base/subprocess.h"
#include "common/base/time.h"
#include "common/io/take.h"
#include "common/synth/synthesizer.h"

namespace reenact {
namespace {

namespace fs = std::filesystem;

using bench::ProcessCpuSeconds;
using bench::ReadText;

// The take to play: --source, or a synthetic one cached in `work`.
absl::StatusOr<std::string> SourceTake(const Flags& flags, const std::string& work,
                                       double seconds) {
  if (auto source = flags.Get("source")) return *source;
  const std::string skeleton = flags.GetOr("sensor-skeleton", "none");
  if (skeleton != "none" && skeleton != "truth") {
    return absl::InvalidArgumentError("--sensor-skeleton must be none or truth");
  }
  const std::string path = absl::StrFormat("%s/source-%gs-1080p-%s.mcap", work, seconds, skeleton);
  if (fs::exists(path)) return path;
  std::cerr << "live_e2e: synthesising a " << seconds << " s 2-sensor take into " << path << "\n";
  synth::SynthOptions options;
  // none: the sensors carry no skeleton and reenactd tracks them (its CPU
  // share included); truth: the jittered true skeleton (a device SDK
  // stand-in), for the methods' own floor apart from the tracker.
  options.sensor_skeleton = skeleton == "truth" ? synth::SynthOptions::SensorSkeleton::kTruth
                                                : synth::SynthOptions::SensorSkeleton::kNone;
  options.motion = "builtin:front-kick";
  options.num_sensors = 2;
  options.seconds = seconds;
  options.ground_truth_mesh = false;
  absl::StatusOr<synth::SynthSummary> summary = synth::SynthesizeTake(options, path);
  if (!summary.ok()) return summary.status();
  return path;
}

// Starts reenact-server on a fresh data folder; its address in `address`.
absl::StatusOr<std::unique_ptr<Subprocess>> StartServer(const std::string& bin,
                                                        const std::string& work,
                                                        std::string* address) {
  fs::remove_all(work + "/server");
  fs::remove(work + "/server.port");
  SubprocessOptions options;
  options.stderr_path = work + "/server.log";
  fs::remove(options.stderr_path);
  absl::StatusOr<std::unique_ptr<Subprocess>> server =
      Subprocess::Start({bin + "/reenact-server", "--data", work + "/server", "--listen",
                         "127.0.0.1:0", "--port-file", work + "/server.port", "--jobs", "1"},
                        options);
  if (!server.ok()) return server.status();
  for (int i = 0; i < 200 && address->empty(); ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
    const std::string text = ReadText(work + "/server.port");
    if (text.find('\n') != std::string::npos) *address = text.substr(0, text.find('\n'));
  }
  if (address->empty()) {
    return absl::UnavailableError("reenact-server did not start; see " + work + "/server.log");
  }
  return server;
}

// Waits for the daemon's take to be recording and submits a live body job.
absl::StatusOr<v1::Job> SubmitLiveJob(const client::ConnectionOptions& connection,
                                      const std::string& model, double timeout_s) {
  const client::TakesClient takes(connection);
  const client::JobsClient jobs(connection);
  const int64_t deadline_ns = SteadyNowNs() + SecondsToNs(timeout_s);
  while (SteadyNowNs() < deadline_ns) {
    absl::StatusOr<std::vector<v1::Take>> recording = takes.List(v1::TAKE_STATE_RECORDING);
    if (recording.ok() && !recording->empty()) {
      absl::StatusOr<v1::Job> job =
          jobs.Submit(recording->front().take_id(), "body", {{"model", model}}, /*segments=*/0,
                      /*live=*/true);
      // Unavailable: the take is being opened; try again.
      if (job.ok() || !absl::IsUnavailable(job.status())) return job;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  return absl::DeadlineExceededError("no take was recording in time");
}

// What the subscriber saw.
struct FollowResult {
  client::FollowStats stats;
  int meshes = 0;
  uint64_t first_sequence = 0;
  absl::StatusOr<v1::FollowEnd> end = absl::UnknownError("not run");
};

void Follow(const client::ConnectionOptions& connection, const std::string& job_id,
            FollowResult* result) {
  result->end =
      client::ReenactmentsClient(connection).Follow(job_id, [&](const v1::FollowEvent& event) {
        result->stats.Add(event, WallNowNs());
        if (event.has_mesh()) ++result->meshes;
        if (event.has_frame() && result->first_sequence == 0) {
          result->first_sequence = event.sequence();
        }
        return true;
      });
}

nlohmann::json DistributionJson(const client::Distribution& d) {
  return {{"p50_ms", d.p50_ms}, {"p95_ms", d.p95_ms}, {"max_ms", d.max_ms}, {"mean_ms", d.mean_ms}};
}

void Report(const FollowResult& follow, const v1::FollowEnd& end, int sensors, double fps,
            double seconds, double server_cpu_s, const std::string& json_path) {
  const client::Distribution latency = follow.stats.latency();
  const client::Distribution receive = follow.stats.receive_delay();
  const client::Distribution fit = follow.stats.fit();
  const int64_t within = follow.stats.FramesWithin(100.0);
  std::cout << absl::StrFormat(
      "live_e2e: %d sensors x %.0f fps, %.0f s played in real time on loopback, %d cores\n"
      "  follower          %d frame sets received (from set %d), %d fitted and published, "
      "%d skipped, %d unfitted; %d meshes\n"
      "  published-arrived p50 %.1f ms, p95 %.1f ms, max %.1f ms (mean %.1f); "
      "%d of %d frames within 100 ms\n"
      "  received-arrived  p50 %.1f ms, p95 %.1f ms, max %.1f ms (mean %.1f)\n"
      "  fit per frame     p50 %.1f ms, p95 %.1f ms, max %.1f ms (mean %.1f)\n"
      "  server CPU        %.0f%% of one core\n",
      sensors, fps, seconds, static_cast<int>(std::thread::hardware_concurrency()),
      end.frames_received(), follow.first_sequence, end.frames_followed(), end.frames_skipped(),
      end.frames_unfitted(), follow.meshes, latency.p50_ms, latency.p95_ms, latency.max_ms,
      latency.mean_ms, within, follow.stats.frames(), receive.p50_ms, receive.p95_ms,
      receive.max_ms, receive.mean_ms, fit.p50_ms, fit.p95_ms, fit.max_ms, fit.mean_ms,
      100.0 * server_cpu_s / seconds);
  if (json_path.empty()) return;
  const nlohmann::json report = {{"sensors", sensors},
                                 {"fps", fps},
                                 {"seconds", seconds},
                                 {"cores", std::thread::hardware_concurrency()},
                                 {"frames_received", end.frames_received()},
                                 {"frames_followed", end.frames_followed()},
                                 {"frames_skipped", end.frames_skipped()},
                                 {"frames_unfitted", end.frames_unfitted()},
                                 {"frames_published_within_100ms", within},
                                 {"meshes", follow.meshes},
                                 {"published_minus_arrived", DistributionJson(latency)},
                                 {"received_minus_arrived", DistributionJson(receive)},
                                 {"fit", DistributionJson(fit)},
                                 {"server_cpu_share_of_one_core", server_cpu_s / seconds}};
  std::ofstream(json_path) << report.dump(2) << "\n";
}

int Fail(const std::string& message) {
  std::cerr << "live_e2e: " << message << "\n";
  return 1;
}

int Run(int argc, char** argv) {
  std::vector<std::string> args(argv + 1, argv + argc);
  auto flags = Flags::Parse(
      args, {"seconds", "source", "work", "json", "bin", "model", "sensor-skeleton"}, {});
  if (!flags.ok()) {
    std::cerr << "live_e2e: " << flags.status().message() << "\n";
    return 2;
  }
  const double seconds = *flags->GetDouble("seconds", 10.0);
  const std::string work = flags->GetOr("work", "/tmp/reenact_live_e2e");
  const std::string bin =
      flags->GetOr("bin", (fs::path(argv[0]).parent_path().parent_path() / "bin").string());
  fs::create_directories(work);
  absl::StatusOr<std::string> source = SourceTake(*flags, work, seconds);
  if (!source.ok()) return Fail(std::string(source.status().message()));
  absl::StatusOr<std::unique_ptr<TakeReader>> take = TakeReader::Open(*source);
  if (!take.ok()) return Fail(std::string(take.status().message()));
  const int sensors = static_cast<int>((*take)->sensors().size());
  const double fps = (*take)->info().fps();

  std::string address;
  absl::StatusOr<std::unique_ptr<Subprocess>> server = StartServer(bin, work, &address);
  if (!server.ok()) return Fail(std::string(server.status().message()));
  const double server_cpu_before = ProcessCpuSeconds((*server)->pid());
  SubprocessOptions daemon_options;
  daemon_options.stderr_path = work + "/daemon.log";
  fs::remove_all(work + "/spool");
  fs::remove(daemon_options.stderr_path);
  absl::StatusOr<std::unique_ptr<Subprocess>> daemon = Subprocess::Start(
      {bin + "/reenactd", "--server", address, "--source", "playback:" + *source, "--once",
       "--take-name", "live-bench", "--spool", work + "/spool", "--control", "127.0.0.1:0"},
      daemon_options);
  if (!daemon.ok()) return Fail(std::string(daemon.status().message()));

  client::ConnectionOptions connection;
  connection.address = address;
  absl::StatusOr<v1::Job> job = SubmitLiveJob(connection, flags->GetOr("model", "procedural"), 30);
  if (!job.ok()) return Fail(std::string(job.status().message()));
  FollowResult follow;
  std::thread subscriber([&] { Follow(connection, job->job_id(), &follow); });
  const absl::StatusOr<ExitInfo> daemon_exit = (*daemon)->Wait(seconds + 120);
  subscriber.join();
  const double server_cpu_s = ProcessCpuSeconds((*server)->pid()) - server_cpu_before;
  (void)(*server)->Signal(SIGTERM);
  (void)(*server)->Wait(30);
  if (!daemon_exit.ok() || !daemon_exit->exited || daemon_exit->exit_code != 0) {
    return Fail("reenactd failed; see " + work + "/daemon.log");
  }
  if (!follow.end.ok()) return Fail(std::string(follow.end.status().message()));
  Report(follow, *follow.end, sensors, fps, seconds, server_cpu_s, flags->GetOr("json", ""));
  return 0;
}

}  // namespace
}  // namespace reenact

int main(int argc, char** argv) { return reenact::Run(argc, argv); }
