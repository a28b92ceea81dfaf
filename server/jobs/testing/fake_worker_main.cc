// Test-only: a stand-in for reenact-worker that speaks its protocol
// (server/jobs/job_scheduler.h) without reconstructing anything, so that the
// job tests run in a second instead of minutes. Its behaviour comes from the
// job's options:
//   fake_steps     progress lines before the end (default 5)
//   fake_step_ms   pause after each, milliseconds (default 20)
//   fake_end       succeed (default): writes a small valid reenactment to
//                  --out (common/io/testing/small_reenactment.h) and exits 0;
//                  fail: {"error":"fake failure"}, exit 1;
//                  garbage: writes a file that is no reenactment, exit 0;
//                  segv: raises SIGSEGV mid-way
//   fake_hang_first  "1": the first attempt (no marker file for the job in
//                  the temporary folder yet: each attempt runs in a scratch
//                  folder of its own) never ends on its own
//   fake_ignore_term "1": SIGTERM is ignored (only SIGKILL stops it)
//   fake_trace     a file to append "start|end JOB_ID UNIX_NS" lines to
// SIGTERM stops it at the next step with exit code 3.
#include <signal.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <string>
#include <thread>
#include <vector>

#include <nlohmann/json.hpp>

#include "common/base/flags.h"
#include "common/io/reenactment_file.h"
#include "common/io/testing/small_reenactment.h"

namespace {

volatile sig_atomic_t g_stop = 0;
void OnTerm(int) { g_stop = 1; }

void Line(const nlohmann::json& j) {
  std::printf("%s\n", j.dump().c_str());
  std::fflush(stdout);
}

}  // namespace

int main(int argc, char** argv) {
  sigset_t signals;
  sigemptyset(&signals);
  sigaddset(&signals, SIGTERM);
  sigprocmask(SIG_UNBLOCK, &signals, nullptr);
  auto flags = reenact::Flags::Parse(std::vector<std::string>(argv + 1, argv + argc),
                                     {"take", "method", "options-json", "out", "reenactment-id",
                                      "take-id", "job-id", "memory-limit-mb"},
                                     {});
  if (!flags.ok() || !flags->Has("take") || !flags->Has("out") || !flags->Has("method")) {
    std::fprintf(stderr, "fake-reenact-worker: bad command line\n");
    return 2;
  }
  std::map<std::string, std::string> options;
  const auto j = nlohmann::json::parse(flags->GetOr("options-json", "{}"), nullptr, false);
  if (!j.is_object()) return 2;
  for (const auto& [key, value] : j.items()) options[key] = value.get<std::string>();
  auto option = [&](const std::string& key, const std::string& fallback) {
    auto it = options.find(key);
    return it == options.end() ? fallback : it->second;
  };
  const bool ignore_term = option("fake_ignore_term", "0") == "1";
  signal(SIGTERM, ignore_term ? SIG_IGN : OnTerm);
  const int steps = std::stoi(option("fake_steps", "5"));
  const int step_ms = std::stoi(option("fake_step_ms", "20"));
  const std::string end = option("fake_end", "succeed");
  bool hang = false;
  const std::filesystem::path attempted = std::filesystem::temp_directory_path() /
                                          ("fake_worker_attempted_" + flags->GetOr("job-id", ""));
  if (option("fake_hang_first", "0") == "1" && !std::filesystem::exists(attempted)) {
    std::ofstream(attempted) << "1\n";
    hang = true;
  }
  Line({{"log", "fake worker: method " + *flags->Get("method") + " take " + *flags->Get("take") +
                    " job " + flags->GetOr("job-id", "") + " memory-limit-mb " +
                    flags->GetOr("memory-limit-mb", "none")}});
  const std::string trace = option("fake_trace", "");
  auto trace_line = [&](const char* what) {
    if (trace.empty()) return;
    const auto now = std::chrono::system_clock::now().time_since_epoch();
    std::ofstream(trace, std::ios::app)
        << what << " " << flags->GetOr("job-id", "") << " "
        << std::chrono::duration_cast<std::chrono::nanoseconds>(now).count() << "\n";
  };
  trace_line("start");
  if (!std::filesystem::exists(*flags->Get("take"))) {
    Line({{"error", "no take file " + *flags->Get("take")}});
    return 1;
  }
  for (int i = 1; i <= steps || hang; ++i) {
    if (g_stop) {
      Line({{"error", "stopped by SIGTERM"}});
      return 3;
    }
    const int shown = hang ? std::min(i, steps - 1) : i;
    Line({{"stage", i <= steps / 2 ? "load" : "register"},
          {"fraction", static_cast<double>(shown) / steps},
          {"frames_done", shown},
          {"frames_total", steps}});
    if (i % 2 == 0) Line({{"log", "step " + std::to_string(i)}});
    if (end == "segv" && i == steps / 2 + 1) {
      std::fprintf(stderr, "fake worker: about to crash at step %d\n", i);
      std::fflush(stderr);
      raise(SIGSEGV);
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(step_ms));
  }
  const std::string out = *flags->Get("out");
  if (end == "fail") {
    Line({{"error", "fake failure at the end"}});
    return 1;
  }
  if (end == "garbage") {
    std::ofstream(out) << "not a reenactment\n";
    Line({{"result", {{"frames", 0}}}});
    return 0;
  }
  reenact::testing::TestReenactmentOptions test;
  test.id = flags->GetOr("reenactment-id", "r-fake");
  reenact::ReenactmentData data = reenact::testing::MakeTestReenactment(test);
  data.info.set_take_id(flags->GetOr("take-id", ""));
  data.info.set_job_id(flags->GetOr("job-id", ""));
  data.info.set_method(*flags->Get("method"));
  data.info.set_generator("fake-reenact-worker");
  if (const auto written = reenact::WriteReenactmentFile(data, out); !written.ok()) {
    Line({{"error", std::string(written.message())}});
    return 1;
  }
  Line({{"result", {{"frames", test.frames}, {"figures", {{"fake", 1.0}}}}}});
  trace_line("end");
  return 0;
}
