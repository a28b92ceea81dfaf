#include "clients/cli/command.h"

#include <ostream>

#include "clients/cli/commands.h"

namespace reenact::cli {

const std::vector<Command>& AllCommands() {
  static const std::vector<Command>* commands = new std::vector<Command>(BuildCommandTable());
  return *commands;
}

// Every command, or those whose first word is `group` when it is not empty.
static void PrintUsage(std::ostream& out, const std::string& group = "") {
  out << "usage: reenact " << (group.empty() ? "" : group + " ")
      << "<command> [args]\n\ncommands:\n";
  for (const Command& c : AllCommands()) {
    if (!group.empty() && c.path.front() != group) continue;
    std::string name;
    for (const auto& p : c.path) name += (name.empty() ? "" : " ") + p;
    out << "  " << name << " " << c.usage << "\n      " << c.summary << "\n";
  }
}

// Whether `word` is the first word of a command of two or more words
// ("takes", "auth", ...).
static bool IsGroup(const std::string& word) {
  for (const Command& c : AllCommands()) {
    if (c.path.size() > 1 && c.path.front() == word) return true;
  }
  return false;
}

int Dispatch(const std::vector<std::string>& argv, std::ostream& out, std::ostream& err) {
  if (argv.empty() || argv[0] == "help" || argv[0] == "--help" || argv[0] == "-h") {
    PrintUsage(argv.empty() ? err : out);
    return argv.empty() ? kExitUsage : kExitOk;
  }
  const Command* best = nullptr;
  for (const Command& c : AllCommands()) {
    if (c.path.size() > argv.size()) continue;
    bool match = true;
    for (size_t i = 0; i < c.path.size() && match; ++i) match = (c.path[i] == argv[i]);
    if (match && (!best || c.path.size() > best->path.size())) best = &c;
  }
  if (!best && IsGroup(argv[0])) {
    // A group without its command: `reenact auth --help` lists the group's
    // commands (exit 0), `reenact auth` does so as a usage error.
    const bool help = argv.size() > 1 && (argv[1] == "--help" || argv[1] == "-h");
    if (argv.size() == 1 || help) {
      PrintUsage(help ? out : err, argv[0]);
      return help ? kExitOk : kExitUsage;
    }
    err << "reenact: unknown command '" << argv[0] << " " << argv[1] << "'\n";
    PrintUsage(err, argv[0]);
    return kExitUsage;
  }
  if (!best) {
    err << "reenact: unknown command '" << argv[0] << "'\n";
    PrintUsage(err);
    return kExitUsage;
  }
  std::vector<std::string> rest(argv.begin() + static_cast<long>(best->path.size()), argv.end());
  for (const auto& a : rest) {
    if (a == "--help" || a == "-h") {
      out << "usage: reenact";
      for (const auto& p : best->path) out << " " << p;
      out << " " << best->usage << "\n" << best->summary << "\n";
      return kExitOk;
    }
  }
  return best->run(rest, out, err);
}

int ReportError(const absl::Status& status, std::ostream& err) {
  err << "reenact: " << status.message() << "\n";
  return status.code() == absl::StatusCode::kInvalidArgument ? kExitUsage : kExitFailure;
}

}  // namespace reenact::cli
