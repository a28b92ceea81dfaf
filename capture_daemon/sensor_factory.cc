#include "capture_daemon/sensor_factory.h"

#include <set>

#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_split.h"
#include "absl/strings/strip.h"
#include "capture_daemon/sensors/source_backends.h"

namespace reenact::capture {

namespace {

// One more than the largest n of the taken ids "<prefix><n>".
int NextIndex(const std::set<std::string>& taken, const std::string& prefix) {
  int next = 0;
  for (const std::string& id : taken) {
    int n = 0;
    if (id.rfind(prefix, 0) == 0 && absl::SimpleAtoi(id.substr(prefix.size()), &n) && n >= next) {
      next = n + 1;
    }
  }
  return next;
}

absl::StatusOr<SensorList> OpenOne(const SourceSpec& spec, int source_number,
                                   const std::set<std::string>& taken, SourceOptions options) {
  const SourceBackend* backend = FindSourceBackend(spec.backend);
  if (backend == nullptr) {
    return absl::InvalidArgumentError(absl::StrCat("unknown backend \"", spec.backend, "\""));
  }
  // "all" and "any" ask a hardware backend for whichever devices are there.
  const std::string argument =
      backend->hardware && (spec.argument == "all" || spec.argument == "any") ? "" : spec.argument;
  if (!backend->id_prefix.empty()) {
    options.id_prefix = std::string(backend->id_prefix);
    options.first_index = NextIndex(taken, options.id_prefix);
    return backend->open(argument, options);
  }
  // The source's own ids, unless they clash with those already taken.
  options.id_prefix.clear();
  absl::StatusOr<SensorList> sensors = backend->open(argument, options);
  if (!sensors.ok()) return sensors;
  bool clash = false;
  for (const auto& sensor : *sensors) clash |= taken.count(sensor->info().sensor_id()) > 0;
  if (!clash) return sensors;
  options.id_prefix = absl::StrCat("p", source_number, "-");
  options.first_index = 0;
  return backend->open(argument, options);
}

}  // namespace

absl::StatusOr<std::vector<SourceSpec>> ParseSourceSpecs(const std::vector<std::string>& specs) {
  std::vector<SourceSpec> out;
  for (const std::string& list : specs) {
    for (absl::string_view item : absl::StrSplit(list, ',', absl::SkipWhitespace())) {
      item = absl::StripAsciiWhitespace(item);
      const size_t colon = item.find(':');
      SourceSpec spec;
      spec.backend = std::string(item.substr(0, colon));
      spec.argument = colon == absl::string_view::npos ? "" : std::string(item.substr(colon + 1));
      const SourceBackend* backend = FindSourceBackend(spec.backend);
      if (backend == nullptr) {
        return absl::InvalidArgumentError(absl::StrCat("source \"", std::string(item),
                                                       "\": unknown backend (expected ",
                                                       SourceSyntaxList(), ")"));
      }
      if (spec.argument.empty()) {
        if (backend->default_argument.empty()) {
          return absl::InvalidArgumentError(
              absl::StrCat("source \"", std::string(item), "\": ", backend->name, " needs ",
                           backend->needs, " (", backend->syntax, ")"));
        }
        spec.argument = std::string(backend->default_argument);
      }
      out.push_back(std::move(spec));
    }
  }
  if (out.empty()) return absl::InvalidArgumentError("no --source given");
  return out;
}

bool IsHardware(const SourceSpec& spec) {
  const SourceBackend* backend = FindSourceBackend(spec.backend);
  return backend != nullptr && backend->hardware;
}

absl::StatusOr<SensorList> OpenSources(const std::vector<SourceSpec>& specs,
                                       const SourceOptions& options) {
  SensorList all;
  std::set<std::string> taken;
  for (size_t i = 0; i < specs.size(); ++i) {
    absl::StatusOr<SensorList> sensors = OpenOne(specs[i], static_cast<int>(i), taken, options);
    if (!sensors.ok()) {
      return absl::Status(sensors.status().code(), absl::StrCat("source ", specs[i].ToString(),
                                                                ": ", sensors.status().message()));
    }
    for (auto& sensor : *sensors) {
      const std::string id = sensor->info().sensor_id();
      if (!taken.insert(id).second) {
        return absl::InternalError(
            absl::StrCat("source ", specs[i].ToString(), " gave sensor id ", id, " twice"));
      }
      all.push_back(std::move(sensor));
    }
  }
  return all;
}

}  // namespace reenact::capture
