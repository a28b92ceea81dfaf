#include "clients/mirror/learner_source.h"

#include <cmath>
#include <limits>

#include "absl/strings/str_cat.h"
#include "common/base/status_macros.h"
#include "common/io/proto_convert.h"

namespace reenact::mirror {
namespace {

// Largest angle between the calibration's up and a level sensor's up for
// the calibration's world to count as gravity-aligned, degrees.
constexpr double kMaxWorldTiltDeg = 45.0;

// The learner skeleton of one body, and how many joints are usable.
struct Candidate {
  body::SkeletonPose pose;
  std::array<bool, body::kNumKinectV2Joints> seen{};
  int usable = 0;
  double depth_m = std::numeric_limits<double>::infinity();
};

Candidate ConvertSkeleton(const v1::Skeleton& skeleton, const Rigid3d& color_from_depth) {
  Candidate candidate;
  for (auto& p : candidate.pose.position_m) p = Eigen::Vector3d::Zero();
  for (int i = 0; i < skeleton.joints_size(); ++i) {
    const v1::Joint& joint = skeleton.joints(i);
    std::optional<body::KinectV2Joint> id = body::KinectV2JointFromName(joint.name());
    if (!id && joint.name().empty() && i < body::kNumKinectV2Joints) {
      id = static_cast<body::KinectV2Joint>(i);
    }
    if (!id || joint.tracking_state() == v1::TRACKING_STATE_NOT_TRACKED) continue;
    const Eigen::Vector3d in_depth = FromProto(joint.position_in_depth_m());
    if (!in_depth.allFinite()) continue;
    const int j = body::Index(*id);
    candidate.pose.position_m[j] = color_from_depth * in_depth;
    if (!candidate.pose.valid[j]) ++candidate.usable;
    candidate.pose.valid[j] = true;
    candidate.seen[j] = joint.tracking_state() == v1::TRACKING_STATE_TRACKED;
  }
  const int base = body::Index(body::KinectV2Joint::kSpineBase);
  if (candidate.pose.valid[base]) candidate.depth_m = candidate.pose.position_m[base].z();
  return candidate;
}

}  // namespace

namespace {
bool HasColorCamera(const v1::SensorCalibration& calibration) {
  return calibration.color_intrinsics().width_px() > 0 ||
         calibration.color_intrinsics().height_px() > 0;
}
}  // namespace

absl::StatusOr<Rigid3d> LearnerColorFromDepth(const v1::SensorCalibration& calibration) {
  if (!HasColorCamera(calibration)) return Rigid3d();
  return FromProto(calibration.color_from_depth());
}

absl::StatusOr<LearnerSensor> LearnerSensorFromCalibration(
    const v1::SensorCalibration& calibration) {
  LearnerSensor sensor;
  sensor.sensor_id = calibration.sensor_id();
  ASSIGN_OR_RETURN(sensor.color_intrinsics,
                   FromProto(HasColorCamera(calibration) ? calibration.color_intrinsics()
                                                         : calibration.depth_intrinsics()));
  if (calibration.nominal_fps() > 0 && std::isfinite(calibration.nominal_fps())) {
    sensor.nominal_fps = calibration.nominal_fps();
  }
  ASSIGN_OR_RETURN(const Rigid3d color_from_depth, LearnerColorFromDepth(calibration));
  ASSIGN_OR_RETURN(const Rigid3d world_from_depth, FromProto(calibration.world_from_depth()));
  const Rigid3d color_from_world = color_from_depth * world_from_depth.Inverse();
  const Eigen::Vector3d up = color_from_world.rotation * Eigen::Vector3d::UnitY();
  const Eigen::Vector3d level_up(0.0, -1.0, 0.0);
  if (up.allFinite() && up.norm() > 0.5 &&
      up.normalized().dot(level_up) >= std::cos(kMaxWorldTiltDeg * M_PI / 180.0)) {
    sensor.up_in_color = up.normalized();
  } else {
    sensor.up_in_color = level_up;
  }
  return sensor;
}

std::optional<LearnerSkeleton> ChooseLearnerSkeleton(
    const std::vector<const v1::Skeleton*>& skeletons, const Rigid3d& color_from_depth) {
  std::optional<Candidate> best;
  int people = 0;
  for (const v1::Skeleton* skeleton : skeletons) {
    Candidate candidate = ConvertSkeleton(*skeleton, color_from_depth);
    if (candidate.usable == 0) continue;
    ++people;
    if (!best || candidate.usable > best->usable ||
        (candidate.usable == best->usable && candidate.depth_m < best->depth_m)) {
      best = std::move(candidate);
    }
  }
  if (!best) return std::nullopt;
  return LearnerSkeleton{best->pose, best->seen, people};
}

std::optional<body::SkeletonPose> LearnerSkeletonInColor(
    const std::vector<const v1::Skeleton*>& skeletons, const Rigid3d& color_from_depth) {
  std::optional<LearnerSkeleton> chosen = ChooseLearnerSkeleton(skeletons, color_from_depth);
  if (!chosen) return std::nullopt;
  return chosen->pose;
}

int64_t ExposureStampNs(int64_t device_stamp_ns, int64_t host_stamp_ns, int64_t clock_offset_ns) {
  return device_stamp_ns != 0 ? device_stamp_ns + clock_offset_ns : host_stamp_ns;
}

}  // namespace reenact::mirror
