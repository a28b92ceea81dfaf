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

// Kinect v2 through libfreenect2, when it was found at build time.
// `serial`: a serial, or empty/"any".
bool Freenect2Built();
absl::StatusOr<SensorList> OpenFreenect2Sensors(const std::string& serial,
                                                const SourceOptions& options);

}  // namespace reenact::capture
