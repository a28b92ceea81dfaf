// Virtual Kinect v2 sensors around the actor. With two sensors they face each
// other across the actor, about 2.5 m from it, as in the thesis's capture
// setup (ch. 4: two Kinect v2 on opposite sides of the teacher).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "common/geometry/camera.h"
#include "common/geometry/transforms.h"

namespace reenact::synth {

struct SensorRigOptions {
  int num_sensors = 2;             // Sensors evenly spaced on a circle round the actor.
  double distance_m = 2.5;         // Horizontal distance of each sensor from the actor.
  double height_m = 1.0;           // Height of the depth camera above the floor.
  double pitch_down_deg = 5.0;     // Downward tilt of the sensors.
  double first_azimuth_deg = 0.0;  // 0: the first sensor stands on +Z, seeing the front.
  int color_width = 1920;          // Colour resolution (intrinsics scale with it).
  int color_height = 1080;
  double fps = 30.0;
  uint64_t seed = 1;  // Draws each sensor's clock offset.

  absl::Status Validate() const;
};

struct VirtualSensor {
  std::string sensor_id;  // "k0", "k1", ...
  CameraIntrinsics depth_intrinsics;
  CameraIntrinsics color_intrinsics;
  Rigid3d world_from_depth;
  Rigid3d color_from_depth;
  // Device clock = host clock - clock_offset_ns (each sensor has its own).
  int64_t clock_offset_ns = 0;
  // Sub-frame phase of the sensor's exposures relative to the take clock.
  int64_t phase_ns = 0;

  Rigid3d world_from_color() const { return world_from_depth * color_from_depth.Inverse(); }
};

absl::StatusOr<std::vector<VirtualSensor>> MakeSensorRig(const SensorRigOptions& options);

}  // namespace reenact::synth
