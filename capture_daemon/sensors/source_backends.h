// The sources reenactd can open, in one table: each backend's name as
// `--source NAME:ARGUMENT` spells it, its argument's syntax and default, the
// prefix of the sensor ids it hands out, whether this build can open it,
// and the function that opens it. Parsing and opening the specs
// (capture_daemon/sensor_factory.h), the usage text, the errors and the USB
// hotplug rescans (capture_daemon/daemon.cc) all read this table; a backend
// is added here and nowhere else (docs/architecture.md, "Adding a sensor
// backend").
//
// An Open function returns one Sensor per device or recorded sensor, ids
// options.id_prefix + (options.first_index + i); NotFound when nothing
// matches the argument, Unimplemented when the backend was not built.
#pragma once

#include <string>

#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"
#include "absl/types/span.h"
#include "capture_daemon/sensors/backends.h"
#include "capture_daemon/sensors/sensor.h"

namespace reenact::capture {

struct SourceBackend {
  // As in `--source NAME:ARGUMENT` and SensorInfo.backend.
  absl::string_view name;
  // `--source` syntax, e.g. "freenect:0|SERIAL|all".
  absl::string_view syntax;
  // One line on what it opens, for the usage text.
  absl::string_view description;
  // The argument when none is given ("all", "any"); empty when one is
  // needed, and then `needs` says what ("a file", "a folder").
  absl::string_view default_argument;
  absl::string_view needs;
  // Sensor ids handed out: `id_prefix` + n, numbered on past the ids that
  // earlier sources took. Empty: the source's own ids (a take's), renamed
  // "p<source>-<n>" only when they clash with ids already taken.
  absl::string_view id_prefix;
  // Devices on a bus: a USB arrival rescans it, and an argument equal to the
  // default means "whichever are there".
  bool hardware = false;
  // Whether this build can open it (vendor libraries found at build time).
  bool (*built)() = nullptr;
  // Opens `argument` ("all" and "any" turned into "" for hardware).
  absl::StatusOr<SensorList> (*open)(const std::string& argument,
                                     const SourceOptions& options) = nullptr;
};

// Every backend, in the order the usage text lists them.
absl::Span<const SourceBackend> SourceBackends();

// The backend called `name`, or nullptr.
const SourceBackend* FindSourceBackend(absl::string_view name);

// "playback:FILE | freenect:0|SERIAL|all | ...", for usage text and errors.
std::string SourceSyntaxList();

}  // namespace reenact::capture
