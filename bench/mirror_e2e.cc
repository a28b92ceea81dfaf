// End-to-end benchmark of the live magic mirror (a command, not a Google
// Benchmark): the real reenactd plays a synthetic one-sensor take in real
// time (30 fps, Kinect v2 sizes: 512x424 depth, 1920x1080 colour, no
// skeleton from the sensor, so reenactd's body tracker runs on every frame)
// into the real reenact-server over loopback, and the real reenact-mirror
// follows the daemon's live stream (--daemon), grades the learner against a
// body-model teacher and draws every frame headless (EGL) at the mirror's
// size. Reports the frames the mirror drew per second of learner time, the
// frames it dropped, the learner-to-screen latency (from the frame's arrival
// on the capture host to its picture handed on; one machine, one clock), the
// mirror's time per frame by stage, and the daemon's CPU.
//
//   build/bench/mirror_e2e [--seconds 10] [--width 960] [--height 540]
//                          [--msaa 4] [--work DIR] [--json FILE] [--bin DIR]
//
// --msaa is reenact-mirror's (default 4, as the mirror's). On a software
// OpenGL (llvmpipe) 0 is the setting for live use: multisampling there
// makes the teacher's render several times slower.
//
// The teacher is a reenactment of a synthetic take's ground truth (body
// model; clients/view/truth_reenactment.h), made once and cached in --work
// with the learner's take. Target: >= 30 frames/s (the sensor's rate) on 2
// cores with tracking on.
#include <signal.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <string>
#include <thread>

#include <nlohmann/json.hpp>

#include "absl/strings/str_format.h"
#include "bench/e2e_util.h"
#include "clients/view/truth_reenactment.h"
#include "common/base/flags.h"
#include "common/base/subprocess.h"
#include "common/body/procedural_body.h"
#include "common/io/reenactment_convert.h"
#include "common/io/take.h"
#include "common/synth/synthesizer.h"

