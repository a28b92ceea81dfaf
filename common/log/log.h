// Structured logs of the Reenact processes (reenact-server, reenactd,
// reenact-worker): one line per event on stderr, written through spdlog.
//
//   log::Info("take_opened", {{"take_id", id}, {"sensors", n}}, "take opened");
//
// An event is a stable snake_case name that operators filter on, key/value
// fields that carry the figures, and an optional human message. Two formats
// (--log-format):
//   text: 2025-03-01T10:00:00.123456Z info take_opened: take opened take_id=t1 sensors=2
//   json: {"ts":"2025-03-01T10:00:00.123456Z","level":"info","event":"take_opened",
//          "msg":"take opened","take_id":"t1","sensors":2}
// Times are UTC. JSON lines are one valid object each (strings escaped, bytes
// that are not UTF-8 replaced), so that a collector can parse them without
// knowing the events; text lines keep every value on the line (quoted and
// escaped when it holds spaces, quotes or control characters). Levels
// (--log-level): debug, info, warn, error; lines below the level are dropped.
//
// Field keys should be unique within an event and not one of ts, level,
// event, msg (such a key is written as "field_<key>").
//
// Thread-safe: lines of concurrent events never interleave.
#pragma once

#include <concepts>
#include <cstdint>
#include <iosfwd>
#include <memory>
#include <string>
#include <string_view>
#include <variant>

#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"
#include "absl/types/span.h"

namespace reenact::log {

enum class Level { kDebug, kInfo, kWarn, kError };
enum class Format { kText, kJson };

// "debug", "info", "warn", "error".
absl::string_view LevelName(Level level);

struct Options {
  Format format = Format::kText;
  Level level = Level::kInfo;
};

// The values of --log-format (text|json) and --log-level
// (debug|info|warn|error); InvalidArgument naming the flag otherwise.
absl::StatusOr<Options> ParseOptions(absl::string_view format, absl::string_view level);

// One line of a program's usage text for the two flags.
inline constexpr char kFlagsUsage[] =
    "[--log-format text|json (default text)] [--log-level debug|info|warn|error (default info)]";

// A field's value: text, an integer, a floating-point number or a boolean.
// The constructors are implicit on purpose: a field list reads
// {{"take_id", id}, {"bytes", n}} whatever the types of id and n.
class Value {
 public:
  Value(const char* text) : value_(std::string(text == nullptr ? "" : text)) {}
  Value(std::string_view text) : value_(std::string(text)) {}
  Value(const std::string& text) : value_(text) {}
  Value(absl::string_view text) : value_(std::string(text)) {}
  Value(bool b) : value_(b) {}
  template <std::integral T>
  requires(!std::same_as<T, bool>) Value(T number) {
    if constexpr (std::is_signed_v<T>) {
      value_ = static_cast<int64_t>(number);
    } else {
      value_ = static_cast<uint64_t>(number);
    }
  }
  template <std::floating_point T>
  Value(T number) : value_(static_cast<double>(number)) {}

  using Variant = std::variant<std::string, int64_t, uint64_t, double, bool>;
  const Variant& variant() const { return value_; }

 private:
  Variant value_;
};

struct Field {
  absl::string_view key;
  Value value;
};
// A braced list ({{"take_id", id}, {"bytes", n}}) or a vector of fields.
using Fields = absl::Span<const Field>;

// A destination with its format and level. Copies share the destination.
class Logger {
 public:
  // Writes to stderr.
  explicit Logger(const Options& options = {});
  // Writes to `out`, which must outlive every copy; null discards every line.
  Logger(std::ostream* out, const Options& options);

  bool Enabled(Level level) const;
  void Log(Level level, absl::string_view event, Fields fields = {},
           absl::string_view msg = {}) const;
  void Debug(absl::string_view event, Fields fields = {}, absl::string_view msg = {}) const {
    Log(Level::kDebug, event, fields, msg);
  }
  void Info(absl::string_view event, Fields fields = {}, absl::string_view msg = {}) const {
    Log(Level::kInfo, event, fields, msg);
  }
  void Warn(absl::string_view event, Fields fields = {}, absl::string_view msg = {}) const {
    Log(Level::kWarn, event, fields, msg);
  }
  void Error(absl::string_view event, Fields fields = {}, absl::string_view msg = {}) const {
    Log(Level::kError, event, fields, msg);
  }

  const Options& options() const;

 private:
  struct Impl;
  std::shared_ptr<const Impl> impl_;
};

// The process's logger (stderr; text at info until Configure is called).
// Programs call Configure once from their flags, before their threads start.
void Configure(const Options& options);
Logger Default();

// The process logger's events.
void Log(Level level, absl::string_view event, Fields fields = {}, absl::string_view msg = {});
inline void Debug(absl::string_view event, Fields fields = {}, absl::string_view msg = {}) {
  Log(Level::kDebug, event, fields, msg);
}
inline void Info(absl::string_view event, Fields fields = {}, absl::string_view msg = {}) {
  Log(Level::kInfo, event, fields, msg);
}
inline void Warn(absl::string_view event, Fields fields = {}, absl::string_view msg = {}) {
  Log(Level::kWarn, event, fields, msg);
}
inline void Error(absl::string_view event, Fields fields = {}, absl::string_view msg = {}) {
  Log(Level::kError, event, fields, msg);
}

}  // namespace reenact::log
