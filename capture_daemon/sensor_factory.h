// Sensor factory of reenactd: turns `--source` specs into open sensors.
// The backends, their syntax, defaults and id prefixes are the table of
// capture_daemon/sensors/source_backends.h (`reenactd --help` lists them).
//
// Several sources may be given (a list, or comma-separated in one spec).
// Sensor ids are unique across sources: hardware sensors and recordings are
// numbered on past the ids already taken ("k0", "k1", ... for Kinects and
// Azure Kinect / TUM recordings, "o0", ... for OpenNI2 devices and .oni
// recordings), and a take whose ids are taken plays under "p<source>-<n>".
#pragma once

#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "capture_daemon/sensors/backends.h"
#include "capture_daemon/sensors/sensor.h"

namespace reenact::capture {

struct SourceSpec {
  // A SourceBackend's name ("playback", "freenect", ...).
  std::string backend;
  std::string argument;  // File or folder, device index/serial/URI, or "all"/"any".
  std::string ToString() const { return backend + ":" + argument; }
};

// Parses specs, splitting each at commas. InvalidArgument naming the spec
// for an unknown backend or a missing argument (playback and the recordings
// need a file or folder; the hardware backends default to "all"/"any"), the
// error listing the backends.
absl::StatusOr<std::vector<SourceSpec>> ParseSourceSpecs(const std::vector<std::string>& specs);

// Whether the spec names devices on a bus (SourceBackend.hardware): USB
// arrivals rescan it, and frames cannot wait for the server.
bool IsHardware(const SourceSpec& spec);

// Opens every source in order. `options` (fast, loop) apply to all; the id
// fields are set per source. The first failing source's error is returned,
// prefixed with its spec.
absl::StatusOr<SensorList> OpenSources(const std::vector<SourceSpec>& specs,
                                       const SourceOptions& options);

}  // namespace reenact::capture
