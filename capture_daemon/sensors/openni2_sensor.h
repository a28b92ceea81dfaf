// OpenNI2 devices (PrimeSense Carmine, Asus Xtion, Orbbec Astra, recorded
// .oni files): the pieces of the backend worth knowing outside it.
// OpenOpenni2Sensors (backends.h) opens the device.
//
// Streams: depth as PIXEL_FORMAT_DEPTH_1_MM (or DEPTH_100_UM, divided by 10)
// at 640x480 when offered, colour as PIXEL_FORMAT_RGB888 of the same size.
// When the device supports IMAGE_REGISTRATION_DEPTH_TO_COLOR the backend turns
// it on, and SensorInfo.provides_registration reports what the device
// accepted; depth-colour frame sync is requested where supported. Frames are
// paired by their device stamps (microseconds on the device clock, converted
// to ns); host stamps are WallNowNs() at arrival.
//
// Calibration: OpenNI2 reports only fields of view, so intrinsics are the
// pinhole fx = width / (2 tan(hfov / 2)), fy likewise with the vertical field
// of view, principal point at the image centre, no distortion. A registered
// device gets depth intrinsics equal to the colour intrinsics and an identity
// colour_from_depth; an unregistered one a nominal 25 mm baseline along x
// (the PrimeSense reference design's IR-to-RGB spacing).
//
// Lifetime: OpenNI::initialize() runs once per process; OpenNI::shutdown() is
// never called, because it crashes with some drivers (the Dummy device driver
// among them) and the process releases everything at exit anyway.
//
// A stream that stops (wait or read error, or no frame for
// kOpenni2StallTimeoutS) ends with EndCallback(Unavailable).
#pragma once

#include <string>
#include <vector>

#include "absl/status/statusor.h"

namespace reenact::capture {

inline constexpr double kOpenni2StallTimeoutS = 5.0;

// One device OpenNI2 enumerates.
struct Openni2DeviceEntry {
  std::string uri;
  std::string vendor;
  std::string name;
  // "vvvv:pppp" in lower-case hex.
  std::string usb_id;
};

// The devices OpenNI2 sees now. Unavailable when OpenNI2 cannot initialise
// (the message carries OpenNI's extended error).
absl::StatusOr<std::vector<Openni2DeviceEntry>> ListOpenni2Devices();

}  // namespace reenact::capture
