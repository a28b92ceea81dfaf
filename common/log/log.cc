#include "common/log/log.h"

#include <cstdio>
#include <mutex>
#include <ostream>
#include <utility>
#include <vector>

#include <spdlog/logger.h>
#include <spdlog/pattern_formatter.h>
#include <spdlog/sinks/ostream_sink.h>
#include <spdlog/sinks/stdout_sinks.h>
#include <nlohmann/json.hpp>

#include "absl/strings/str_cat.h"
#include "common/base/json_text.h"

namespace reenact::log {
namespace {

// spdlog writes the time stamp (UTC, microseconds); the rest of the line is
// ours, so that the level names and the JSON escaping are exactly ours.
constexpr char kTextPattern[] = "%Y-%m-%dT%H:%M:%S.%fZ %v";
constexpr char kJsonPattern[] = "{\"ts\":\"%Y-%m-%dT%H:%M:%S.%fZ\",%v}";

spdlog::level::level_enum SpdLevel(Level level) {
  switch (level) {
    case Level::kDebug:
      return spdlog::level::debug;
    case Level::kInfo:
      return spdlog::level::info;
    case Level::kWarn:
      return spdlog::level::warn;
    case Level::kError:
      return spdlog::level::err;
  }
  return spdlog::level::info;
}

// A JSON string literal of `text`; bytes that are not UTF-8 become U+FFFD
// rather than an exception or an invalid line.
std::string JsonString(absl::string_view text) {
  return nlohmann::json(std::string(text))
      .dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
}

std::string JsonValue(const Value& value) {
  return std::visit(
      [](const auto& v) -> std::string {
        using T = std::decay_t<decltype(v)>;
        if constexpr (std::is_same_v<T, std::string>) {
          return JsonString(v);
        } else {
          // Non-finite doubles come out as null, which JSON allows.
          return JsonText(nlohmann::json(v));
        }
      },
      value.variant());
}

bool IsReserved(absl::string_view key) {
  return key == "ts" || key == "level" || key == "event" || key == "msg";
}

// Text values stay on one line: control characters are escaped, and a value
// that a reader could not split from the next field is quoted.
void AppendEscaped(absl::string_view text, std::string* out) {
  for (const char c : text) {
    switch (c) {
      case '"':
        out->append("\\\"");
        break;
      case '\\':
        out->append("\\\\");
        break;
      case '\n':
        out->append("\\n");
        break;
      case '\r':
        out->append("\\r");
        break;
      case '\t':
        out->append("\\t");
        break;
      default:
        if (static_cast<unsigned char>(c) < 0x20 || c == 0x7f) {
          char hex[8];
          std::snprintf(hex, sizeof(hex), "\\x%02x", static_cast<unsigned char>(c));
          out->append(hex);
        } else {
          out->push_back(c);
        }
    }
  }
}

bool NeedsQuotes(absl::string_view text) {
  if (text.empty()) return true;
  for (const char c : text) {
    if (c == ' ' || c == '"' || c == '=' || c == '\\' || static_cast<unsigned char>(c) < 0x20 ||
        c == 0x7f) {
      return true;
    }
  }
  return false;
}

std::string TextValue(const Value& value) {
  if (const auto* text = std::get_if<std::string>(&value.variant())) {
    std::string out;
    const bool quoted = NeedsQuotes(*text);
    if (quoted) out.push_back('"');
    AppendEscaped(*text, &out);
    if (quoted) out.push_back('"');
    return out;
  }
  if (const auto* b = std::get_if<bool>(&value.variant())) return *b ? "true" : "false";
  return JsonValue(value);  // Numbers: the shortest text that reads back the same.
}

std::string FormatBody(Format format, Level level, absl::string_view event, Fields fields,
                       absl::string_view msg) {
  std::string line;
  if (format == Format::kJson) {
    absl::StrAppend(&line, "\"level\":\"", LevelName(level), "\",\"event\":", JsonString(event),
                    ",\"msg\":", JsonString(msg));
    for (const Field& field : fields) {
      const std::string key =
          IsReserved(field.key) ? absl::StrCat("field_", field.key) : std::string(field.key);
      absl::StrAppend(&line, ",", JsonString(key), ":", JsonValue(field.value));
    }
    return line;
  }
  absl::StrAppend(&line, LevelName(level), " ");
  AppendEscaped(event, &line);
  if (!msg.empty()) {
    line.append(": ");
    AppendEscaped(msg, &line);
  }
  for (const Field& field : fields) {
    line.push_back(' ');
    AppendEscaped(field.key, &line);
    line.push_back('=');
    line.append(TextValue(field.value));
  }
  return line;
}

}  // namespace

absl::string_view LevelName(Level level) {
  switch (level) {
    case Level::kDebug:
      return "debug";
    case Level::kInfo:
      return "info";
    case Level::kWarn:
      return "warn";
    case Level::kError:
      return "error";
  }
  return "info";
}

absl::StatusOr<Options> ParseOptions(absl::string_view format, absl::string_view level) {
  Options options;
  if (format == "text") {
    options.format = Format::kText;
  } else if (format == "json") {
    options.format = Format::kJson;
  } else {
    return absl::InvalidArgumentError(
        absl::StrCat("--log-format must be text or json, got \"", format, "\""));
  }
  if (level == "debug") {
    options.level = Level::kDebug;
  } else if (level == "info") {
    options.level = Level::kInfo;
  } else if (level == "warn") {
    options.level = Level::kWarn;
  } else if (level == "error") {
    options.level = Level::kError;
  } else {
    return absl::InvalidArgumentError(
        absl::StrCat("--log-level must be debug, info, warn or error, got \"", level, "\""));
  }
  return options;
}

struct Logger::Impl {
  Options options;
  // Null: every line is dropped.
  std::shared_ptr<spdlog::logger> logger;
};

namespace {

std::shared_ptr<spdlog::logger> MakeSpdLogger(spdlog::sink_ptr sink, const Options& options) {
  // Not registered with spdlog's registry: loggers of tests and of a daemon
  // beside the process logger must not collide on a name.
  auto logger = std::make_shared<spdlog::logger>("reenact", std::move(sink));
  logger->set_formatter(std::make_unique<spdlog::pattern_formatter>(
      options.format == Format::kJson ? kJsonPattern : kTextPattern,
      spdlog::pattern_time_type::utc));
  logger->set_level(SpdLevel(options.level));
  // A line is on its way before the event's effects are: a crash right after
  // loses nothing that was logged.
  logger->flush_on(spdlog::level::trace);
  return logger;
}

}  // namespace

Logger::Logger(const Options& options) {
  auto impl = std::make_shared<Impl>();
  impl->options = options;
  impl->logger = MakeSpdLogger(std::make_shared<spdlog::sinks::stderr_sink_mt>(), options);
  impl_ = std::move(impl);
}

Logger::Logger(std::ostream* out, const Options& options) {
  auto impl = std::make_shared<Impl>();
  impl->options = options;
  if (out != nullptr) {
    impl->logger = MakeSpdLogger(
        std::make_shared<spdlog::sinks::ostream_sink_mt>(*out, /*force_flush=*/true), options);
  }
  impl_ = std::move(impl);
}

bool Logger::Enabled(Level level) const {
  return impl_->logger != nullptr && impl_->logger->should_log(SpdLevel(level));
}

void Logger::Log(Level level, absl::string_view event, Fields fields, absl::string_view msg) const {
  if (!Enabled(level)) return;
  const std::string body = FormatBody(impl_->options.format, level, event, fields, msg);
  impl_->logger->log(SpdLevel(level), spdlog::string_view_t(body.data(), body.size()));
}

const Options& Logger::options() const { return impl_->options; }

namespace {

std::mutex& DefaultMutex() {
  static auto* const mu = new std::mutex;
  return *mu;
}

Logger& DefaultLocked() {
  static auto* const logger = new Logger(Options{});
  return *logger;
}

}  // namespace

void Configure(const Options& options) {
  std::lock_guard<std::mutex> lock(DefaultMutex());
  DefaultLocked() = Logger(options);
}

Logger Default() {
  std::lock_guard<std::mutex> lock(DefaultMutex());
  return DefaultLocked();
}

void Log(Level level, absl::string_view event, Fields fields, absl::string_view msg) {
  Default().Log(level, event, fields, msg);
}

}  // namespace reenact::log
