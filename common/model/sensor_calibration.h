// One RGB-D sensor's calibration as plain values: what SensorCalibration
// (sensor.proto) carries, in the core types of common/geometry. Takes and
// reenactments both hold them; common/io converts from and to the message.
#pragma once

#include <cstdint>
#include <string>

#include "common/geometry/camera.h"
#include "common/geometry/transforms.h"

namespace reenact {

struct SensorCalibration {
  std::string sensor_id;  // [A-Za-z0-9_-], unique within a take.
  std::string model;      // e.g. "kinect-v2", "azure-kinect", "synthetic".
  std::string serial;
  CameraIntrinsics depth_intrinsics;  // Pixels of the depth image.
  CameraIntrinsics color_intrinsics;  // Pixels of the full-size colour image.
  Rigid3d color_from_depth;           // Metres.
  Rigid3d world_from_depth;           // Metres.
  int64_t clock_offset_ns = 0;        // Device clock -> host clock.
  double depth_scale_m_per_unit = 0.0;
  double nominal_fps = 0.0;
  std::string world_anchor;  // How world_from_depth was found; empty: unknown.
  double world_anchor_rms_px = 0.0;

  // world_from_depth composed with the inverse of color_from_depth.
  Rigid3d WorldFromColor() const { return world_from_depth * color_from_depth.Inverse(); }
};

}  // namespace reenact
