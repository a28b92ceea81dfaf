#include "clients/cli/remote_flags.h"

#include <cmath>
#include <ctime>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "clients/cli/command.h"
#include "common/base/time.h"
#include "common/rpc/channel.h"

namespace reenact::cli {

absl::StatusOr<client::ConnectionOptions> ConnectionFromFlags(const Flags& flags,
                                                              const char* address_flag,
                                                              const char* fallback,
                                                              double default_timeout_s) {
  client::ConnectionOptions options;
  options.address = flags.GetOr(address_flag, fallback);
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
