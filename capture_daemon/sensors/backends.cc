#include "capture_daemon/sensors/backends.h"

#include "absl/strings/str_cat.h"

// Kinect v1 (freenect_sensor.cc) and OpenNI2 (openni2_sensor.cc) are always
// built. Kinect v2 needs libfreenect2, which Debian 12 does not ship: with it,
// freenect2_sensor.cc defines the functions below instead.
#ifndef REENACT_HAVE_FREENECT2
namespace reenact::capture {

bool Freenect2Built() { return false; }

absl::StatusOr<SensorList> OpenFreenect2Sensors(const std::string& serial, const SourceOptions&) {
  return absl::UnimplementedError(absl::StrCat(
      "Kinect v2 (", serial.empty() ? "any" : serial,
      ") needs libfreenect2, and reenactd was built without libfreenect2 (install it and rebuild; "
      "CMake looks for the pkg-config module freenect2)"));
}

}  // namespace reenact::capture
#endif
