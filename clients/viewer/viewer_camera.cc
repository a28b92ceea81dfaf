#include "clients/viewer/viewer_camera.h"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <numbers>
#include <sstream>

#include <Eigen/Geometry>
#include <nlohmann/json.hpp>

#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_split.h"
#include "clients/view/reenactment_renderer.h"
#include "common/base/status_macros.h"

namespace reenact::viewer {
namespace {

constexpr double kDegToRad = std::numbers::pi / 180.0;

absl::Status CheckSize(int width, int height) {
  if (width < 16 || height < 16 || width > 8192 || height > 8192) {
    return absl::InvalidArgumentError(
        absl::StrCat("image size must be 16..8192 pixels, got ", width, "x", height));
  }
  return absl::OkStatus();
}

// One key of a camera path file, after defaults.
struct PathKey {
  int step = 0;
  double frame = 0;
  Eigen::Vector3d eye = Eigen::Vector3d::Zero();
  Eigen::Vector3d target = Eigen::Vector3d::Zero();
  double fov_deg = 50.0;
};

absl::StatusOr<Eigen::Vector3d> JsonVector(const nlohmann::json& key, const char* name, int index) {
  if (!key.contains(name) || !key[name].is_array() || key[name].size() != 3) {
    return absl::InvalidArgumentError(
        absl::StrCat("camera path key ", index, ": \"", name, "\" must be [x, y, z] in metres"));
  }
  Eigen::Vector3d v;
  for (int i = 0; i < 3; ++i) {
    if (!key[name][i].is_number()) {
      return absl::InvalidArgumentError(
          absl::StrCat("camera path key ", index, ": \"", name, "\" holds a non-number"));
    }
    v[i] = key[name][i].get<double>();
  }
  if (!v.allFinite()) {
    return absl::InvalidArgumentError(
        absl::StrCat("camera path key ", index, ": \"", name, "\" is not finite"));
  }
  return v;
}

absl::StatusOr<std::vector<PathKey>> ParseKeys(const nlohmann::json& root, int frame_count,
                                               const Eigen::Vector3d& origin) {
  const double default_fov = root.value("fov_deg", 50.0);
  if (!root.contains("keys") || !root["keys"].is_array() || root["keys"].empty()) {
    return absl::InvalidArgumentError("camera path: \"keys\" must be a non-empty list");
  }
  std::vector<PathKey> keys;
  for (const nlohmann::json& item : root["keys"]) {
    const int index = static_cast<int>(keys.size());
    if (!item.is_object()) {
      return absl::InvalidArgumentError(absl::StrCat("camera path key ", index, ": not an object"));
    }
    PathKey key;
    key.step = item.value("step", index == 0 ? 0 : keys.back().step + 1);
    if (index > 0 && key.step <= keys.back().step) {
      return absl::InvalidArgumentError(
          absl::StrCat("camera path key ", index, ": steps must increase"));
    }
    key.frame = item.contains("frame")
                    ? item["frame"].get<double>()
                    : (index == 0 ? 0.0 : keys.back().frame + (key.step - keys.back().step));
    if (!(key.frame >= 0) || key.frame > frame_count - 1) {
      return absl::InvalidArgumentError(absl::StrCat("camera path key ", index, ": frame ",
                                                     key.frame, " is outside the reenactment's ",
                                                     frame_count, " instants"));
    }
    ASSIGN_OR_RETURN(key.eye, JsonVector(item, "eye", index));
    ASSIGN_OR_RETURN(key.target, JsonVector(item, "target", index));
    key.eye += origin;
    key.target += origin;
    key.fov_deg = item.value("fov_deg", default_fov);
    keys.push_back(key);
  }
  return keys;
}

absl::StatusOr<std::string> ReadText(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return absl::InvalidArgumentError(absl::StrCat(path, ": cannot read the camera path"));
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

absl::StatusOr<std::vector<Shot>> SensorShots(const std::string& kind, const std::string& arg,
                                              const Reenactment& data, int width, int height,
                                              int first_frame, int end_frame) {
  if (static_cast<int>(data.info.sensors.size()) == 0) {
    return absl::FailedPreconditionError("the reenactment names no sensor to place a camera by");
  }
  int sensor = 0;
  double angle_deg = 0.0;
  bool full_turn = false;
  if (kind == "sensor") {
    if (!absl::SimpleAtoi(arg, &sensor) || sensor < 0 ||
        sensor >= static_cast<int>(data.info.sensors.size())) {
      return absl::InvalidArgumentError(absl::StrCat(
          "--camera sensor:N: N must be 0..", static_cast<int>(data.info.sensors.size()) - 1));
    }
  } else if (arg.empty()) {
    full_turn = true;
  } else if (!absl::SimpleAtod(arg, &angle_deg) || !std::isfinite(angle_deg)) {
    return absl::InvalidArgumentError(absl::StrCat("--camera orbit:DEG: bad angle '", arg, "'"));
  }
  ASSIGN_OR_RETURN(render::RenderCamera base,
                   view::SensorRenderCamera(data.info.sensors[sensor], width, height));
  Eigen::Vector3d pivot = Eigen::Vector3d::Zero();
  if (kind == "orbit") {
    absl::StatusOr<Eigen::Vector3d> actor = view::MeanActorPosition(data);
    if (!actor.ok()) return absl::FailedPreconditionError(actor.status().message());
    pivot = *actor;
  }
  std::vector<Shot> shots;
  for (int f = first_frame; f < end_frame; ++f) {
    const double angle =
        full_turn ? 360.0 * (f - first_frame) / (end_frame - first_frame) : angle_deg;
    shots.push_back({f, kind == "orbit" ? view::OrbitCamera(base, pivot, angle) : base});
  }
  return shots;
}

}  // namespace

absl::StatusOr<render::RenderCamera> LookAtCamera(const Eigen::Vector3d& eye_in_world,
                                                  const Eigen::Vector3d& target_in_world,
                                                  double horizontal_fov_deg, int width, int height,
                                                  const Eigen::Vector3d& up_in_world) {
  RETURN_IF_ERROR(CheckSize(width, height));
  if (!eye_in_world.allFinite() || !target_in_world.allFinite() || !up_in_world.allFinite()) {
    return absl::InvalidArgumentError("camera eye, target and up must be finite");
  }
  if (!(horizontal_fov_deg >= 1.0 && horizontal_fov_deg <= 170.0)) {
    return absl::InvalidArgumentError(
        absl::StrCat("field of view must be 1..170 degrees, got ", horizontal_fov_deg));
  }
  const Eigen::Vector3d forward = target_in_world - eye_in_world;
  if (forward.norm() < 1e-6 || up_in_world.norm() < 1e-9) {
    return absl::InvalidArgumentError("camera eye and target coincide (or up is zero)");
  }
  const Eigen::Vector3d z = forward.normalized();
  // Image rows go down: y is -up made orthogonal to the view direction.
  Eigen::Vector3d y = -up_in_world.normalized();
  y -= y.dot(z) * z;
  if (y.norm() < 1e-6) return absl::InvalidArgumentError("camera looks along the up direction");
  y.normalize();
  const Eigen::Vector3d x = y.cross(z);
  render::RenderCamera camera;
  camera.width = width;
  camera.height = height;
  camera.fx = 0.5 * width / std::tan(0.5 * horizontal_fov_deg * kDegToRad);
  camera.fy = camera.fx;
  camera.cx = 0.5 * width;
  camera.cy = 0.5 * height;
  Eigen::Matrix3d rotation;
  rotation << x, y, z;
  camera.world_from_camera.linear() = rotation;
  camera.world_from_camera.translation() = eye_in_world;
  camera.near_m = 0.05;
  camera.far_m = 50.0;
  return camera;
}

absl::StatusOr<std::vector<Shot>> ParseCameraPath(const std::string& json_text, int frame_count,
                                                  int width, int height,
                                                  const Eigen::Vector3d& actor_in_world) {
  if (frame_count <= 0) return absl::InvalidArgumentError("the reenactment has no instant");
  const nlohmann::json root = nlohmann::json::parse(json_text, nullptr, false);
  if (root.is_discarded() || !root.is_object()) {
    return absl::InvalidArgumentError("camera path: not a JSON object");
  }
  const std::string origin = root.value("origin", "world");
  if (origin != "world" && origin != "actor") {
    return absl::InvalidArgumentError("camera path: \"origin\" must be \"world\" or \"actor\"");
  }
  std::vector<PathKey> keys;
  try {
    ASSIGN_OR_RETURN(keys, ParseKeys(root, frame_count,
                                     origin == "actor" ? actor_in_world : Eigen::Vector3d::Zero()));
  } catch (const nlohmann::json::exception& e) {
    return absl::InvalidArgumentError(absl::StrCat("camera path: ", e.what()));
  }
  std::vector<Shot> shots;
  for (size_t k = 0; k < keys.size(); ++k) {
    const PathKey& a = keys[k];
    const PathKey& b = keys[std::min(k + 1, keys.size() - 1)];
    const int steps = k + 1 < keys.size() ? b.step - a.step : 1;
    for (int s = 0; s < steps; ++s) {
      const double t = k + 1 < keys.size() ? static_cast<double>(s) / steps : 0.0;
      ASSIGN_OR_RETURN(
          render::RenderCamera camera,
          LookAtCamera(a.eye + t * (b.eye - a.eye), a.target + t * (b.target - a.target),
                       a.fov_deg + t * (b.fov_deg - a.fov_deg), width, height));
      const int frame = static_cast<int>(std::lround(a.frame + t * (b.frame - a.frame)));
      shots.push_back({std::clamp(frame, 0, frame_count - 1), camera});
    }
  }
  return shots;
}

absl::StatusOr<std::vector<Shot>> CameraShots(const std::string& spec, const Reenactment& data,
                                              int width, int height, int first_frame,
                                              int end_frame) {
  RETURN_IF_ERROR(CheckSize(width, height));
  const std::vector<std::string> pieces = absl::StrSplit(spec, absl::MaxSplits(':', 1));
  const std::string& kind = pieces[0];
  const std::string arg = pieces.size() > 1 ? pieces[1] : "";
  const int frame_count = static_cast<int>(data.frames.size());
  if (kind == "path") {
    if (arg.empty()) return absl::InvalidArgumentError("--camera path:FILE needs a file");
    ASSIGN_OR_RETURN(std::string text, ReadText(arg));
    Eigen::Vector3d actor = Eigen::Vector3d::Zero();
    if (text.find("\"actor\"") != std::string::npos) {
      absl::StatusOr<Eigen::Vector3d> mean = view::MeanActorPosition(data);
      if (!mean.ok()) return absl::FailedPreconditionError(mean.status().message());
      actor = *mean;
    }
    return ParseCameraPath(text, frame_count, width, height, actor);
  }
  if ((kind != "orbit" && kind != "sensor") || (kind == "sensor" && pieces.size() != 2)) {
    return absl::InvalidArgumentError(absl::StrCat(
        "--camera: expected orbit, orbit:DEG, sensor:N or path:FILE, got '", spec, "'"));
  }
  if (first_frame < 0 || end_frame > frame_count || first_frame >= end_frame) {
    return absl::InvalidArgumentError(
        absl::StrCat("instants ", first_frame, "..", end_frame, " select none of ", frame_count));
  }
  return SensorShots(kind, arg, data, width, height, first_frame, end_frame);
}

OrbitController OrbitController::FromCamera(const render::RenderCamera& camera,
                                            const Eigen::Vector3d& target_in_world) {
  OrbitController orbit;
  orbit.target_in_world_ = target_in_world;
  const Eigen::Vector3d offset = camera.world_from_camera.translation() - target_in_world;
  orbit.distance_m_ = std::clamp(offset.norm(), 0.3, 30.0);
  if (offset.norm() > 1e-6) {
    orbit.pitch_deg_ = std::asin(std::clamp(offset.y() / offset.norm(), -1.0, 1.0)) / kDegToRad;
    orbit.yaw_deg_ = std::atan2(offset.x(), offset.z()) / kDegToRad;
  }
  orbit.pitch_deg_ = std::clamp(orbit.pitch_deg_, -85.0, 85.0);
  if (camera.fx > 0 && camera.width > 0) {
    orbit.fov_deg_ = 2.0 * std::atan(0.5 * camera.width / camera.fx) / kDegToRad;
  }
  orbit.initial_yaw_deg_ = orbit.yaw_deg_;
  orbit.initial_pitch_deg_ = orbit.pitch_deg_;
  orbit.initial_distance_m_ = orbit.distance_m_;
  return orbit;
}

void OrbitController::Rotate(double dx_px, double dy_px, double degrees_per_pixel) {
  yaw_deg_ = std::remainder(yaw_deg_ - dx_px * degrees_per_pixel, 360.0);
  pitch_deg_ = std::clamp(pitch_deg_ + dy_px * degrees_per_pixel, -85.0, 85.0);
}

void OrbitController::Zoom(double steps) {
  distance_m_ = std::clamp(distance_m_ * std::pow(0.9, steps), 0.3, 30.0);
}

void OrbitController::Reset() {
  yaw_deg_ = initial_yaw_deg_;
  pitch_deg_ = initial_pitch_deg_;
  distance_m_ = initial_distance_m_;
}

absl::StatusOr<render::RenderCamera> OrbitController::Camera(int width, int height) const {
  const double yaw = yaw_deg_ * kDegToRad;
  const double pitch = pitch_deg_ * kDegToRad;
  const Eigen::Vector3d direction(std::cos(pitch) * std::sin(yaw), std::sin(pitch),
                                  std::cos(pitch) * std::cos(yaw));
  return LookAtCamera(target_in_world_ + distance_m_ * direction, target_in_world_, fov_deg_, width,
                      height);
}

}  // namespace reenact::viewer
