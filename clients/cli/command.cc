#include "clients/cli/command.h"

#include <algorithm>
#include <optional>
#include <ostream>
#include <string>
#include <vector>

#include "clients/cli/commands.h"
#include "clients/cli/remote_flags.h"
#include "common/base/nearest_name.h"

namespace reenact::cli {

const std::vector<Command>& AllCommands() {
  static const std::vector<Command>* commands = new std::vector<Command>(BuildCommandTable());
  return *commands;
}

namespace {

// The headings of `reenact help`, by a command's first word, in the order
// they are printed; a command whose first word is not here goes under the
// last.
struct Section {
  const char* heading;
  std::vector<std::string> first_words;
};

const std::vector<Section>& Sections() {
  static const std::vector<Section>* sections = new std::vector<Section>{
      {"Record with a reenactd beside the sensors", {"capture"}},
      {"Takes on this machine", {"import", "synth", "board", "take", "motion"}},
      {"A reenact-server: takes, jobs and reenactments", {"takes", "jobs", "reenactments"}},
      {"Watch, export and grade a reenactment", {"export", "render", "eval", "grade"}},
      {"Skeleton tracking", {"track", "tracker"}},
      {"Access to a server", {"auth"}},
  };
  return *sections;
}

int SectionOf(const Command& c) {
  const std::vector<Section>& sections = Sections();
  for (size_t s = 0; s < sections.size(); ++s) {
    for (const std::string& word : sections[s].first_words) {
      if (c.path.front() == word) return static_cast<int>(s);
    }
  }
  return static_cast<int>(sections.size()) - 1;
}

std::string NameOf(const Command& c) {
  std::string name;
  for (const auto& p : c.path) name += (name.empty() ? "" : " ") + p;
  return name;
}

// `text` folded at spaces into lines of at most `width` bytes, every line
// after the first indented by `indent` spaces.
std::string Fold(const std::string& text, size_t width, size_t indent) {
  std::string out, line;
  size_t start = 0;
  while (start < text.size()) {
    size_t end = text.find(' ', start);
    if (end == std::string::npos) end = text.size();
    const std::string word = text.substr(start, end - start);
    if (!line.empty() && line.size() + 1 + word.size() > width) {
      out += line + "\n" + std::string(indent, ' ');
      line.clear();
    }
    line += (line.empty() ? "" : " ") + word;
    start = end + 1;
  }
  return out + line;
}

// The first clause of a command's summary, for the overview: up to its
// first parenthesis or semicolon (the rest is in `reenact COMMAND --help`).
std::string Brief(const std::string& summary) {
  size_t end = summary.size();
  for (const char* stop : {" (", "; "}) {
    const size_t at = summary.find(stop);
    if (at != std::string::npos && at >= 15) end = std::min(end, at);
  }
  return summary.substr(0, end);
}

// Every command by section, a line each (name and what it does), or those
// whose first word is `group` when it is not empty.
void PrintUsage(std::ostream& out, const std::string& group = "") {
  out << "usage: reenact " << (group.empty() ? "" : group + " ") << "<command> [args]\n";
  constexpr size_t kNameWidth = 22;
  for (size_t s = 0; s < Sections().size(); ++s) {
    bool heading = false;
    for (const Command& c : AllCommands()) {
      if (SectionOf(c) != static_cast<int>(s)) continue;
      if (!group.empty() && c.path.front() != group) continue;
      if (!heading) {
        out << "\n" << Sections()[s].heading << ":\n";
        heading = true;
      }
      std::string name = NameOf(c);
      if (name.size() < kNameWidth) name.resize(kNameWidth, ' ');
      out << "  " << name << " " << Fold(Brief(c.summary), 72, kNameWidth + 3) << "\n";
    }
  }
  out << "\nreenact " << (group.empty() ? "COMMAND" : group + " COMMAND")
      << " --help: what it does, its arguments and flags. reenact --version: the version.\n"
         "Commands that talk to a server take --server HOST:PORT (or REENACT_SERVER; default "
      << kDefaultServer << "),\n--tls-ca and --token-file (or REENACT_TLS_CA and REENACT_TOKEN).\n";
}

// Whether `word` is the first word of a command of two or more words
// ("takes", "auth", ...).
bool IsGroup(const std::string& word) {
  for (const Command& c : AllCommands()) {
    if (c.path.size() > 1 && c.path.front() == word) return true;
  }
  return false;
}

// " (did you mean 'reenact X'?)" for the command nearest `typed` among
// those of `group` (every command when empty), or "".
std::string DidYouMean(const std::string& typed, const std::string& group) {
  std::vector<std::string> names;
  for (const Command& c : AllCommands()) {
    if (!group.empty() && c.path.front() != group) continue;
    names.push_back(NameOf(c));
    if (group.empty() && c.path.size() > 1) names.push_back(c.path.front());
  }
  const std::optional<std::string> near = NearestName(typed, names);
  return near ? " (did you mean 'reenact " + *near + "'?)" : "";
}

}  // namespace

int Dispatch(const std::vector<std::string>& argv, std::ostream& out, std::ostream& err) {
  if (argv.empty() || argv[0] == "help" || argv[0] == "--help" || argv[0] == "-h") {
    // `reenact help jobs` as `reenact jobs --help`.
    if (argv.size() == 2 && argv[0] == "help" && IsGroup(argv[1])) {
      PrintUsage(out, argv[1]);
      return kExitOk;
    }
    PrintUsage(argv.empty() ? err : out);
    return argv.empty() ? kExitUsage : kExitOk;
  }
  if (argv[0] == "--version" || argv[0] == "version") {
    out << "reenact " << REENACT_VERSION << "\n";
    return kExitOk;
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
    err << "reenact: unknown command '" << argv[0] << " " << argv[1] << "'"
        << DidYouMean(argv[0] + " " + argv[1], argv[0]) << "\n";
    PrintUsage(err, argv[0]);
    return kExitUsage;
  }
  if (!best) {
    const std::string typed =
        argv.size() > 1 && argv[1].rfind('-', 0) != 0 ? argv[0] + " " + argv[1] : argv[0];
    std::string hint = DidYouMean(typed, "");
    if (hint.empty() && typed != argv[0]) hint = DidYouMean(argv[0], "");
    err << "reenact: unknown command '" << argv[0] << "'" << hint << "\n";
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
