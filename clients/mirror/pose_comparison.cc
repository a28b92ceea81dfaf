#include "clients/mirror/pose_comparison.h"

#include <algorithm>
#include <cmath>
#include <numbers>

#include <Eigen/Geometry>

#include "absl/strings/str_cat.h"

namespace reenact::mirror {
namespace {

using body::KinectV2Joint;

constexpr double kDegPerRad = 180.0 / std::numbers::pi;

// The part a joint beyond the compared parts hangs from.
std::optional<BodyPart> HangsFrom(KinectV2Joint joint) {
  switch (joint) {
    case KinectV2Joint::kHandLeft:
    case KinectV2Joint::kHandTipLeft:
    case KinectV2Joint::kThumbLeft:
      return BodyPart::kLeftLowerArm;
    case KinectV2Joint::kHandRight:
    case KinectV2Joint::kHandTipRight:
    case KinectV2Joint::kThumbRight:
      return BodyPart::kRightLowerArm;
    case KinectV2Joint::kFootLeft:
      return BodyPart::kLeftLowerLeg;
    case KinectV2Joint::kFootRight:
      return BodyPart::kRightLowerLeg;
    default:
      return std::nullopt;
  }
}

void TakeMax(std::optional<double>& slot, double value) {
  slot = slot ? std::max(*slot, value) : value;
}

uint8_t Mix(uint8_t a, uint8_t b, double t) {
  return static_cast<uint8_t>(std::lround(a + (static_cast<double>(b) - a) * t));
}

// Where `value` lies between `low` and `high`, clamped to [0, 1] (1 for an
// empty interval, so unvalidated options cannot divide by zero).
double Fraction(double value, double low, double high) {
  if (!(high > low)) return 1.0;
  return std::clamp((value - low) / (high - low), 0.0, 1.0);
}

Srgb8 Mix(const Srgb8& a, const Srgb8& b, double t) {
  return {Mix(a.r, b.r, t), Mix(a.g, b.g, t), Mix(a.b, b.b, t)};
}

}  // namespace

double AngleBetweenDeg(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return std::atan2(a.cross(b).norm(), a.dot(b)) * kDegPerRad;
}

PoseComparison CompareDirections(const PerPart<Eigen::Vector3d>& learner,
                                 const PerPart<Eigen::Vector3d>& teacher) {
  PoseComparison comparison;
  double sum_deg = 0.0;
  for (int p = 0; p < kNumBodyParts; ++p) {
    if (!learner[p] || !teacher[p]) continue;
    const double error_deg = AngleBetweenDeg(*learner[p], *teacher[p]);
    comparison.part_error_deg[p] = error_deg;
    sum_deg += error_deg;
    ++comparison.num_parts_compared;
  }
  if (comparison.num_parts_compared > 0) {
    comparison.mean_error_deg = sum_deg / comparison.num_parts_compared;
  }
  return comparison;
}

PoseComparison ComparePoses(const body::SkeletonPose& learner, const body::SkeletonPose& teacher) {
  return CompareDirections(PartDirectionsInSpine(learner), PartDirectionsInSpine(teacher));
}

std::array<std::optional<double>, body::kNumKinectV2Joints> JointErrorsDeg(
    const PoseComparison& comparison) {
  std::array<std::optional<double>, body::kNumKinectV2Joints> joint_error_deg;
  for (int p = 0; p < kNumBodyParts; ++p) {
    const std::optional<double>& error_deg = comparison.part_error_deg[p];
    if (!error_deg) continue;
    const PartBone bone = BodyPartBone(BodyPartAt(p));
    TakeMax(joint_error_deg[body::Index(bone.from)], *error_deg);
    TakeMax(joint_error_deg[body::Index(bone.to)], *error_deg);
  }
  for (int j = 0; j < body::kNumKinectV2Joints; ++j) {
    const std::optional<BodyPart> part = HangsFrom(static_cast<KinectV2Joint>(j));
    if (part) joint_error_deg[j] = comparison.part_error_deg[Index(*part)];
  }
  return joint_error_deg;
}

absl::Status ErrorColorOptions::Validate() const {
  if (!std::isfinite(yellow_deg) || !std::isfinite(red_deg) || yellow_deg <= 0.0 ||
      red_deg <= yellow_deg) {
    return absl::InvalidArgumentError(
        absl::StrCat("error colours need 0 < yellow_deg < red_deg, got yellow_deg=", yellow_deg,
                     " red_deg=", red_deg));
  }
  return absl::OkStatus();
}

Srgb8 ErrorToSrgb(double error_deg, const ErrorColorOptions& options) {
  if (std::isnan(error_deg)) return options.missing_color;
  const double e = std::max(error_deg, 0.0);
  if (e >= options.red_deg) return options.red_color;
  if (e <= options.yellow_deg) {
    return Mix(options.green_color, options.yellow_color, Fraction(e, 0.0, options.yellow_deg));
  }
  return Mix(options.yellow_color, options.red_color,
             Fraction(e, options.yellow_deg, options.red_deg));
}

Srgb8 ErrorToSrgb(const std::optional<double>& error_deg, const ErrorColorOptions& options) {
  return error_deg ? ErrorToSrgb(*error_deg, options) : options.missing_color;
}

}  // namespace reenact::mirror
