// reenact auth add: tokens for reenact-server --auth and reenactd --auth.
#include <ostream>

#include "absl/status/status.h"
#include "clients/cli/command.h"
#include "clients/cli/commands.h"
#include "common/base/flags.h"
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
  out << *token << "\n";
  err << "reenact: added " << flags->GetOr("name", "") << " (" << rpc::RoleName(*role) << ") to "
      << file << "; the token above is shown only now\n";
  return kExitOk;
}

}  // namespace reenact::cli
