// What the commands that talk to a reenact-server or a reenactd share: the
// default addresses, the connection from --server/--daemon and --timeout,
// how a failed RPC is reported, and how sizes and times are printed.
#pragma once

#include <cstdint>
#include <iosfwd>
#include <string>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "clients/sdk/takes_client.h"
#include "common/base/flags.h"

namespace reenact::cli {

inline constexpr char kDefaultServer[] = "127.0.0.1:50051";
inline constexpr char kDefaultDaemon[] = "127.0.0.1:50052";

// $REENACT_SERVER when it is set and not empty, else `fallback`.
std::string ServerAddressFromEnvironment(const char* fallback = kDefaultServer);

// The address from `--<address_flag>` (else, for --server, $REENACT_SERVER;
// else `fallback`), the RPC deadline from --timeout seconds (else
// `default_timeout_s`), the server's CA from --tls-ca (else
// $REENACT_TLS_CA) and the token from --token-file (else $REENACT_TOKEN).
// InvalidArgument for an address that is not HOST:PORT (or unix:PATH), a
// timeout that is not a positive number or an unreadable CA or token file.
absl::StatusOr<client::ConnectionOptions> ConnectionFromFlags(const Flags& flags,
                                                              const char* address_flag = "server",
                                                              const char* fallback = kDefaultServer,
                                                              double default_timeout_s = 10.0);

// Prints the error with its status name ("PERMISSION_DENIED: ...") and,
// for an unreachable server, a missing token or the like, a line on what to
// try next; returns kExitFailure: a failed RPC is a failure, not a usage error,
// whatever its code.
int ReportRemoteError(const absl::Status& status, std::ostream& err);

// "512 B", "3.2 KiB", "4.0 MiB", "1.25 GiB".
std::string HumanBytes(int64_t bytes);

// "2026-03-01 12:00:05Z"; "-" for 0 (not set).
std::string UtcTime(int64_t unix_ns);

}  // namespace reenact::cli
