// The `reenact` tool is a table of subcommands; each `RunX()` lives in this
// tested library and the main only dispatches. A command writes its results to
// `out`, diagnostics to `err`, and returns the process exit code:
// 0 success, 1 failure (bad input, I/O error), 2 usage error.
#pragma once

#include <functional>
#include <iosfwd>
#include <string>
#include <vector>

#include "absl/status/status.h"

namespace reenact::cli {

constexpr int kExitOk = 0;
constexpr int kExitFailure = 1;
constexpr int kExitUsage = 2;

using CommandFn =
    std::function<int(const std::vector<std::string>& args, std::ostream& out, std::ostream& err)>;

struct Command {
  std::vector<std::string> path;  // e.g. {"motion", "info"}.
  std::string usage;              // One line: arguments and flags.
  std::string summary;            // One line: what it does.
  CommandFn run;
};

// Every subcommand, in the order `reenact help` lists them.
const std::vector<Command>& AllCommands();

// Finds the command whose path is the longest prefix of `argv`, runs it with
// the rest, and returns the exit code (prints usage on no match).
int Dispatch(const std::vector<std::string>& argv, std::ostream& out, std::ostream& err);

// Prints "reenact: <message>" for `status` and returns the exit code it maps
// to: InvalidArgument -> kExitUsage, anything else -> kExitFailure.
int ReportError(const absl::Status& status, std::ostream& err);

}  // namespace reenact::cli
