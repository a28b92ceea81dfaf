#include "common/methods/option_reader.h"

#include <cmath>

#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"

namespace reenact::methods {

const std::string* OptionReader::Visit(OptionSpec spec) {
  if (options_ == nullptr) {
    described_.push_back(std::move(spec));
    return nullptr;
  }
  known_.insert(spec.name);
  const auto it = options_->find(spec.name);
  return it == options_->end() ? nullptr : &it->second;
}

absl::Status OptionReader::Int(const std::string& key, int* value, int min, int max,
                               const std::string& doc) {
  const bool bounded = min != INT_MIN || max != INT_MAX;
  const std::string* text =
      Visit({key, OptionType::kInt, absl::StrCat(*value), bounded, double(min), double(max), doc});
  if (text == nullptr) return absl::OkStatus();
  int parsed = 0;
  if (!absl::SimpleAtoi(*text, &parsed)) {
    return absl::InvalidArgumentError(
        absl::StrCat("option ", key, ": \"", *text, "\" is not an integer"));
  }
  if (parsed < min || parsed > max) {
    return absl::InvalidArgumentError(
        absl::StrCat("option ", key, ": ", parsed, " is outside [", min, ", ", max, "]"));
  }
  *value = parsed;
  return absl::OkStatus();
}

absl::Status OptionReader::Double(const std::string& key, double* value, double min, double max,
                                  const std::string& doc) {
  const bool bounded = min != -1e300 || max != 1e300;
  const std::string* text =
      Visit({key, OptionType::kDouble, absl::StrCat(*value), bounded, min, max, doc});
  if (text == nullptr) return absl::OkStatus();
  double parsed = 0;
  if (!absl::SimpleAtod(*text, &parsed) || !std::isfinite(parsed)) {
    return absl::InvalidArgumentError(
        absl::StrCat("option ", key, ": \"", *text, "\" is not a finite number"));
  }
  if (parsed < min || parsed > max) {
    return absl::InvalidArgumentError(
        absl::StrCat("option ", key, ": ", parsed, " is outside [", min, ", ", max, "]"));
  }
  *value = parsed;
  return absl::OkStatus();
}

absl::Status OptionReader::Bool(const std::string& key, bool* value, const std::string& doc) {
  const std::string* text =
      Visit({key, OptionType::kBool, *value ? "true" : "false", false, 0.0, 0.0, doc});
  if (text == nullptr) return absl::OkStatus();
  // Exactly "true" or "false": absl::SimpleAtob would also take "yes", "y",
  // "t" and "1", which read as a typo as easily as a choice.
  if (*text != "true" && *text != "false") {
    return absl::InvalidArgumentError(
        absl::StrCat("option ", key, ": \"", *text, "\" is not true or false"));
  }
  *value = *text == "true";
  return absl::OkStatus();
}

absl::Status OptionReader::String(const std::string& key, std::string* value,
                                  const std::string& doc) {
  const std::string* text = Visit({key, OptionType::kString, *value, false, 0.0, 0.0, doc});
  if (text != nullptr) *value = *text;
  return absl::OkStatus();
}

absl::Status OptionReader::Finish() const {
  if (options_ == nullptr) return absl::OkStatus();
  std::vector<std::string> unknown;
  for (const auto& [key, value] : *options_) {
    if (!known_.count(key)) unknown.push_back(key);
  }
  if (unknown.empty()) return absl::OkStatus();
  return absl::InvalidArgumentError(absl::StrCat("unknown option", unknown.size() > 1 ? "s" : "",
                                                 " ", absl::StrJoin(unknown, ", "),
                                                 " (known: ", absl::StrJoin(known_, ", "), ")"));
}

}  // namespace reenact::methods
