// The reenact-worker binary's protocol edges: usage errors exit 2, a method
// that cannot run exits 1 with one {"error"} line, and the first line names
// what it was asked to do; a job over its memory limit fails on its own;
// the memory a job is estimated to take (recon::JobMemoryBytes) is never
// under what a worker measurably takes. (Real reconstructions are run end
// to end by tests/reenactment_e2e_test.cc.)
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "common/base/files.h"
#include "common/base/memory_limit.h"
#include "common/base/subprocess.h"
#include "common/testing/test_data.h"
#include "server/recon/methods.h"
#include "server/recon/testing/short_take.h"

namespace reenact {
namespace {

struct WorkerRun {
  ExitInfo exit;
  std::vector<nlohmann::json> lines;
  std::string err;
};

WorkerRun RunWorker(const std::vector<std::string>& args) {
  const std::string dir = testing::MakeTempDir("worker_main");
  SubprocessOptions options;
  options.stdout_path = dir + "/out.jsonl";
  options.stderr_path = dir + "/err.txt";
  std::vector<std::string> argv = {REENACT_WORKER_BINARY};
  argv.insert(argv.end(), args.begin(), args.end());
  WorkerRun run;
  auto process = Subprocess::Start(argv, options);
  EXPECT_TRUE(process.ok()) << process.status();
  if (!process.ok()) return run;
  auto exit = (*process)->Wait(60);
  EXPECT_TRUE(exit.ok()) << exit.status();
  if (exit.ok()) run.exit = *exit;
  std::istringstream out(ReadFileToString(options.stdout_path).value_or(""));
  std::string line;
  while (std::getline(out, line)) {
    run.lines.push_back(nlohmann::json::parse(line, nullptr, false));
    EXPECT_TRUE(run.lines.back().is_object()) << "not a JSON object: " << line;
  }
  run.err = ReadFileToString(options.stderr_path).value_or("");
  return run;
}

TEST(Worker, UsageErrorsExitTwo) {
  for (const std::vector<std::string>& args :
       {std::vector<std::string>{"--method", "rigid-carved", "--out", "/tmp/x.reen"},
        std::vector<std::string>{"--take", "t.mcap", "--method", "rigid-carved", "--out", "x",
                                 "--options-json", "[1, 2]"},
        std::vector<std::string>{"--take", "t.mcap", "--bogus", "1"}}) {
    const WorkerRun run = RunWorker(args);
    EXPECT_TRUE(run.exit.exited);
    EXPECT_EQ(run.exit.exit_code, 2) << run.err;
    ASSERT_FALSE(run.lines.empty());
    EXPECT_TRUE(run.lines.back().contains("error")) << run.lines.back().dump();
    EXPECT_NE(run.err.find("usage: reenact-worker"), std::string::npos) << run.err;
  }
}

TEST(Worker, NetworkModeUsageErrorsExitTwo) {
  for (const std::vector<std::string>& args :
       {std::vector<std::string>{"--server", "127.0.0.1:1", "--take", "t.mcap"},
        std::vector<std::string>{"--server", "127.0.0.1:1", "--once", "--loop"},
        std::vector<std::string>{"--server", "127.0.0.1:1", "--once", "--wait", "-1"},
        std::vector<std::string>{"--server", "127.0.0.1:1", "--token-file", "/no/such/token"}}) {
    const WorkerRun run = RunWorker(args);
    EXPECT_TRUE(run.exit.exited);
    EXPECT_EQ(run.exit.exit_code, 2) << run.err;
  }
}

TEST(Worker, OnceGivesUpOnAServerThatNeverAnswers) {
  // Port 1 on loopback: refused at once, retried with a growing pause until
  // --wait passes; no job, so exit 0.
  const WorkerRun run = RunWorker({"--server", "127.0.0.1:1", "--once", "--wait", "1.5"});
  EXPECT_TRUE(run.exit.exited);
  EXPECT_EQ(run.exit.exit_code, 0) << run.err;
  EXPECT_NE(run.err.find("server_unreachable"), std::string::npos) << run.err;
  EXPECT_NE(run.err.find("jobs=0"), std::string::npos) << run.err;
}

TEST(Worker, AMethodThatCannotRunExitsOneWithItsError) {
  const std::string dir = testing::MakeTempDir("worker_main_missing");
  const std::string out = dir + "/r.reen";
  const WorkerRun run =
      RunWorker({"--take", dir + "/no-such-take.mcap", "--method", "rigid-cylinders",
                 "--options-json", R"({"no_such_option":"1"})", "--out", out, "--reenactment-id",
                 "r-1", "--take-id", "t", "--job-id", "j"});
  EXPECT_TRUE(run.exit.exited);
  EXPECT_EQ(run.exit.exit_code, 1) << run.err;
  ASSERT_GE(run.lines.size(), 2u);
  EXPECT_NE(run.lines.front().value("log", "").find("rigid-cylinders"), std::string::npos);
  ASSERT_TRUE(run.lines.back().contains("error")) << run.lines.back().dump();
  EXPECT_FALSE(run.lines.back()["error"].get<std::string>().empty());
  EXPECT_FALSE(std::filesystem::exists(out));
}

// Runs the worker on the shared take in a child process of its own and
// returns the worker's peak resident memory, bytes (the child's
// RUSAGE_CHILDREN), and its exit code in `exit_code`.
int64_t PeakOfAWorker(const std::vector<std::string>& args, int* exit_code) {
  const std::string dir = testing::MakeTempDir("worker_peak");
  const std::string peak_path = dir + "/peak";
  std::vector<std::string> argv = {REENACT_WORKER_BINARY};
  argv.insert(argv.end(), args.begin(), args.end());
  std::vector<char*> raw;
  for (std::string& arg : argv) raw.push_back(arg.data());
  raw.push_back(nullptr);
  // What this process printed goes out once, not again from the children.
  std::fflush(stdout);
  std::fflush(stderr);
  const pid_t measurer = fork();
  if (measurer == 0) {
    const pid_t worker = fork();
    if (worker == 0) {
      if (std::freopen((dir + "/out.jsonl").c_str(), "w", stdout) == nullptr) _exit(120);
      if (std::freopen((dir + "/err.txt").c_str(), "w", stderr) == nullptr) _exit(121);
      execv(raw[0], raw.data());
      _exit(127);
    }
    int status = 0;
    if (waitpid(worker, &status, 0) != worker) _exit(122);
    struct rusage usage {};
    getrusage(RUSAGE_CHILDREN, &usage);
    FILE* out = std::fopen(peak_path.c_str(), "w");
    if (out == nullptr) _exit(123);
    std::fprintf(out, "%ld\n", usage.ru_maxrss);
    std::fclose(out);
    _exit(WIFEXITED(status) ? WEXITSTATUS(status) : 124);
  }
  int status = 0;
  waitpid(measurer, &status, 0);
  *exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  const int64_t kib = std::atoll(ReadFileToString(peak_path).value_or("0").c_str());
  if (*exit_code != 0) {
    std::cerr << ReadFileToString(dir + "/out.jsonl").value_or("") << "\n"
              << ReadFileToString(dir + "/err.txt").value_or("");
  }
  return kib * 1024;
}

// The attack of a coach with too large options: 8192 px textures on
// cylinders of 256 x 256 quads. Under a 512 MiB limit the worker fails
// with the limit's words, writes nothing, and stays near its limit (it took
// 16.5 GB without one).
TEST(Worker, AJobOverItsMemoryLimitFailsWithoutTakingTheMachinesMemory) {
  if (!kDataMemoryLimitEnforced) GTEST_SKIP() << "no memory limit under a sanitizer";
  RECON_REQUIRE_SHARED_TAKE();
  const std::string dir = testing::MakeTempDir("worker_memory_limit");
  const std::string out = dir + "/r.reen";
  const std::vector<std::string> args = {
      "--take",
      recon::testing::GetSharedTake().path,
      "--method",
      "rigid-cylinders",
      "--options-json",
      R"({"texture_size_px":"8192","segments":"256","rings":"256","color_scale":"8"})",
      "--out",
      out,
      "--memory-limit-mb",
      "512"};
  int exit_code = 0;
  const int64_t peak = PeakOfAWorker(args, &exit_code);
  std::printf("[ figures ] peak of a worker over its 512 MiB limit: %.1f MiB\n", peak / 1048576.0);
  EXPECT_EQ(exit_code, 1);
  EXPECT_LT(peak, int64_t{600} << 20);
  EXPECT_FALSE(std::filesystem::exists(out));
  const WorkerRun run = RunWorker(args);
  ASSERT_FALSE(run.lines.empty());
  const std::string error = run.lines.back().value("error", "");
  EXPECT_NE(error.find("more memory than its limit of 512 MiB"), std::string::npos) << error;
  EXPECT_EQ(run.exit.exit_code, 1);
  // A limit under what the program itself needs is a usage error.
  EXPECT_EQ(
      RunWorker({"--take", "t.mcap", "--method", "body", "--out", out, "--memory-limit-mb", "10"})
          .exit.exit_code,
      2);
}

// recon::JobMemoryBytes on the shared take's catalog figures against the
// measured peak of a worker running the job: never under it. The attack's
// estimate is far over any budget of this machine.
TEST(JobMemoryBytes, NeverUnderTheMeasuredPeakOfAWorker) {
  RECON_REQUIRE_SHARED_TAKE();
  const recon::testing::SharedTake& take = recon::testing::GetSharedTake();
  recon::TakeSize size;
  size.frame_sets = take.summary.frames;
  size.sensors = 2;
  size.file_bytes = static_cast<int64_t>(std::filesystem::file_size(take.path));
  size.duration_s = 1.5;
  const absl::StatusOr<int64_t> attack = recon::JobMemoryBytes(
      "rigid-cylinders",
      {{"texture_size_px", "8192"}, {"segments", "256"}, {"rings", "256"}, {"color_scale", "8"}},
      size);
  ASSERT_TRUE(attack.ok()) << attack.status();
  std::printf("[ figures ] the attack's estimate: %.0f MiB\n", *attack / 1048576.0);
  EXPECT_GT(*attack, int64_t{16} << 30);
  EXPECT_EQ(recon::JobMemoryBytes("no-such-method", {}, size).status().code(),
            absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(recon::JobMemoryBytes("body", {{"atlas_px", "x"}}, size).status().code(),
            absl::StatusCode::kInvalidArgument);

  const std::string dir = testing::MakeTempDir("job_memory_bytes");
  const std::vector<std::pair<std::string, std::map<std::string, std::string>>> jobs = {
      {"rigid-cylinders", {}},
      {"rigid-cylinders", {{"texture_size_px", "2048"}}},
      {"rigid-carved", {}},
      {"rigid-carved", {{"voxel_mm", "5"}}},
      {"body", {}},
      {"body", {{"atlas_px", "4096"}}},
  };
  for (const auto& [method, options] : jobs) {
    const absl::StatusOr<int64_t> estimate = recon::JobMemoryBytes(method, options, size);
    ASSERT_TRUE(estimate.ok()) << estimate.status();
    nlohmann::json json = nlohmann::json::object();
    for (const auto& [key, value] : options) json[key] = value;
    int exit_code = 0;
    const int64_t peak = PeakOfAWorker({"--take", take.path, "--method", method, "--options-json",
                                        json.dump(), "--out", dir + "/r.reen"},
                                       &exit_code);
    std::printf("[ figures ] %s %s: peak %.0f MiB, estimate %.0f MiB\n", method.c_str(),
                json.dump().c_str(), peak / 1048576.0, *estimate / 1048576.0);
    EXPECT_EQ(exit_code, 0) << method << " " << json.dump();
    EXPECT_GT(peak, 0);
    EXPECT_GE(*estimate, peak) << method << " " << json.dump();
  }
}

}  // namespace
}  // namespace reenact
