#include "clients/cli/remote_flags.h"

#include <cmath>
#include <cstdlib>
#include <ctime>

#include "absl/strings/ascii.h"
#include "absl/strings/match.h"
#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "absl/strings/string_view.h"
#include "clients/cli/command.h"
#include "common/base/status_macros.h"
#include "common/base/time.h"
#include "common/rpc/channel.h"

namespace reenact::cli {

namespace {

// OK for "HOST:PORT" (HOST a name, an IPv4 address or a bracketed IPv6
// one; PORT 1..65535) and "unix:PATH"; InvalidArgument naming `flag`
// otherwise, before anything dials a port 0 or a name with no port.
absl::Status CheckAddress(const std::string& address, const std::string& flag) {
  if (absl::StartsWith(address, "unix:") && address.size() > 5) return absl::OkStatus();
  const std::string example = flag == "daemon" ? kDefaultDaemon : kDefaultServer;
  std::string host;
  int port = 0;
  absl::Status split = SplitHostPort(absl::StrCat("--", flag), address, &host, &port);
  if (split.ok() && port == 0) {
    split = absl::InvalidArgumentError(
        absl::StrCat("--", flag, " \"", address, "\": port 0 names no server"));
  }
  if (split.ok()) return split;
  return absl::InvalidArgumentError(
      absl::StrCat(split.message(), "; give HOST:PORT, e.g. ", example));
}

// What to try next after a failed RPC with `status` (empty: nothing to add
// to the message).
std::string Hint(const absl::Status& status) {
  const std::string message = absl::AsciiStrToLower(status.message());
  switch (status.code()) {
    case absl::StatusCode::kUnavailable:
      if (absl::StrContains(message, "dns") || absl::StrContains(message, "resolv") ||
          absl::StrContains(message, "c-ares")) {
        return "the host name does not resolve: check the --server address (or REENACT_SERVER)";
      }
      if (absl::StrContains(message, "socket closed") ||
          absl::StrContains(message, "connection reset") ||
          absl::StrContains(message, "handshake") || absl::StrContains(message, "http1")) {
        return "something answered there but not in gRPC: is that the server's --listen port "
               "(not its --http or --metrics port)? A server with TLS needs --tls-ca CA.pem "
               "(or REENACT_TLS_CA)";
      }
      return "nothing answers there: is reenact-server running, and is the address its --listen "
             "HOST:PORT? Give it with --server HOST:PORT or REENACT_SERVER (default " +
             std::string(kDefaultServer) + ")";
    case absl::StatusCode::kDeadlineExceeded:
      return "no answer within --timeout: a busy or distant server needs a longer one; a TLS "
             "server dialled without --tls-ca also never answers";
    case absl::StatusCode::kUnauthenticated:
      return "this server wants a token: --token-file FILE or REENACT_TOKEN (whoever runs the "
             "server makes one with `reenact auth add`)";
    case absl::StatusCode::kPermissionDenied:
      return "your token's role may not do this: ask whoever runs the server for a token with "
             "that role (`reenact auth list` shows them)";
    default:
      return "";
  }
}

}  // namespace

std::string ServerAddressFromEnvironment(const char* fallback) {
  const char* from_environment = std::getenv("REENACT_SERVER");
  return from_environment != nullptr && *from_environment != '\0' ? from_environment : fallback;
}

absl::StatusOr<client::ConnectionOptions> ConnectionFromFlags(const Flags& flags,
                                                              const char* address_flag,
                                                              const char* fallback,
                                                              double default_timeout_s) {
  client::ConnectionOptions options;
  const std::string flag = address_flag;
  options.address =
      flags.GetOr(flag, flag == "server" ? ServerAddressFromEnvironment(fallback) : fallback);
  RETURN_IF_ERROR(CheckAddress(options.address, flag));
  auto timeout = flags.GetDouble("timeout", default_timeout_s);
  if (!timeout.ok()) return timeout.status();
  if (!(*timeout > 0) || !std::isfinite(*timeout)) {
    return absl::InvalidArgumentError("--timeout must be > 0 seconds");
  }
  options.timeout_s = *timeout;
  auto security = rpc::LoadClientSecurity(flags.GetOr("tls-ca", ""), flags.GetOr("token-file", ""));
  if (!security.ok()) return security.status();
  options.security = *std::move(security);
  return options;
}

int ReportRemoteError(const absl::Status& status, std::ostream& err) {
  // The status name first: UNAUTHENTICATED and PERMISSION_DENIED tell a user
  // to look at their token, whatever the message says.
  err << "reenact: " << absl::StatusCodeToString(status.code()) << ": " << status.message() << "\n";
  if (const std::string hint = Hint(status); !hint.empty()) err << "  hint: " << hint << "\n";
  return kExitFailure;
}

std::string HumanBytes(int64_t bytes) {
  if (bytes >= (int64_t{1} << 30)) return absl::StrFormat("%.2f GiB", bytes / 1073741824.0);
  if (bytes >= (int64_t{1} << 20)) return absl::StrFormat("%.1f MiB", bytes / 1048576.0);
  if (bytes >= 1024) return absl::StrFormat("%.1f KiB", bytes / 1024.0);
  return absl::StrCat(bytes, " B");
}

std::string UtcTime(int64_t unix_ns) {
  if (unix_ns == 0) return "-";
  const std::time_t seconds = static_cast<std::time_t>(unix_ns / kNanosPerSecond);
  std::tm tm{};
  gmtime_r(&seconds, &tm);
  char buffer[32];
  std::strftime(buffer, sizeof(buffer), "%Y-%m-%d %H:%M:%SZ", &tm);
  return buffer;
}

}  // namespace reenact::cli
