// Typed options of a reconstruction method, read out of the string map a job
// carries ("key" -> "value", as submitted). One Read(OptionReader&) per
// options struct serves two purposes:
//
//   - parsing: OptionReader(map) fills the struct and remembers which keys
//     were read, so that Finish() can reject the rest, naming what is valid;
//   - describing: OptionReader::Describer() reads nothing and records each
//     option's name, type, bounds, documentation and the struct's current
//     value as its default; MethodSpec::options comes from it, so the list
//     that `reenact jobs methods` prints cannot drift from what is parsed.
//
//   struct Options {
//     double lambda = 0.5;
//     absl::Status Read(OptionReader& reader) {
//       return reader.Double("lambda", &lambda, 0.0, 100.0, "lambda of Eq. 3.5");
//     }
//   };
#pragma once

#include <climits>
#include <map>
#include <set>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "common/methods/method_spec.h"

namespace reenact::methods {

using OptionMap = std::map<std::string, std::string>;

class OptionReader {
 public:
  // Parses `options` (which must outlive the reader).
  explicit OptionReader(const OptionMap& options) : options_(&options) {}
  // Reads nothing; collects an OptionSpec per getter call (described()).
  static OptionReader Describer() { return OptionReader(); }

  // Each getter leaves `*value` unchanged when the key is absent, and
  // returns InvalidArgument naming the key when the text does not parse as
  // the type or (Int, Double) lies outside [min, max].
  absl::Status Int(const std::string& key, int* value, int min = INT_MIN, int max = INT_MAX,
                   const std::string& doc = "");
  absl::Status Double(const std::string& key, double* value, double min = -1e300,
                      double max = 1e300, const std::string& doc = "");
  // "true"/"false"/"1"/"0"/"yes"/"no".
  absl::Status Bool(const std::string& key, bool* value, const std::string& doc = "");
  absl::Status String(const std::string& key, std::string* value, const std::string& doc = "");

  // InvalidArgument naming every key that no getter asked for, and listing
  // the keys the method knows. OK in describe mode.
  absl::Status Finish() const;

  // Describe mode: the options in the order they were read.
  const std::vector<OptionSpec>& described() const { return described_; }

 private:
  OptionReader() = default;
  // Records `spec` (describe mode) or marks its key as known; returns the
  // value text when parsing and the key is present.
  const std::string* Visit(OptionSpec spec);

  const OptionMap* options_ = nullptr;  // Null in describe mode.
  std::set<std::string> known_;
  std::vector<OptionSpec> described_;
};

// Parses `options` into a default `Options` with its Read(OptionReader&),
// rejects unknown keys, then runs its Validate() (cross-field checks).
template <typename Options>
absl::Status ParseOptions(const OptionMap& options, Options* out) {
  OptionReader reader(options);
  if (absl::Status read = out->Read(reader); !read.ok()) return read;
  if (absl::Status finish = reader.Finish(); !finish.ok()) return finish;
  return out->Validate();
}

// The options of a default `Options`, as its Read describes them.
template <typename Options>
std::vector<OptionSpec> DescribeOptions() {
  Options defaults;
  OptionReader describer = OptionReader::Describer();
  (void)defaults.Read(describer);
  return describer.described();
}

}  // namespace reenact::methods
