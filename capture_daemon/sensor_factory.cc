#include "capture_daemon/sensor_factory.h"

#include <set>

#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_split.h"
#include "absl/strings/strip.h"
#include "capture_daemon/playback_sensor.h"

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
  if (spec.backend == "playback") {
    options.id_prefix.clear();
    absl::StatusOr<SensorList> sensors = OpenPlaybackSensors(spec.argument, options);
    if (!sensors.ok()) return sensors;
    bool clash = false;
    for (const auto& sensor : *sensors) clash |= taken.count(sensor->info().sensor_id()) > 0;
    if (!clash) return sensors;
    options.id_prefix = absl::StrCat("p", source_number, "-");
    options.first_index = 0;
    return OpenPlaybackSensors(spec.argument, options);
  }
  if (spec.backend == "azure-mkv" || spec.backend == "tum" || spec.backend == "oni") {
    // Recordings of other tools: Kinect ids for Azure Kinect and TUM (a
    // Kinect v1), OpenNI2 ids for .oni files.
    options.id_prefix = spec.backend == "oni" ? "o" : "k";
    options.first_index = NextIndex(taken, options.id_prefix);
    return OpenRecordingSensors(spec.backend, spec.argument, options);
  }
  const std::string argument =
      spec.argument == "all" || spec.argument == "any" ? "" : spec.argument;
  if (spec.backend == "freenect" || spec.backend == "freenect2") {
    options.id_prefix = "k";
    options.first_index = NextIndex(taken, "k");
    return spec.backend == "freenect" ? OpenFreenectSensors(argument, options)
                                      : OpenFreenect2Sensors(argument, options);
  }
  options.id_prefix = "o";
  options.first_index = NextIndex(taken, "o");
  return OpenOpenni2Sensors(argument, options);
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
      if (spec.backend == "playback") {
        if (spec.argument.empty()) {
          return absl::InvalidArgumentError(absl::StrCat(
              "source \"", std::string(item), "\": playback needs a file (playback:FILE)"));
        }
      } else if (spec.backend == "azure-mkv" || spec.backend == "tum" || spec.backend == "oni") {
        if (spec.argument.empty()) {
          return absl::InvalidArgumentError(
              absl::StrCat("source \"", std::string(item), "\": ", spec.backend, " needs a ",
                           spec.backend == "tum" ? "folder (tum:DIR)"
                                                 : absl::StrCat("file (", spec.backend, ":FILE)")));
        }
      } else if (spec.backend == "freenect") {
        if (spec.argument.empty()) spec.argument = "all";
      } else if (spec.backend == "openni2" || spec.backend == "freenect2") {
        if (spec.argument.empty()) spec.argument = "any";
      } else {
        return absl::InvalidArgumentError(absl::StrCat(
            "source \"", std::string(item),
            "\": unknown backend (expected playback:FILE, freenect:0|SERIAL|all, openni2:any|URI, "
            "freenect2:any|SERIAL, azure-mkv:FILE, tum:DIR or oni:FILE)"));
      }
      out.push_back(std::move(spec));
    }
  }
  if (out.empty()) return absl::InvalidArgumentError("no --source given");
  return out;
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
