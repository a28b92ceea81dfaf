#include "common/base/flags.h"

#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "common/base/nearest_name.h"

namespace reenact {

absl::StatusOr<Flags> Flags::Parse(const std::vector<std::string>& args,
                                   const std::set<std::string>& value_flags,
                                   const std::set<std::string>& bool_flags) {
  Flags flags;
  for (size_t i = 0; i < args.size(); ++i) {
    const std::string& arg = args[i];
    if (arg.rfind("--", 0) != 0 || arg.size() == 2) {
      flags.positional_.push_back(arg);
      continue;
    }
    std::string name = arg.substr(2);
    std::optional<std::string> value;
    if (const size_t eq = name.find('='); eq != std::string::npos) {
      value = name.substr(eq + 1);
      name = name.substr(0, eq);
    }
    if (bool_flags.count(name)) {
      if (value) return absl::InvalidArgumentError(absl::StrCat("--", name, " takes no value"));
      flags.values_[name] = "true";
    } else if (value_flags.count(name)) {
      if (!value) {
        if (i + 1 >= args.size()) {
          return absl::InvalidArgumentError(absl::StrCat("--", name, " needs a value"));
        }
        value = args[++i];
      }
      flags.values_[name] = *value;
    } else {
      std::vector<std::string> known(value_flags.begin(), value_flags.end());
      known.insert(known.end(), bool_flags.begin(), bool_flags.end());
      const std::optional<std::string> near = NearestName(name, known);
      return absl::InvalidArgumentError(
          absl::StrCat("unknown flag --", name,
                       near ? absl::StrCat(" (did you mean --", *near, "?)") : std::string()));
    }
  }
  return flags;
}

std::optional<std::string> Flags::Get(const std::string& name) const {
  auto it = values_.find(name);
  if (it == values_.end()) return std::nullopt;
  return it->second;
}

std::string Flags::GetOr(const std::string& name, const std::string& fallback) const {
  return Get(name).value_or(fallback);
}

absl::StatusOr<std::string> Flags::Required(const std::string& name) const {
  auto value = Get(name);
  if (!value || value->empty()) {
    return absl::InvalidArgumentError(absl::StrCat("missing required flag --", name));
  }
  return *value;
}

absl::StatusOr<int> Flags::GetInt(const std::string& name, int fallback) const {
  auto value = Get(name);
  if (!value) return fallback;
  int out = 0;
  if (!absl::SimpleAtoi(*value, &out)) {
    return absl::InvalidArgumentError(absl::StrCat("--", name, ": not an integer: ", *value));
  }
  return out;
}

absl::StatusOr<double> Flags::GetDouble(const std::string& name, double fallback) const {
  auto value = Get(name);
  if (!value) return fallback;
  double out = 0;
  if (!absl::SimpleAtod(*value, &out)) {
    return absl::InvalidArgumentError(absl::StrCat("--", name, ": not a number: ", *value));
  }
  return out;
}

absl::Status SplitHostPort(absl::string_view what, const std::string& address, std::string* host,
                           int* port) {
  const auto bad = [&](absl::string_view why) {
    return absl::InvalidArgumentError(
        absl::StrCat(what, " \"", address, "\" is not HOST:PORT: ", why));
  };
  const size_t colon = address.rfind(':');
  if (colon == std::string::npos) return bad("no port");
  if (colon == 0) return bad("no host");
  int value = -1;
  if (!absl::SimpleAtoi(address.substr(colon + 1), &value) || value < 0 || value > 65535) {
    return bad("the port must be a number from 0 to 65535");
  }
  std::string name = address.substr(0, colon);
  const bool bracketed = name.front() == '[';
  if (bracketed ? name.size() < 3 || name.back() != ']' : name.find(':') != std::string::npos) {
    return bad("an IPv6 address goes in brackets, [::1]:PORT");
  }
  *host = bracketed ? name.substr(1, name.size() - 2) : std::move(name);
  *port = value;
  return absl::OkStatus();
}

std::string JoinHostPort(const std::string& host, int port) {
  return host.find(':') != std::string::npos ? absl::StrCat("[", host, "]:", port)
                                             : absl::StrCat(host, ":", port);
}

}  // namespace reenact
