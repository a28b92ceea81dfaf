// Test-only: what the end-to-end tests share to run the real binaries
// (REENACT_BINARY_DIR is the build's bin/ folder, defined per test target).
#pragma once

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "common/base/subprocess.h"

namespace reenact::testing {

// REENACT_BINARY_DIR/name.
inline std::string Bin(const std::string& name) {
  return std::string(REENACT_BINARY_DIR) + "/" + name;
}

// The file's text; "" when it cannot be read.
inline std::string ReadText(const std::string& path) {
  std::ifstream in(path);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

struct CommandResult {
  int exit_code = -1;  // -1: did not start, killed, or still running at the timeout.
  std::string out;
  std::string err;
};

// Runs a command to completion with stdout and stderr in DIR/NAME.out and
// DIR/NAME.err (replaced).
inline CommandResult RunCommand(const std::string& dir, const std::string& name,
                                const std::vector<std::string>& argv, double timeout_s = 600) {
  SubprocessOptions options;
  options.stdout_path = dir + "/" + name + ".out";
  options.stderr_path = dir + "/" + name + ".err";
  std::filesystem::remove(options.stdout_path);  // Subprocess appends.
  std::filesystem::remove(options.stderr_path);
  CommandResult result;
  auto child = Subprocess::Start(argv, options);
  if (!child.ok()) {
    result.err = std::string(child.status().message());
    return result;
  }
  auto info = (*child)->Wait(timeout_s);
  if (info.ok() && info->exited) result.exit_code = info->exit_code;
  result.out = ReadText(options.stdout_path);
  result.err = ReadText(options.stderr_path);
  return result;
}

}  // namespace reenact::testing
