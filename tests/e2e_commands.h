// Test-only: what the end-to-end tests share to run the real binaries
// (REENACT_BINARY_DIR is the build's bin/ folder, defined per test target).
#pragma once

#include <chrono>
#include <filesystem>
#include <fstream>
#include <memory>
#include <sstream>
#include <string>
#include <thread>
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

// Starts `reenact-server --data DATA --port-file DATA.port` plus `flags`
// (which name --listen), logging to DATA.log, and waits up to 30 s for the
// port file. Returns the address it listens on, or "" with `*error` set; the
// started process (if any) is kept in `*server` either way.
inline std::string StartServerForTest(const std::string& data,
                                      const std::vector<std::string>& flags,
                                      std::unique_ptr<Subprocess>* server, std::string* error) {
  SubprocessOptions options;
  options.stdout_path = options.stderr_path = data + ".log";
  const std::string port_file = data + ".port";
  std::filesystem::remove(port_file);
  std::vector<std::string> argv = {Bin("reenact-server"), "--data", data, "--port-file", port_file};
  argv.insert(argv.end(), flags.begin(), flags.end());
  auto started = Subprocess::Start(argv, options);
  if (!started.ok()) {
    *error = std::string(started.status().message());
    return "";
  }
  *server = std::move(*started);
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(30);
  while (std::chrono::steady_clock::now() < deadline) {
    const std::string text = ReadText(port_file);
    if (const auto nl = text.find('\n'); nl != std::string::npos) return text.substr(0, nl);
    if (!(*server)->Running()) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  *error = "the server did not start: " + ReadText(data + ".log");
  return "";
}

}  // namespace reenact::testing
