// Kinect v1 through libfreenect (OpenKinect): the pieces of the backend that
// are worth knowing outside it. OpenFreenectSensors (backends.h) opens the
// devices; each FreenectSensor runs its own libfreenect context and event
// thread.
//
// Depth: FREENECT_DEPTH_MM (millimetres, in the depth camera's own pixel
// grid) when the library offers that mode. libfreenect's fakenect playback
// library offers only the raw 11-bit disparity mode; raw values are then
// converted with KinectV1RawToMm.
//
// Colour: 640x480 RGB (FREENECT_VIDEO_RGB, medium resolution). Each depth
// frame is paired with the colour frame whose device stamp is within half a
// frame period (DepthColorPairer).
//
// Stamps: host_stamp_ns is WallNowNs() when libfreenect hands the depth frame
// over (the daemon's host clock, common/base/time.h). device_stamp_ns comes
// from the 32-bit timestamp libfreenect copies from the camera's packet
// headers: a counter of the camera's 60 MHz clock (OpenKinect protocol notes;
// libfreenect issue #681 and pull request #465). It wraps every 2^32 / 60e6 =
// 71.6 s; KinectV1Clock unwraps it and converts ticks to nanoseconds
// (ns = ticks * 50 / 3).
//
// Calibration: the camera does not report its intrinsics through libfreenect,
// so SensorInfo carries KinectV1DefaultCalibration, the widely republished
// calibration of a Kinect v1 by Nicolas Burrus ("Kinect calibration",
// nicolas.burrus.name, 2011). Devices differ by a few pixels; calibrate a
// device for accurate registration.
//
// A stream that stops (freenect_process_events fails, the device was
// unplugged, a fakenect recording ended, or no depth frame arrived for
// kFreenectStallTimeoutS) ends with EndCallback(Unavailable).
#pragma once

#include <cstdint>
#include <string>

#include "reenact/v1/sensor.pb.h"

namespace reenact::capture {

// libfreenect's "no measurement" raw value.
inline constexpr uint16_t kKinectV1RawNoValue = 2047;
// Seconds without a depth frame after which a stream counts as stopped.
inline constexpr double kFreenectStallTimeoutS = 5.0;

// Converts a raw 11-bit Kinect v1 disparity value to depth in millimetres
// along z with the model fitted by N. Burrus (2011):
//   z_m = 1 / (3.3309495161 - 0.0030711016 * raw).
// 0 (no measurement) for raw >= 2047 and for values the model maps outside
// 0.3..10 m (beyond 10 m the model's pole at raw ~1084.6 makes depth
// meaningless; FREENECT_DEPTH_MM_MAX_VALUE is 10000 mm as well).
uint16_t KinectV1RawToMm(uint16_t raw);

// Unwraps the Kinect v1's 32-bit 60 MHz device counter into nanoseconds
// since the first stamp seen plus the first stamp's own value, so stamps keep
// increasing across wraps. Assumes consecutive stamps are less than half a
// wrap (35.8 s) apart.
class KinectV1Clock {
 public:
  static constexpr int64_t kTicksPerSecond = 60'000'000;
  int64_t ToNs(uint32_t ticks);

 private:
  bool started_ = false;
  uint32_t last_ticks_ = 0;
  int64_t unwrapped_ticks_ = 0;
};

// Kinect v1 default calibration (N. Burrus, 2011; see the file comment):
// depth (IR) camera 640x480 fx 594.214 fy 591.041 cx 339.308 cy 242.739,
// k1 -0.263865 k2 0.999668 p1 -0.000763 p2 0.005035 k3 -1.305363;
// colour camera 640x480 fx 529.215 fy 525.564 cx 328.943 cy 267.481,
// k1 0.264516 k2 -0.839907 p1 -0.001992 p2 0.001437 k3 0.911925;
// colour_from_depth: the published R and T (point_rgb = R point_depth + T),
// T = (19.99, -0.74, -10.92) mm. world_from_depth is the identity (the daemon
// has not placed the sensor), clock_offset_ns 0 until frames arrive,
// depth_scale 0.001, 30 fps.
v1::SensorCalibration KinectV1DefaultCalibration(const std::string& sensor_id,
                                                 const std::string& serial);

}  // namespace reenact::capture
