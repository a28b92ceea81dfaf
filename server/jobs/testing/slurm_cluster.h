// Test-only: a one-node Slurm cluster of Debian's slurm-wlm and munge
// (deploy/slurm/test-cluster.sh) in a short temporary folder, stopped when
// it goes, and the small process helpers its tests share.
#pragma once

#include <signal.h>
#include <stdlib.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <functional>
#include <iostream>
#include <map>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_split.h"
#include "absl/strings/strip.h"
#include "common/base/files.h"
#include "common/base/subprocess.h"

namespace reenact::server::testing {

struct ToolOutput {
  int exit_code = -1;  // -1: did not start, did not end in time or killed.
  std::string out;
  std::string err;
};

// Runs `argv` with `env` added, for at most `timeout_s`.
inline ToolOutput RunTool(const std::vector<std::string>& argv,
                          const std::map<std::string, std::string>& env = {},
                          double timeout_s = 30) {
  static int runs = 0;
  const std::string base =
      absl::StrCat(::testing::TempDir(), "/slurm_tool_", ::getpid(), "_", ++runs);
  SubprocessOptions options;
  options.env = env;
  options.stdout_path = base + ".out";
  options.stderr_path = base + ".err";
  ToolOutput output;
  absl::StatusOr<std::unique_ptr<Subprocess>> child = Subprocess::Start(argv, options);
  if (child.ok()) {
    absl::StatusOr<ExitInfo> exit = (*child)->Wait(timeout_s);
    if (exit.ok() && exit->exited) output.exit_code = exit->exit_code;
  }
  output.out = ReadFileToString(base + ".out").value_or("");
  output.err = ReadFileToString(base + ".err").value_or("");
  std::filesystem::remove(base + ".out");
  std::filesystem::remove(base + ".err");
  return output;
}

// True when `program` is an executable in PATH.
inline bool OnPath(const std::string& program) {
  const char* path = std::getenv("PATH");
  for (absl::string_view dir : absl::StrSplit(path == nullptr ? "" : path, ':')) {
    const std::string candidate = absl::StrCat(dir, "/", program);
    if (!dir.empty() && ::access(candidate.c_str(), X_OK) == 0) return true;
  }
  return false;
}

// Calls `step` every 100 ms until `done` holds, for at most `timeout_s`;
// true when it held.
inline bool PollUntil(
    double timeout_s, const std::function<bool()>& done,
    const std::function<void()>& step = [] {}) {
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
  while (true) {
    step();
    if (done()) return true;
    if (std::chrono::steady_clock::now() >= deadline) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
}

class SlurmTestCluster {
 public:
  // Starts a cluster with `script` (deploy/slurm/test-cluster.sh); null,
  // saying why in `why`, where it cannot run (not root, no sbatch, the
  // daemons did not come up).
  static std::unique_ptr<SlurmTestCluster> Start(const std::string& script, std::string* why) {
    if (::geteuid() != 0) {
      *why = "the test Slurm cluster needs root";
      return nullptr;
    }
    if (!OnPath("sbatch")) {
      *why = "sbatch is missing (apt-get install slurm-wlm munge)";
      return nullptr;
    }
    // A short path: the cluster's Unix sockets live below it.
    std::string dir = "/tmp/rsl.XXXXXX";
    if (::mkdtemp(dir.data()) == nullptr) {
      *why = "mkdtemp failed";
      return nullptr;
    }
    std::unique_ptr<SlurmTestCluster> cluster(new SlurmTestCluster(script, dir));
    const ToolOutput start = RunTool({script, "start", dir}, {}, 60);
    for (absl::string_view line : absl::StrSplit(start.out, '\n')) {
      if (absl::ConsumePrefix(&line, "SLURM_CONF="))
        cluster->env_["SLURM_CONF"] = std::string(line);
    }
    if (start.exit_code != 0 || cluster->env_.empty()) {
      *why = absl::StrCat("the test Slurm cluster did not start (exit ", start.exit_code, "):\n",
                          start.err);
      return nullptr;  // The destructor stops what came up.
    }
    return cluster;
  }

  ~SlurmTestCluster() {
    const ToolOutput stop = RunTool({script_, "stop", dir_}, {}, 60);
    EXPECT_EQ(stop.exit_code, 0) << stop.err;
    KillLeftoverDaemons();
    std::error_code error;
    std::filesystem::remove_all(dir_, error);
  }
  SlurmTestCluster(const SlurmTestCluster&) = delete;
  SlurmTestCluster& operator=(const SlurmTestCluster&) = delete;

  const std::string& dir() const { return dir_; }
  // What clients of the cluster need in their environment (SLURM_CONF).
  const std::map<std::string, std::string>& env() const { return env_; }

  // squeue's state of each job in the cluster.
  std::map<std::string, std::string> Squeue() const {
    const ToolOutput output = RunTool({"squeue", "-h", "-o", "%i %T"}, env_, 10);
    std::map<std::string, std::string> states;
    for (absl::string_view line : absl::StrSplit(output.out, '\n', absl::SkipWhitespace())) {
      std::vector<std::string> words = absl::StrSplit(line, ' ', absl::SkipEmpty());
      if (words.size() == 2) states[words[0]] = words[1];
    }
    return states;
  }

 private:
  SlurmTestCluster(std::string script, std::string dir)
      : script_(std::move(script)), dir_(std::move(dir)) {}

  // A start that fails early can leave a daemon that had not yet written
  // its pid file, which stop cannot find; its command line names this
  // cluster's files, which no other process's does.
  void KillLeftoverDaemons() const {
    const std::vector<std::string> markers = {dir_ + "/slurm.conf",
                                              "--socket=" + dir_ + "/munge.socket"};
    std::error_code error;  // Processes come and go while this reads.
    for (auto it = std::filesystem::directory_iterator("/proc", error);
         !error && it != std::filesystem::directory_iterator(); it.increment(error)) {
      const std::filesystem::directory_entry& entry = *it;
      const std::string name = entry.path().filename().string();
      int pid;
      if (!absl::SimpleAtoi(name, &pid) || pid == ::getpid()) continue;
      const std::string cmdline = ReadFileToString(entry.path().string() + "/cmdline").value_or("");
      const std::vector<std::string> argv = absl::StrSplit(cmdline, '\0', absl::SkipEmpty());
      if (argv.empty()) continue;
      const std::string program = std::filesystem::path(argv[0]).filename().string();
      if (program != "slurmd" && program != "slurmctld" && program != "munged") continue;
      for (const std::string& marker : markers) {
        if (std::find(argv.begin(), argv.end(), marker) == argv.end()) continue;
        std::cerr << "killing leftover " << program << " (pid " << pid << ")\n";
        ::kill(pid, SIGKILL);
        break;
      }
    }
  }
  std::string script_;
  std::string dir_;
  std::map<std::string, std::string> env_;
};

}  // namespace reenact::server::testing
