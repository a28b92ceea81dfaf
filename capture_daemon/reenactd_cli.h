// The command line of reenactd, as a tested library: flag and config-file
// parsing into DaemonOptions, and RunReenactd(), which the thin main calls.
//
//   reenactd --server HOST:PORT --source playback:FILE [--source ...]
//            [--fast] [--loop] [--once] [--max-seconds S]
//            [--control HOST:PORT] [--control-port-file FILE]
//            [--spool DIR] [--spool-max-mb N] [--take-name NAME]
//            [--daemon-id ID] [--sync-tolerance-ms X]
//            [--segmentation auto|on|off] [--registration auto|on|off]
//            [--drain-timeout-s S] [--config FILE] [--stats-json FILE]
//            [--verbose] [--metrics HOST:PORT]
//            [--log-format text|json] [--log-level debug|info|warn|error]
//
// --config FILE is a JSON object with the same keys as the flags (without
// the dashes; "source" may be a string or a list; booleans are true/false);
// flags given on the command line win, and command-line sources replace the
// file's. Exit codes: 0 the take(s) ended durable on the server (or the
// daemon was stopped with nothing pending), 1 failure (no sensor, server
// refused the take, drain timed out with the spool left on disk), 2 usage.
#pragma once

#include <iosfwd>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "capture_daemon/daemon.h"

namespace reenact::capture {

constexpr int kExitOk = 0;
constexpr int kExitFailure = 1;
constexpr int kExitUsage = 2;

// One line per flag, for --help.
std::string ReenactdUsage();

// Parses `args` (without the program name), reading --config when given.
// InvalidArgument naming the flag or key for bad input; `help` is set for
// --help (then the options are defaults).
absl::StatusOr<DaemonOptions> ParseReenactdFlags(const std::vector<std::string>& args,
                                                 bool* help = nullptr);

// Parses, runs the daemon until it ends, and returns the exit code. Usage
// errors go to `err` as text; once the flags are read, events go to `err`
// in the --log-format (common/log/log.h), and the process logger is
// configured the same way for the libraries (it writes to stderr).
int RunReenactd(const std::vector<std::string>& args, std::ostream& out, std::ostream& err);

}  // namespace reenact::capture
