#include "clients/mirror/facing.h"

#include <algorithm>
#include <cmath>
#include <numbers>

#include "absl/strings/str_cat.h"
#include "clients/mirror/body_parts.h"

namespace reenact::mirror {
namespace {

using body::KinectV2Joint;

constexpr double kDegPerRad = 180.0 / std::numbers::pi;
constexpr double kMinHorizontalLineM = 0.05;

// `v` with its component along unit `up` removed.
Eigen::Vector3d Horizontal(const Eigen::Vector3d& v, const Eigen::Vector3d& up) {
  return v - v.dot(up) * up;
}

// The horizontal line from joint `right` to joint `left`, when long enough.
std::optional<Eigen::Vector3d> HorizontalLeft(const body::SkeletonPose& pose, KinectV2Joint right,
                                              KinectV2Joint left, const Eigen::Vector3d& up) {
  if (!IsJointUsable(pose, right) || !IsJointUsable(pose, left)) return std::nullopt;
  const Eigen::Vector3d line =
      Horizontal(pose.position_m[body::Index(left)] - pose.position_m[body::Index(right)], up);
  if (!(line.norm() >= kMinHorizontalLineM)) return std::nullopt;
  return line.normalized();
}

// Signed angle from horizontal unit `reference` to horizontal unit `forward`
// about unit `up` (right-hand rule), degrees.
double YawAboutDeg(const Eigen::Vector3d& reference, const Eigen::Vector3d& forward,
                   const Eigen::Vector3d& up) {
  return WrapDeg180(std::atan2(reference.cross(forward).dot(up), reference.dot(forward)) *
                    kDegPerRad);
}

std::optional<double> FacingYawDeg(const body::SkeletonPose& pose, const Eigen::Vector3d& up,
                                   const Eigen::Vector3d& reference) {
  if (!(up.norm() > 0.0) || !up.allFinite()) return std::nullopt;
  const Eigen::Vector3d unit_up = up.normalized();
  const Eigen::Vector3d flat_reference = Horizontal(reference, unit_up);
  if (flat_reference.norm() < 1e-6) return std::nullopt;
  const std::optional<Eigen::Vector3d> forward = HorizontalForward(pose, unit_up);
  if (!forward) return std::nullopt;
  return YawAboutDeg(flat_reference.normalized(), *forward, unit_up);
}

// World yaw (0 = +Z, +90 = +X) of a horizontal direction.
double WorldYawDeg(const Eigen::Vector3d& direction_in_world) {
  return std::atan2(direction_in_world.x(), direction_in_world.z()) * kDegPerRad;
}

Eigen::Vector3d WorldDirection(double yaw_deg) {
  const double yaw_rad = yaw_deg / kDegPerRad;
  return {std::sin(yaw_rad), 0.0, std::cos(yaw_rad)};
}

std::optional<Eigen::Vector3d> MeanSpineBase(const std::vector<body::SkeletonPose>& poses) {
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  int count = 0;
  for (const body::SkeletonPose& pose : poses) {
    if (!IsJointUsable(pose, KinectV2Joint::kSpineBase)) continue;
    sum += pose.position_m[body::Index(KinectV2Joint::kSpineBase)];
    ++count;
  }
  if (count == 0) return std::nullopt;
  return sum / count;
}

}  // namespace

double WrapDeg180(double angle_deg) {
  double wrapped = std::fmod(angle_deg, 360.0);
  if (wrapped <= -180.0) wrapped += 360.0;
  if (wrapped > 180.0) wrapped -= 360.0;
  return wrapped;
}

std::optional<double> CircularMeanDeg(const std::vector<double>& angles_deg) {
  double sum_sin = 0.0;
  double sum_cos = 0.0;
  for (double angle_deg : angles_deg) {
    sum_sin += std::sin(angle_deg / kDegPerRad);
    sum_cos += std::cos(angle_deg / kDegPerRad);
  }
  if (angles_deg.empty() || std::hypot(sum_sin, sum_cos) < 1e-9 * angles_deg.size()) {
    return std::nullopt;
  }
  return WrapDeg180(std::atan2(sum_sin, sum_cos) * kDegPerRad);
}

Eigen::Vector3d LevelSensorUp() { return {0.0, -1.0, 0.0}; }

std::optional<Eigen::Vector3d> HorizontalForward(const body::SkeletonPose& pose,
                                                 const Eigen::Vector3d& up) {
  if (!(up.norm() > 0.0) || !up.allFinite()) return std::nullopt;
  const Eigen::Vector3d unit_up = up.normalized();
  std::optional<Eigen::Vector3d> left =
      HorizontalLeft(pose, KinectV2Joint::kShoulderRight, KinectV2Joint::kShoulderLeft, unit_up);
  if (!left) {
    left = HorizontalLeft(pose, KinectV2Joint::kHipRight, KinectV2Joint::kHipLeft, unit_up);
  }
  if (!left) return std::nullopt;
  return left->cross(unit_up).normalized();
}

std::optional<double> FacingYawInSensorDeg(const body::SkeletonPose& pose_in_sensor,
                                           const Eigen::Vector3d& up_in_sensor) {
  return FacingYawDeg(pose_in_sensor, up_in_sensor, Eigen::Vector3d(0.0, 0.0, -1.0));
}

std::optional<double> FacingYawInWorldDeg(const body::SkeletonPose& pose_in_world) {
  return FacingYawDeg(pose_in_world, Eigen::Vector3d::UnitY(), Eigen::Vector3d::UnitZ());
}

body::SkeletonPose TransformPose(const Eigen::Isometry3d& b_from_a,
                                 const body::SkeletonPose& pose_in_a) {
  body::SkeletonPose pose_in_b = pose_in_a;
  for (Eigen::Vector3d& position : pose_in_b.position_m) position = b_from_a * position;
  return pose_in_b;
}

absl::Status SteadinessOptions::Validate() const {
  if (!(tolerance_deg > 0.0 && tolerance_deg < 90.0)) {
    return absl::InvalidArgumentError(
        absl::StrCat("facing tolerance_deg must be in (0, 90): ", tolerance_deg));
  }
  if (!(hold_s >= 0.0 && std::isfinite(hold_s))) {
    return absl::InvalidArgumentError(absl::StrCat("facing hold_s must be >= 0: ", hold_s));
  }
  if (!(smoothing_s >= 0.0 && std::isfinite(smoothing_s))) {
    return absl::InvalidArgumentError(
        absl::StrCat("facing smoothing_s must be >= 0: ", smoothing_s));
  }
  return absl::OkStatus();
}

absl::StatusOr<SteadinessDetector> SteadinessDetector::Create(const SteadinessOptions& options) {
  if (absl::Status valid = options.Validate(); !valid.ok()) return valid;
  return SteadinessDetector(options);
}

void SteadinessDetector::Reset() {
  raw_.clear();
  window_.clear();
  status_ = SteadinessStatus();
}

bool SteadinessDetector::WithinTolerance() const {
  std::vector<double> yaws_deg;
  yaws_deg.reserve(window_.size());
  for (const Sample& sample : window_) yaws_deg.push_back(sample.yaw_deg);
  const std::optional<double> mean_deg = CircularMeanDeg(yaws_deg);
  if (!mean_deg) return false;
  return std::all_of(yaws_deg.begin(), yaws_deg.end(), [&](double yaw_deg) {
    return std::abs(WrapDeg180(yaw_deg - *mean_deg)) <= options_.tolerance_deg;
  });
}

void SteadinessDetector::UpdateStatus() {
  std::vector<double> yaws_deg;
  for (const Sample& sample : window_) yaws_deg.push_back(sample.yaw_deg);
  status_.mean_yaw_deg = CircularMeanDeg(yaws_deg);
  status_.held_s =
      window_.empty() ? 0.0 : (window_.back().stamp_ns - window_.front().stamp_ns) * 1e-9;
  // A nanosecond of slack so that frames stamped exactly hold_s apart count.
  status_.steady = !window_.empty() && status_.held_s + 1e-9 >= options_.hold_s;
}

const SteadinessStatus& SteadinessDetector::Add(int64_t stamp_ns, std::optional<double> yaw_deg) {
  const bool went_back = !raw_.empty() && stamp_ns < raw_.back().stamp_ns;
  if (!yaw_deg || !std::isfinite(*yaw_deg) || went_back) Reset();
  if (!yaw_deg || !std::isfinite(*yaw_deg)) return status_;
  raw_.push_back({stamp_ns, WrapDeg180(*yaw_deg)});
  const int64_t smoothing_ns = static_cast<int64_t>(std::llround(options_.smoothing_s * 1e9));
  while (raw_.size() > 1 && raw_.front().stamp_ns <= stamp_ns - smoothing_ns) raw_.pop_front();
  std::vector<double> recent_deg;
  recent_deg.reserve(raw_.size());
  for (const Sample& sample : raw_) recent_deg.push_back(sample.yaw_deg);
  // Opposite facings that cancel out fall back to the newest one.
  const double smoothed_deg = CircularMeanDeg(recent_deg).value_or(raw_.back().yaw_deg);
  window_.push_back({stamp_ns, smoothed_deg});
  while (window_.size() > 1 && !WithinTolerance()) window_.pop_front();
  // Keep one sample at or before (newest - hold) so the window spans hold_s.
  const int64_t hold_ns = static_cast<int64_t>(std::llround(options_.hold_s * 1e9));
  while (window_.size() > 1 && window_[1].stamp_ns <= window_.back().stamp_ns - hold_ns) {
    window_.pop_front();
  }
  UpdateStatus();
  return status_;
}

absl::StatusOr<TeacherFacing> MeasureTeacherFacing(
    const std::vector<body::SkeletonPose>& teacher_in_world, double fps, double window_s) {
  if (!(fps > 0.0 && std::isfinite(fps))) {
    return absl::InvalidArgumentError(absl::StrCat("teacher fps must be > 0: ", fps));
  }
  const std::optional<Eigen::Vector3d> pivot = MeanSpineBase(teacher_in_world);
  if (!pivot) return absl::InvalidArgumentError("no teacher frame has a usable SpineBase");
  const size_t window_frames =
      window_s > 0.0 ? static_cast<size_t>(std::ceil(window_s * fps)) : teacher_in_world.size();
  std::vector<double> yaws_deg;
  for (size_t f = 0; f < std::min(window_frames, teacher_in_world.size()); ++f) {
    if (std::optional<double> yaw_deg = FacingYawInWorldDeg(teacher_in_world[f])) {
      yaws_deg.push_back(*yaw_deg);
    }
  }
  const std::optional<double> mean_yaw_deg = CircularMeanDeg(yaws_deg);
  if (!mean_yaw_deg) {
    return absl::InvalidArgumentError(
        absl::StrCat("no teacher facing in the first ", window_s, " s (shoulders or hips)"));
  }
  return TeacherFacing{*pivot, *mean_yaw_deg, static_cast<int>(yaws_deg.size())};
}

absl::StatusOr<Eigen::Isometry3d> PlaceVirtualCamera(const Eigen::Vector3d& target_in_world,
                                                     double bearing_yaw_world_deg,
                                                     double distance_m, double height_m) {
  if (!(distance_m > 0.0 && std::isfinite(distance_m)) || !std::isfinite(height_m) ||
      !std::isfinite(bearing_yaw_world_deg) || !target_in_world.allFinite()) {
    return absl::InvalidArgumentError(absl::StrCat("virtual camera needs a finite target, bearing",
                                                   " and height and distance_m > 0, got ",
                                                   distance_m));
  }
  Eigen::Vector3d camera_in_world =
      target_in_world + distance_m * WorldDirection(bearing_yaw_world_deg);
  camera_in_world.y() = height_m;
  const Eigen::Vector3d z_axis = (target_in_world - camera_in_world).normalized();
  const Eigen::Vector3d x_axis = z_axis.cross(Eigen::Vector3d::UnitY()).normalized();
  Eigen::Matrix3d world_from_camera_rotation;
  world_from_camera_rotation.col(0) = x_axis;
  world_from_camera_rotation.col(1) = z_axis.cross(x_axis);  // Down in the image.
  world_from_camera_rotation.col(2) = z_axis;
  Eigen::Isometry3d world_from_camera = Eigen::Isometry3d::Identity();
  world_from_camera.linear() = world_from_camera_rotation;
  world_from_camera.translation() = camera_in_world;
  return world_from_camera;
}

absl::StatusOr<TeacherTurn> ComputeTeacherTurn(const TeacherFacing& teacher, double view_yaw_deg,
                                               const Eigen::Isometry3d& world_from_virtual_camera) {
  const Eigen::Vector3d toward_camera = -world_from_virtual_camera.linear().col(2);
  const Eigen::Vector3d flat(toward_camera.x(), 0.0, toward_camera.z());
  if (!std::isfinite(view_yaw_deg) || !(flat.norm() > 1e-6)) {
    return absl::InvalidArgumentError(
        "teacher turn needs a finite view yaw and a virtual camera that does not look straight "
        "up or down");
  }
  TeacherTurn turn;
  turn.view_yaw_deg = WrapDeg180(view_yaw_deg);
  turn.turn_yaw_deg = WrapDeg180(view_yaw_deg + WorldYawDeg(flat) - teacher.facing_yaw_world_deg);
  const Eigen::AngleAxisd rotation(turn.turn_yaw_deg / kDegPerRad, Eigen::Vector3d::UnitY());
  turn.turned_from_original = Eigen::Translation3d(teacher.pivot_in_world) * rotation *
                              Eigen::Translation3d(-teacher.pivot_in_world);
  return turn;
}

}  // namespace reenact::mirror
