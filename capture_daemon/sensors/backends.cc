#include "capture_daemon/sensors/backends.h"

namespace reenact::capture {

// Placeholders until the backends land; each says what is missing.
absl::StatusOr<SensorList> OpenFreenectSensors(const std::string&, const SourceOptions&) {
  return absl::UnimplementedError("freenect backend not built yet");
}
absl::StatusOr<SensorList> OpenOpenni2Sensors(const std::string&, const SourceOptions&) {
  return absl::UnimplementedError("openni2 backend not built yet");
}
bool Freenect2Built() { return false; }
absl::StatusOr<SensorList> OpenFreenect2Sensors(const std::string&, const SourceOptions&) {
  return absl::UnimplementedError("reenactd was built without libfreenect2");
}

}  // namespace reenact::capture
