#include "capture_daemon/sensors/source_backends.h"

#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "capture_daemon/sensors/playback_sensor.h"

namespace reenact::capture {
namespace {

bool Always() { return true; }

absl::StatusOr<SensorList> OpenAzureMkv(const std::string& path, const SourceOptions& options) {
  return OpenRecordingSensors("azure-mkv", path, options);
}
absl::StatusOr<SensorList> OpenTum(const std::string& path, const SourceOptions& options) {
  return OpenRecordingSensors("tum", path, options);
}
absl::StatusOr<SensorList> OpenOni(const std::string& path, const SourceOptions& options) {
  return OpenRecordingSensors("oni", path, options);
}

// Kinects and the Kinect-class recordings (Azure Kinect, TUM's Kinect v1)
// are "k0", "k1", ...; OpenNI2 devices and recordings "o0", ....
constexpr SourceBackend kBackends[] = {
    {"playback", "playback:FILE", "an MCAP take, played as live sensors", "", "a file", "", false,
     &Always, &OpenPlaybackSensors},
    {"freenect", "freenect:0|SERIAL|all", "Kinect v1 through libfreenect", "all", "", "k", true,
     &Always, &OpenFreenectSensors},
    {"openni2", "openni2:any|URI", "an OpenNI2 device (PrimeSense, Asus Xtion, Orbbec)", "any", "",
     "o", true, &Always, &OpenOpenni2Sensors},
    {"freenect2", "freenect2:any|SERIAL", "Kinect v2 through libfreenect2 (when built with it)",
     "any", "", "k", true, &Freenect2Built, &OpenFreenect2Sensors},
    {"azure-mkv", "azure-mkv:FILE", "an Azure Kinect recording (k4arecorder .mkv)", "", "a file",
     "k", false, &Always, &OpenAzureMkv},
    {"tum", "tum:DIR", "a TUM RGB-D benchmark folder", "", "a folder", "k", false, &Always,
     &OpenTum},
    {"oni", "oni:FILE", "an OpenNI2 recording (.oni)", "", "a file", "o", false, &Always, &OpenOni},
};

}  // namespace

absl::Span<const SourceBackend> SourceBackends() { return absl::MakeConstSpan(kBackends); }

const SourceBackend* FindSourceBackend(absl::string_view name) {
  for (const SourceBackend& backend : kBackends) {
    if (backend.name == name) return &backend;
  }
  return nullptr;
}

std::string SourceSyntaxList() {
  return absl::StrJoin(kBackends, " | ", [](std::string* out, const SourceBackend& backend) {
    absl::StrAppend(out, backend.syntax);
  });
}

}  // namespace reenact::capture
