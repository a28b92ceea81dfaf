#include "server/recon/body_parts.h"

#include <cmath>

namespace reenact::recon {
namespace {

using body::KinectV2Joint;
using Eigen::Matrix3d;
using Eigen::Vector3d;
using J = KinectV2Joint;
using P = BodyPart;
using JointArray25 = std::array<Vector3d, body::kNumKinectV2Joints>;

constexpr double kMinBoneLengthM = 1e-3;
// Below this |sin| between a reference line and the bone, the line is
// treated as parallel to the bone (about 8 degrees).
constexpr double kMinReferenceSin = 0.14;
// Swings whose rest direction and bone are closer to opposite than this
// cosine (about 2 degrees) use the half turn about the rest frame's Z.
constexpr double kAntiparallelCos = -0.9994;

const std::array<BodyPartInfo, kNumBodyParts> kParts = {{
    {P::kHead, "head", J::kNeck, J::kHead, P::kChest},
    {P::kChest, "chest", J::kSpineMid, J::kSpineShoulder, std::nullopt},
    {P::kAbdomen, "abdomen", J::kSpineBase, J::kSpineMid, std::nullopt},
    {P::kUpperArmLeft, "upper_arm_left", J::kShoulderLeft, J::kElbowLeft, P::kChest},
    {P::kForearmLeft, "forearm_left", J::kElbowLeft, J::kWristLeft, P::kUpperArmLeft},
    {P::kHandLeft, "hand_left", J::kWristLeft, J::kHandTipLeft, P::kForearmLeft},
    {P::kUpperArmRight, "upper_arm_right", J::kShoulderRight, J::kElbowRight, P::kChest},
    {P::kForearmRight, "forearm_right", J::kElbowRight, J::kWristRight, P::kUpperArmRight},
    {P::kHandRight, "hand_right", J::kWristRight, J::kHandTipRight, P::kForearmRight},
    {P::kThighLeft, "thigh_left", J::kHipLeft, J::kKneeLeft, P::kAbdomen},
    {P::kShinLeft, "shin_left", J::kKneeLeft, J::kAnkleLeft, P::kThighLeft},
    {P::kFootLeft, "foot_left", J::kAnkleLeft, J::kFootLeft, P::kShinLeft},
    {P::kThighRight, "thigh_right", J::kHipRight, J::kKneeRight, P::kAbdomen},
    {P::kShinRight, "shin_right", J::kKneeRight, J::kAnkleRight, P::kThighRight},
    {P::kFootRight, "foot_right", J::kAnkleRight, J::kFootRight, P::kShinRight},
}};

bool Finite(const Vector3d& v) { return v.allFinite(); }

// Rotation whose columns are x, y, z.
Matrix3d Columns(const Vector3d& x, const Vector3d& y, const Vector3d& z) {
  Matrix3d m;
  m.col(0) = x;
  m.col(1) = y;
  m.col(2) = z;
  return m;
}

// The frame with +Y = `y` and X = `reference` made orthogonal to it; nullopt
// when the reference is missing or within ~8 degrees of the bone.
std::optional<Matrix3d> FrameFromReference(const Vector3d& y, const Vector3d& reference) {
  if (!Finite(reference) || reference.norm() < kMinBoneLengthM) return std::nullopt;
  const Vector3d r = reference.normalized();
  const Vector3d x = r - r.dot(y) * y;  // Gram-Schmidt.
  if (x.norm() < kMinReferenceSin) return std::nullopt;
  const Vector3d xn = x.normalized();
  return Columns(xn, y, xn.cross(y));
}

// The part's rest frame in its parent's frame (columns: X, Y, Z of the part
// in parent coordinates), see the header: the rest pose has arms out
// sideways, legs down, feet forward.
Matrix3d RestInParent(BodyPart part) {
  const Vector3d ex = Vector3d::UnitX(), ey = Vector3d::UnitY(), ez = Vector3d::UnitZ();
  switch (part) {
    case P::kUpperArmLeft:  // Y = chest +X (out to the left), Z forward.
      return Columns(-ey, ex, ez);
    case P::kUpperArmRight:  // Y = chest -X (out to the right), Z forward.
      return Columns(ey, -ex, ez);
    case P::kThighLeft:
    case P::kThighRight:  // Y = abdomen -Y (down), Z forward.
      return Columns(-ex, -ey, ez);
    case P::kFootLeft:
    case P::kFootRight:  // +90 degrees about the shin's X: Y = shin Z, Z = -shin Y.
      return Columns(ex, ez, -ey);
    default:  // Head, forearms, hands, shins: the parent's frame.
      return Matrix3d::Identity();
  }
}

// The rest frame `rest` (world) turned by the smallest rotation taking its Y
// onto `y` (parallel transport).
Matrix3d Swing(const Matrix3d& rest, const Vector3d& y) {
  const Vector3d y0 = rest.col(1);
  if (y0.dot(y) < kAntiparallelCos) {
    // Half turn about the rest frame's Z, then the small remaining swing.
    const Matrix3d half = Eigen::AngleAxisd(M_PI, rest.col(2)).toRotationMatrix();
    return Swing(half * rest, y);
  }
  const Matrix3d swing = Eigen::Quaterniond::FromTwoVectors(y0, y).toRotationMatrix();
  Matrix3d frame = swing * rest;
  frame.col(1) = y;  // Exact along the bone.
  frame.col(0) = (frame.col(0) - frame.col(0).dot(y) * y).normalized();
  frame.col(2) = frame.col(0).cross(y);
  return frame;
}

Vector3d Line(const JointArray25& joints, J from, J to) {
  return joints[body::Index(to)] - joints[body::Index(from)];
}

}  // namespace

const std::array<BodyPartInfo, kNumBodyParts>& BodyParts() { return kParts; }

const BodyPartInfo& GetBodyPartInfo(BodyPart part) { return kParts[Index(part)]; }

std::vector<std::string> BodyPartNames() {
  std::vector<std::string> names;
  names.reserve(kParts.size());
  for (const BodyPartInfo& info : kParts) names.emplace_back(info.name);
  return names;
}

std::optional<BodyPart> BodyPartFromName(std::string_view name) {
  for (const BodyPartInfo& info : kParts) {
    if (info.name == name) return info.part;
  }
  return std::nullopt;
}

PartPoses PartPosesFromJoints(const JointArray25& joints) {
  PartPoses poses;
  // Rotation of each part's frame in the world, valid or not (an invalid
  // part passes its parent's on to its children).
  std::array<Matrix3d, kNumBodyParts> rotation;
  // Parents come before children in part-id order except for the head
  // (parent chest, id 1); do the torso first.
  constexpr std::array<P, kNumBodyParts> kOrder = {
      P::kChest,    P::kAbdomen,       P::kHead,         P::kUpperArmLeft, P::kForearmLeft,
      P::kHandLeft, P::kUpperArmRight, P::kForearmRight, P::kHandRight,    P::kThighLeft,
      P::kShinLeft, P::kFootLeft,      P::kThighRight,   P::kShinRight,    P::kFootRight};
  const Vector3d shoulder_line = Line(joints, J::kShoulderRight, J::kShoulderLeft);
  const Vector3d hip_line = Line(joints, J::kHipRight, J::kHipLeft);
  for (P part : kOrder) {
    const BodyPartInfo& info = kParts[Index(part)];
    const Vector3d& a = joints[body::Index(info.proximal)];
    const Vector3d& b = joints[body::Index(info.distal)];
    PartPose& pose = poses[Index(part)];
    const bool joints_ok = Finite(a) && Finite(b) && (b - a).norm() >= kMinBoneLengthM;
    Matrix3d parent_rotation = Matrix3d::Identity();  // World axes without a parent.
    if (info.parent) parent_rotation = rotation[Index(*info.parent)];
    if (!joints_ok) {
      // Children of an invalid part swing from its parent's rest frame.
      rotation[Index(part)] = parent_rotation * RestInParent(part);
      continue;
    }
    const Vector3d y = (b - a).normalized();
    std::optional<Matrix3d> frame;
    if (!info.parent) {
      // Chest: shoulder line, then hip line; abdomen: the other way round;
      // then world +Z (as X of a frame turned so that Z is forward), +X.
      const bool chest = part == P::kChest;
      frame = FrameFromReference(y, chest ? shoulder_line : hip_line);
      if (!frame) frame = FrameFromReference(y, chest ? hip_line : shoulder_line);
      if (!frame) frame = FrameFromReference(y, Vector3d::UnitX());
      if (!frame) frame = FrameFromReference(y, Vector3d::UnitZ());
    } else {
      frame = Swing(parent_rotation * RestInParent(part), y);
    }
    rotation[Index(part)] = *frame;
    pose.world_from_part.linear() = *frame;
    pose.world_from_part.translation() = a;
    pose.length_m = (b - a).norm();
    pose.valid = true;
  }
  return poses;
}

}  // namespace reenact::recon
