// reenact auth add|list|remove: tokens for reenact-server --auth and reenactd
// --auth.
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <iostream>
#include <ostream>

#include <nlohmann/json.hpp>

#include "absl/status/status.h"
#include "absl/strings/str_format.h"
#include "clients/cli/command.h"
#include "clients/cli/commands.h"
#include "common/base/flags.h"
#include "common/base/json_text.h"
#include "common/base/terminal_text.h"
#include "common/rpc/auth.h"

namespace reenact::cli {

int RunAuthAdd(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  auto flags = Flags::Parse(args, {"file", "role", "name"}, {});
  if (!flags.ok()) return ReportError(flags.status(), err);
  if (!flags->Has("file") || !flags->Has("role") || !flags->Has("name") ||
      !flags->positional().empty()) {
    return ReportError(absl::InvalidArgumentError("auth add needs --file, --role and --name"), err);
  }
  auto role = rpc::ParseRole(flags->GetOr("role", ""));
  if (!role.ok()) return ReportError(role.status(), err);
  const std::string file = flags->GetOr("file", "");
  auto token = rpc::AddToken(file, *role, flags->GetOr("name", ""));
  if (!token.ok()) {
    err << "reenact: " << token.status().message() << "\n";
    return token.status().code() == absl::StatusCode::kInvalidArgument ? kExitUsage : kExitFailure;
  }
  // `reenact auth add ... > x.token`: the shell made the file with its
  // umask (often 0644); a token is a password, so it becomes 0600 before
  // the token is written.
  struct stat info {};
  if (&out == &std::cout && ::fstat(STDOUT_FILENO, &info) == 0 && S_ISREG(info.st_mode) &&
      (info.st_mode & 077) != 0) {
    std::cout.flush();
    if (::fchmod(STDOUT_FILENO, 0600) != 0) {
      err << "reenact: the token is not printed: its file cannot be made 0600: "
          << std::strerror(errno) << "\n";
      return kExitFailure;
    }
  }
  out << *token << "\n";
  err << "reenact: added " << flags->GetOr("name", "") << " (" << rpc::RoleName(*role) << ") to "
      << file << "; the token above is shown only now\n";
  return kExitOk;
}

int RunAuthList(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  auto flags = Flags::Parse(args, {"file"}, {"json"});
  if (!flags.ok()) return ReportError(flags.status(), err);
  if (!flags->Has("file") || !flags->positional().empty()) {
    return ReportError(absl::InvalidArgumentError("auth list needs --file"), err);
  }
  auto table = rpc::TokenTable::Load(flags->GetOr("file", ""));
  if (!table.ok()) return ReportError(table.status(), err);
  if (flags->Has("json")) {
    nlohmann::json tokens = nlohmann::json::array();
    for (const auto& [name, role] : table->Names()) {
      tokens.push_back({{"name", name}, {"role", std::string(rpc::RoleName(role))}});
    }
    out << JsonText(nlohmann::json{{"tokens", tokens}}, 2) << "\n";
    return kExitOk;
  }
  out << "NAME                             ROLE\n";
  for (const auto& [name, role] : table->Names()) {
    out << absl::StrFormat("%-32s %s\n", TerminalSafe(name), rpc::RoleName(role));
  }
  if (table->size() == 0) out << "(no tokens)\n";
  return kExitOk;
}

int RunAuthRemove(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  auto flags = Flags::Parse(args, {"file", "name"}, {});
  if (!flags.ok()) return ReportError(flags.status(), err);
  if (!flags->Has("file") || !flags->Has("name") || !flags->positional().empty()) {
    return ReportError(absl::InvalidArgumentError("auth remove needs --file and --name"), err);
  }
  const std::string file = flags->GetOr("file", "");
  const std::string name = flags->GetOr("name", "");
  if (absl::Status removed = rpc::RemoveToken(file, name); !removed.ok()) {
    return ReportError(removed, err);
  }
  out << "removed " << TerminalSafe(name) << " from " << file
      << "; a running server forgets it on SIGHUP (systemctl reload reenact-server)\n";
  return kExitOk;
}

}  // namespace reenact::cli
