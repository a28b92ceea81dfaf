// The reenact-worker binary's protocol edges: usage errors exit 2, a method
// that cannot run exits 1 with one {"error"} line, and the first line names
// what it was asked to do. (Real reconstructions are run end to end by
// tests/reenactment_e2e_test.cc.)
#include <filesystem>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "common/base/files.h"
#include "common/base/subprocess.h"
#include "common/testing/test_data.h"
#include "server/recon/methods.h"

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

}  // namespace
}  // namespace reenact
