// Hardware backends of reenactd. Each opens the devices it is asked for and
// returns one Sensor per device. "No device" is NotFound with a message that
// says what was looked for; a backend that was not built is Unimplemented.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "capture_daemon/sensors/sensor.h"

namespace reenact::capture {

using SensorList = std::vector<std::unique_ptr<Sensor>>;

// Kinect v1 through libfreenect. `device`: an index ("0"), a serial, or
// empty/"all" for every connected Kinect. Without hardware, libfreenect's own
// fakenect library plays a recording (LD_LIBRARY_PATH=<libdir>/fakenect,
// FAKENECT_PATH=<recording folder>).
absl::StatusOr<SensorList> OpenFreenectSensors(const std::string& device,
                                               const SourceOptions& options);

// OpenNI2 devices (PrimeSense, Asus Xtion, Orbbec, Kinect through a driver).
// `uri`: a device URI, or empty/"any" for the first device.
absl::StatusOr<SensorList> OpenOpenni2Sensors(const std::string& uri, const SourceOptions& options);

// Recordings made by other tools played as live sensors
// (common/io/recordings): `format` "azure-mkv" (an Azure Kinect .mkv), "tum"
// (a TUM RGB-D folder) or "oni" (an OpenNI2 recording); one sensor, paced as
// recorded unless options.fast, starting over with options.loop, ending with
// OK at the end of the recording. Ids: options.id_prefix (default "k", "o"
// for .oni) + first_index. NotFound for a missing path; the reader's errors
// for a recording it cannot read.
absl::StatusOr<SensorList> OpenRecordingSensors(const std::string& format, const std::string& path,
                                                const SourceOptions& options);

// Kinect v2 through libfreenect2, when it was found at build time.
// `serial`: a serial, or empty/"any".
bool Freenect2Built();
absl::StatusOr<SensorList> OpenFreenect2Sensors(const std::string& serial,
                                                const SourceOptions& options);

}  // namespace reenact::capture
