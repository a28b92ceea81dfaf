#include "common/synth/sensor_rig.h"

#include <cmath>
#include <random>

#include "absl/strings/str_cat.h"

namespace reenact::synth {

absl::Status SensorRigOptions::Validate() const {
  if (num_sensors < 1 || num_sensors > 8) {
    return absl::InvalidArgumentError("sensor rig: num_sensors must be 1..8");
  }
  if (!(distance_m > 0.5 && distance_m < 4.5)) {
    return absl::InvalidArgumentError("sensor rig: distance_m must be within the 0.5-4.5 m range");
  }
  if (!(height_m > 0 && height_m < 3)) {
    return absl::InvalidArgumentError("sensor rig: height_m must be in (0, 3)");
  }
  if (color_width < 16 || color_height < 16 || !(fps > 0)) {
    return absl::InvalidArgumentError("sensor rig: colour size >= 16 px and fps > 0 required");
  }
  return absl::OkStatus();
}

absl::StatusOr<std::vector<VirtualSensor>> MakeSensorRig(const SensorRigOptions& options) {
  if (auto status = options.Validate(); !status.ok()) return status;
  std::mt19937_64 rng(options.seed);
  std::uniform_int_distribution<int64_t> offset_ms(-5000, 5000);
  std::uniform_real_distribution<double> phase(0.0, 0.3);
  auto color =
      ScaledIntrinsics(KinectV2ColorIntrinsics(), options.color_width, options.color_height);
  if (!color.ok()) return color.status();
  std::vector<VirtualSensor> sensors;
  for (int i = 0; i < options.num_sensors; ++i) {
    VirtualSensor s;
    s.sensor_id = absl::StrCat("k", i);
    s.depth_intrinsics = KinectV2DepthIntrinsics();
    s.color_intrinsics = *color;
    s.color_from_depth = KinectV2ColorFromDepth();
    const double azimuth =
        (options.first_azimuth_deg + 360.0 * i / options.num_sensors) * M_PI / 180.0;
    const Eigen::Vector3d position(options.distance_m * std::sin(azimuth), options.height_m,
                                   options.distance_m * std::cos(azimuth));
    // Camera axes (OpenCV): z towards the actor's vertical axis, tilted down;
    // y down; x = y cross z.
    const double pitch = options.pitch_down_deg * M_PI / 180.0;
    const Eigen::Vector3d toward(-std::sin(azimuth), 0.0, -std::cos(azimuth));
    const Eigen::Vector3d z =
        (std::cos(pitch) * toward - std::sin(pitch) * Eigen::Vector3d::UnitY()).normalized();
    const Eigen::Vector3d x = (-Eigen::Vector3d::UnitY()).cross(z).normalized();
    const Eigen::Vector3d y = z.cross(x);
    Eigen::Matrix3d world_from_camera;
    world_from_camera << x, y, z;
    s.world_from_depth = Rigid3d(Eigen::Quaterniond(world_from_camera), position);
    s.clock_offset_ns = offset_ms(rng) * 1'000'000;
    s.phase_ns = static_cast<int64_t>(phase(rng) * 1e9 / options.fps);
    sensors.push_back(s);
  }
  return sensors;
}

}  // namespace reenact::synth
