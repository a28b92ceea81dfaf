#include "clients/cli/command.h"

#include <ostream>

#include "clients/cli/commands.h"

namespace reenact::cli {

const std::vector<Command>& AllCommands() {
  static const std::vector<Command>* commands = new std::vector<Command>(BuildCommandTable());
  return *commands;
}

static void PrintUsage(std::ostream& out) {
  out << "usage: reenact <command> [args]\n\ncommands:\n";
  for (const Command& c : AllCommands()) {
    std::string name;
    for (const auto& p : c.path) name += (name.empty() ? "" : " ") + p;
    out << "  " << name << " " << c.usage << "\n      " << c.summary << "\n";
  }
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