namespace reenact {
namespace {

namespace fs = std::filesystem;

using bench::ProcessCpuSeconds;
using bench::ReadText;

int Fail(const std::string& message) {
  std::cerr << "mirror_e2e: " << message << "\n";
  return 1;
}

// The teacher: 2 s of the front kick, its ground truth as a body
// reenactment, cached in `work`.
absl::StatusOr<std::string> TeacherReen(const std::string& work) {
  const std::string reen = work + "/teacher.reen";
  if (fs::exists(reen)) return reen;
  synth::SynthOptions options;
  options.motion = "builtin:front-kick";
  options.num_sensors = 1;
  options.seconds = 2.0;
  options.color_width = 480;
  options.color_height = 270;
  const std::string take_path = work + "/teacher.mcap";
  if (auto s = synth::SynthesizeTake(options, take_path); !s.ok()) return s.status();
  absl::StatusOr<std::unique_ptr<TakeReader>> take = TakeReader::Open(take_path);
  if (!take.ok()) return take.status();
  absl::StatusOr<body::BodyModel> model = body::BuildProceduralBody();
  if (!model.ok()) return model.status();
  absl::StatusOr<Reenactment> data = view::testing::MakeTruthBodyReenactment(**take, *model);
  if (!data.ok()) return data.status();
  if (absl::Status written = WriteReenactment(*data, reen); !written.ok()) return written;
  return reen;
}

// The learner: the kick after 2 s of standing, `seconds` in all, one sensor
// with no skeleton, cached in `work`.
absl::StatusOr<std::string> LearnerTake(const std::string& work, double seconds) {
  const std::string path = absl::StrFormat("%s/learner-%gs-1080p.mcap", work, seconds);
  if (fs::exists(path)) return path;
  std::cerr << "mirror_e2e: synthesising a " << seconds << " s one-sensor take into " << path
            << "\n";
  synth::SynthOptions options;
  options.motion = "builtin:front-kick";
  options.sensor_skeleton = synth::SynthOptions::SensorSkeleton::kNone;
  options.num_sensors = 1;
  options.seconds = seconds;
  options.lead_in_s = 2.0;
  options.ground_truth_mesh = false;
  options.seed = 2;
  if (auto s = synth::SynthesizeTake(options, path); !s.ok()) return s.status();
  return path;
}

// Waits for a port file's first line.
std::string WaitForAddress(const std::string& path, double timeout_s) {
  for (int i = 0; i < static_cast<int>(timeout_s * 20); ++i) {
    const std::string text = ReadText(path);
    if (text.find('\n') != std::string::npos) return text.substr(0, text.find('\n'));
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  return "";
}

int Run(int argc, char** argv) {
  std::vector<std::string> args(argv + 1, argv + argc);
  auto flags =
      Flags::Parse(args, {"seconds", "work", "json", "bin", "width", "height", "msaa"}, {});
  if (!flags.ok()) {
    std::cerr << "mirror_e2e: " << flags.status().message() << "\n";
    return 2;
  }
  const absl::StatusOr<double> seconds = flags->GetDouble("seconds", 10.0);
  if (!seconds.ok() || !(*seconds >= 3.0 && *seconds <= 600.0)) {
    std::cerr << "mirror_e2e: --seconds must be in [3, 600]\n";
    return 2;
  }
  const std::string work = flags->GetOr("work", "/tmp/reenact_mirror_e2e");
  const std::string bin =
      flags->GetOr("bin", (fs::path(argv[0]).parent_path().parent_path() / "bin").string());
  fs::create_directories(work);
  const absl::StatusOr<std::string> teacher = TeacherReen(work);
  if (!teacher.ok()) return Fail(std::string(teacher.status().message()));
  const absl::StatusOr<std::string> learner = LearnerTake(work, *seconds);
  if (!learner.ok()) return Fail(std::string(learner.status().message()));

  // reenact-server, then reenactd playing the learner's take in real time.
  for (const char* name : {"server", "spool", "frames"}) fs::remove_all(work + "/" + name);
  for (const char* name :
       {"server.port", "control.port", "server.log", "daemon.log", "mirror.json", "mirror.log"}) {
    fs::remove(work + "/" + name);
  }
  SubprocessOptions server_options;
  server_options.stderr_path = work + "/server.log";
  absl::StatusOr<std::unique_ptr<Subprocess>> server =
      Subprocess::Start({bin + "/reenact-server", "--data", work + "/server", "--listen",
                         "127.0.0.1:0", "--port-file", work + "/server.port", "--jobs", "1"},
                        server_options);
  if (!server.ok()) return Fail(std::string(server.status().message()));
  const std::string server_address = WaitForAddress(work + "/server.port", 10.0);
  if (server_address.empty()) return Fail("reenact-server did not start; see server.log");
  SubprocessOptions daemon_options;
  daemon_options.stderr_path = work + "/daemon.log";
  absl::StatusOr<std::unique_ptr<Subprocess>> daemon = Subprocess::Start(
      {bin + "/reenactd", "--server", server_address, "--source", "playback:" + *learner, "--once",
       "--take-name", "mirror-bench", "--spool", work + "/spool", "--control", "127.0.0.1:0",
       "--control-port-file", work + "/control.port", "--tracker", "auto"},
      daemon_options);
  if (!daemon.ok()) return Fail(std::string(daemon.status().message()));
  const std::string control = WaitForAddress(work + "/control.port", 10.0);
  if (control.empty()) return Fail("reenactd did not start; see daemon.log");
  const double daemon_cpu_before = ProcessCpuSeconds((*daemon)->pid());

  // reenact-mirror on the daemon's live stream, headless, for the take's
  // length less a second of start-up.
  SubprocessOptions mirror_options;
  mirror_options.stdout_path = work + "/mirror.json";
  mirror_options.stderr_path = work + "/mirror.log";
  const double mirror_seconds = *seconds - 1.0;
  absl::StatusOr<std::unique_ptr<Subprocess>> mirror =
      Subprocess::Start({bin + "/reenact-mirror",
                         "--teacher-file",
                         *teacher,
                         "--daemon",
                         control,
                         "--render-to",
                         work + "/frames",
                         "--every",
                         "100000",
                         "--no-mp4",
                         "--seconds",
                         absl::StrFormat("%g", mirror_seconds),
                         "--hold-s",
                         "0.5",
                         "--repetitions",
                         "0",
                         "--width",
                         flags->GetOr("width", "960"),
                         "--height",
                         flags->GetOr("height", "540"),
                         "--msaa",
                         flags->GetOr("msaa", "4"),
                         "--json"},
                        mirror_options);
  if (!mirror.ok()) return Fail(std::string(mirror.status().message()));
  const absl::StatusOr<ExitInfo> mirror_exit = (*mirror)->Wait(*seconds + 120);
  const double daemon_cpu_s = ProcessCpuSeconds((*daemon)->pid()) - daemon_cpu_before;
  const absl::StatusOr<ExitInfo> daemon_exit = (*daemon)->Wait(*seconds + 60);
  (void)(*server)->Signal(SIGTERM);
  (void)(*server)->Wait(30);
  if (!mirror_exit.ok() || !mirror_exit->exited || mirror_exit->exit_code != 0) {
    return Fail("reenact-mirror failed; see " + work + "/mirror.log");
  }
  if (!daemon_exit.ok() || !daemon_exit->exited || daemon_exit->exit_code != 0) {
    return Fail("reenactd failed; see " + work + "/daemon.log");
  }
  const nlohmann::json m = nlohmann::json::parse(ReadText(work + "/mirror.json"), nullptr, false);
  if (!m.is_object()) return Fail("reenact-mirror printed no summary; see mirror.log");

  const double learner_fps = m["frames"].get<double>() / mirror_seconds;
  const int cores = static_cast<int>(std::thread::hardware_concurrency());
  std::cout << absl::StrFormat(
      "mirror_e2e: one sensor (512x424 depth, 1920x1080 colour) at 30 fps played in real time, "
      "tracked by reenactd; reenact-mirror at %sx%s, msaa %s, %d cores, %s\n"
      "  drawn             %d frames in %.1f s of learner time: %.1f frames/s (%d with the "
      "learner, %d dropped)\n"
      "  learner to screen p50 %.1f ms, p95 %.1f ms, max %.1f ms (mean %.1f; %d frames)\n"
      "  mirror per frame  teacher render %.1f ms, compose %.1f ms, output %.1f ms\n"
      "  reenactd CPU      %.0f%% of one core (decode, tracking, encoding, streaming)\n"
      "  target >= 30 frames/s (the sensor's rate): %s\n",
      flags->GetOr("width", "960"), flags->GetOr("height", "540"), flags->GetOr("msaa", "4"), cores,
      m["renderer"].get<std::string>(), m["frames"].get<int>(), mirror_seconds, learner_fps,
      m["frames_with_learner"].get<int>(), m["frames_dropped"].get<int>(),
      m["latency_ms_p50"].get<double>(), m["latency_ms_p95"].get<double>(),
      m["latency_ms_max"].get<double>(), m["latency_ms_mean"].get<double>(),
      m["latency_frames"].get<int>(), m["render_ms_mean"].get<double>(),
      m["compose_ms_mean"].get<double>(), m["output_ms_mean"].get<double>(),
      100.0 * daemon_cpu_s / *seconds, learner_fps >= 29.4 ? "met within 2 %" : "NOT met");
  if (const auto path = flags->Get("json")) {
    const nlohmann::json report = {{"cores", cores},
                                   {"learner_seconds", mirror_seconds},
                                   {"frames_per_second", learner_fps},
                                   {"daemon_cpu_share_of_one_core", daemon_cpu_s / *seconds},
                                   {"mirror", m}};
    std::ofstream(*path) << report.dump(2) << "\n";
  }
  return 0;
}

}  // namespace
}  // namespace reenact

int main(int argc, char** argv) { return reenact::Run(argc, argv); }
