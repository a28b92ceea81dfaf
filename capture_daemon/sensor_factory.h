// Sensor factory of reenactd: turns `--source` specs into open sensors.
//
//   playback:FILE            an MCAP take (capture_daemon/playback_sensor.h)
//   freenect:0|SERIAL|all    Kinect v1 through libfreenect
//   openni2:any|URI          an OpenNI2 device
//   freenect2:any|SERIAL     Kinect v2 through libfreenect2
//   azure-mkv:FILE           an Azure Kinect recording (k4arecorder .mkv)
//   tum:DIR                  a TUM RGB-D benchmark folder
//   oni:FILE                 an OpenNI2 recording (.oni)
// (the last three: common/io/recordings played by OpenRecordingSensors)
//
// Several sources may be given (a list, or comma-separated in one spec).
// Sensor ids are unique across sources: hardware sensors are numbered on
// ("k0", "k1", ... for Kinects and Azure Kinect / TUM recordings, "o0", ...
// for OpenNI2 devices and .oni recordings) past the ids already
// taken, and a take whose ids are taken plays under "p<source>-<n>".
#pragma once

#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "capture_daemon/sensors/backends.h"
#include "capture_daemon/sensors/sensor.h"

namespace reenact::capture {

struct SourceSpec {
  // "playback", "freenect", "openni2", "freenect2", "azure-mkv", "tum", "oni".
  std::string backend;
  std::string argument;  // File or folder, device index/serial/URI, or "all"/"any".
  std::string ToString() const { return backend + ":" + argument; }
};

// Parses specs, splitting each at commas. InvalidArgument naming the spec
// for an unknown backend or a missing argument (playback and the recordings
// need a file or folder; the hardware backends default to "all"/"any").
absl::StatusOr<std::vector<SourceSpec>> ParseSourceSpecs(const std::vector<std::string>& specs);

// Opens every source in order. `options` (fast, loop) apply to all; the id
// fields are set per source. The first failing source's error is returned,
// prefixed with its spec.
absl::StatusOr<SensorList> OpenSources(const std::vector<SourceSpec>& specs,
                                       const SourceOptions& options);

}  // namespace reenact::capture
