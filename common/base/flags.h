// A small flag parser for the command-line programs: `--name value`,
// `--name=value`, boolean `--name`, and positional arguments.
#pragma once

#include <map>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"

namespace reenact {

class Flags {
 public:
  // Parses `args`. `value_flags` take a value, `bool_flags` take none; any
  // other `--x` is an error naming it.
  static absl::StatusOr<Flags> Parse(const std::vector<std::string>& args,
                                     const std::set<std::string>& value_flags,
                                     const std::set<std::string>& bool_flags);

  bool Has(const std::string& name) const { return values_.count(name) > 0; }
  std::optional<std::string> Get(const std::string& name) const;
  std::string GetOr(const std::string& name, const std::string& fallback) const;
  // Errors name the flag when the value is missing or not a number.
  absl::StatusOr<std::string> Required(const std::string& name) const;
  absl::StatusOr<int> GetInt(const std::string& name, int fallback) const;
  absl::StatusOr<double> GetDouble(const std::string& name, double fallback) const;
  const std::vector<std::string>& positional() const { return positional_; }

 private:
  std::map<std::string, std::string> values_;
  std::vector<std::string> positional_;
};

// A "HOST:PORT" address flag split at its last colon: the host (a name, an
// IPv4 address, or an IPv6 address in brackets, returned without them) and
// the port (0..65535; 0 picks a free one). InvalidArgument naming `what`
// (e.g. "--http") otherwise.
absl::Status SplitHostPort(absl::string_view what, const std::string& address, std::string* host,
                           int* port);
// "HOST:PORT" again, an IPv6 host in brackets.
std::string JoinHostPort(const std::string& host, int port);

}  // namespace reenact
