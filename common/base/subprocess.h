// Child processes: start a program with arguments and extra environment,
// send it signals, wait for it with a deadline. Used by the server to run
// worker processes and by integration tests and benchmarks to run the real
// binaries. POSIX only (fork/exec).
#pragma once

#include <sys/types.h>

#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"

namespace reenact {

struct SubprocessOptions {
  // Added to (or replacing in) the parent's environment.
  std::map<std::string, std::string> env;
  // Files that receive the child's stdout and stderr (appended); empty:
  // inherit the parent's.
  std::string stdout_path;
  std::string stderr_path;
  // Working directory of the child; empty: the parent's.
  std::string working_dir;
};

// How a child ended.
struct ExitInfo {
  bool exited = false;  // Returned from main or called exit().
  int exit_code = 0;    // When exited.
  int signal = 0;       // When killed by a signal.
  std::string ToString() const;
};

class Subprocess {
 public:
  // Starts `argv[0]` (looked up in PATH when it has no '/') with `argv`.
  // NotFound when the program does not exist or is not executable.
  static absl::StatusOr<std::unique_ptr<Subprocess>> Start(const std::vector<std::string>& argv,
                                                           const SubprocessOptions& options = {});
  // Kills (SIGKILL) and reaps a child that is still running.
  ~Subprocess();
  Subprocess(const Subprocess&) = delete;
  Subprocess& operator=(const Subprocess&) = delete;

  pid_t pid() const { return pid_; }
  // Sends `signal` (e.g. SIGTERM, SIGKILL). OK when the child already ended.
  absl::Status Signal(int signal);
  // The exit information once the child ended, without blocking.
  std::optional<ExitInfo> Poll();
  // Waits up to `timeout_s` (negative: forever). DeadlineExceeded when the
  // child is still running then.
  absl::StatusOr<ExitInfo> Wait(double timeout_s = -1);
  // True while the child runs.
  bool Running() { return !Poll().has_value(); }

 private:
  explicit Subprocess(pid_t pid) : pid_(pid) {}
  pid_t pid_;
  std::optional<ExitInfo> exit_;
};

}  // namespace reenact
