#include "common/synth/builtin_motions.h"

#include <algorithm>
#include <cmath>
#include <map>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "common/body/joint_set.h"

namespace reenact::synth {
namespace {

using body::KinectV2Joint;
using J = KinectV2Joint;

// Rest offsets (metres, parent frame = world axes in the T-pose) of a 1.75 m
// adult; proportions after Drillis and Contini's segment-length ratios.
Eigen::Vector3d RestOffset(J joint) {
  switch (joint) {
    case J::kSpineBase:
      return {0, 0.93, 0};
    case J::kSpineMid:
      return {0, 0.21, 0};
    case J::kSpineShoulder:
      return {0, 0.23, 0};
    case J::kNeck:
      return {0, 0.07, 0};
    case J::kHead:
      return {0, 0.15, 0.01};
    case J::kShoulderLeft:
      return {0.18, -0.03, 0};
    case J::kShoulderRight:
      return {-0.18, -0.03, 0};
    case J::kElbowLeft:
      return {0.29, 0, 0};
    case J::kElbowRight:
      return {-0.29, 0, 0};
    case J::kWristLeft:
      return {0.25, 0, 0};
    case J::kWristRight:
      return {-0.25, 0, 0};
    case J::kHandLeft:
      return {0.08, 0, 0};
    case J::kHandRight:
      return {-0.08, 0, 0};
    case J::kHandTipLeft:
      return {0.09, 0, 0};
    case J::kHandTipRight:
      return {-0.09, 0, 0};
    case J::kThumbLeft:
      return {0.05, 0, 0.04};
    case J::kThumbRight:
      return {-0.05, 0, 0.04};
    case J::kHipLeft:
      return {0.09, -0.05, 0};
    case J::kHipRight:
      return {-0.09, -0.05, 0};
    case J::kKneeLeft:
    case J::kKneeRight:
      return {0, -0.43, 0};
    case J::kAnkleLeft:
    case J::kAnkleRight:
      return {0, -0.40, 0};
    case J::kFootLeft:
    case J::kFootRight:
      return {0, -0.05, 0.13};
  }
  return {0, 0, 0};
}

// A key pose: Euler angles (degrees, applied X then Y then Z in the parent
// frame, i.e. R = Rz * Ry * Rx) for the joints that move; others stay at rest.
using KeyPose = std::map<J, Eigen::Vector3d>;
struct Key {
  double time_s;
  KeyPose pose;
};

Eigen::Quaterniond FromEulerDeg(const Eigen::Vector3d& deg) {
  const Eigen::Vector3d r = deg * M_PI / 180.0;
  return Eigen::AngleAxisd(r.z(), Eigen::Vector3d::UnitZ()) *
         Eigen::AngleAxisd(r.y(), Eigen::Vector3d::UnitY()) *
         Eigen::AngleAxisd(r.x(), Eigen::Vector3d::UnitX());
}

Eigen::Quaterniond KeyRotation(const KeyPose& pose, J joint) {
  auto it = pose.find(joint);
  return it == pose.end() ? Eigen::Quaterniond::Identity() : FromEulerDeg(it->second);
}

// Arms hanging at the sides (from the T-pose) plus `extra` on top.
KeyPose ArmsDown(double deg, KeyPose extra = {}) {
  extra.emplace(J::kShoulderLeft, Eigen::Vector3d(0, 0, -deg));
  extra.emplace(J::kShoulderRight, Eigen::Vector3d(0, 0, deg));
  return extra;
}

std::vector<Key> ArmRaiseKeys() {
  // Lateral raise: down, overhead, down; slow (8 s cycle).
  return {{0.0, ArmsDown(78)},
          {3.0, ArmsDown(-80)},
          {4.0, ArmsDown(-80)},
          {7.0, ArmsDown(78)},
          {8.0, ArmsDown(78)}};
}

std::vector<Key> SquatKeys() {
  KeyPose stand = ArmsDown(78);
  KeyPose low = {{J::kShoulderLeft, {0, -80, 0}}, {J::kShoulderRight, {0, 80, 0}},
                 {J::kSpineMid, {25, 0, 0}},      {J::kHipLeft, {-95, 0, 4}},
                 {J::kHipRight, {-95, 0, -4}},    {J::kKneeLeft, {105, 0, 0}},
                 {J::kKneeRight, {105, 0, 0}},    {J::kAnkleLeft, {-15, 0, 0}},
                 {J::kAnkleRight, {-15, 0, 0}}};
  return {{0.0, stand}, {0.5, stand}, {2.0, low}, {2.5, low}, {4.0, stand}};
}

std::vector<Key> FrontKickKeys() {
  // Guard: upper arms down and forward, forearms up in front of the chest.
  KeyPose guard = {{J::kShoulderLeft, {0, -20, -70}},
                   {J::kShoulderRight, {0, 20, 70}},
                   {J::kElbowLeft, {0, -110, 0}},
                   {J::kElbowRight, {0, 110, 0}}};
  KeyPose chamber = guard, extend = guard, land = guard;
  chamber[J::kHipRight] = {-85, 0, 0};
  chamber[J::kKneeRight] = {100, 0, 0};
  chamber[J::kSpineMid] = {-8, 0, 0};
  extend[J::kHipRight] = {-88, 0, 0};
  extend[J::kKneeRight] = {5, 0, 0};
  extend[J::kAnkleRight] = {30, 0, 0};
  extend[J::kSpineMid] = {-12, 0, 0};
  land[J::kHipRight] = {-20, 0, 0};
  land[J::kKneeRight] = {30, 0, 0};
  return {{0.0, guard},   {0.6, guard}, {1.0, chamber}, {1.3, extend},
          {1.6, chamber}, {2.0, land},  {2.4, guard},   {3.0, guard}};
}

std::vector<Key> KeysFor(std::string_view name) {
  if (name == "arm-raise") return ArmRaiseKeys();
  if (name == "squat") return SquatKeys();
  if (name == "front-kick") return FrontKickKeys();
  return {};
}

// Smoothstep-eased slerp between the surrounding keys at cycle time t.
Eigen::Quaterniond Interpolate(const std::vector<Key>& keys, J joint, double t) {
  size_t i = 0;
  while (i + 1 < keys.size() && keys[i + 1].time_s <= t) ++i;
  if (i + 1 >= keys.size()) return KeyRotation(keys.back().pose, joint);
  const Key& a = keys[i];
  const Key& b = keys[i + 1];
  double u = (t - a.time_s) / (b.time_s - a.time_s);
  u = u * u * (3 - 2 * u);
  return KeyRotation(a.pose, joint).slerp(u, KeyRotation(b.pose, joint));
}

}  // namespace

std::vector<std::string> BuiltinMotionNames() { return {"arm-raise", "squat", "front-kick"}; }

absl::StatusOr<body::Motion> MakeBuiltinMotion(std::string_view name, double seconds, double fps) {
  const std::vector<Key> keys = KeysFor(name);
  if (keys.empty()) {
    return absl::NotFoundError(
        absl::StrCat("unknown built-in motion '", std::string(name),
                     "'; known: ", absl::StrJoin(BuiltinMotionNames(), ", ")));
  }
  if (!(seconds > 0) || !(fps > 0)) {
    return absl::InvalidArgumentError("built-in motion: seconds and fps must be positive");
  }
  std::vector<body::MotionJoint> joints(body::kNumKinectV2Joints);
  for (int j = 0; j < body::kNumKinectV2Joints; ++j) {
    const auto joint = static_cast<J>(j);
    joints[j].name = std::string(body::KinectV2JointName(joint));
    const auto parent = body::KinectV2Parent(joint);
    joints[j].parent = parent ? body::Index(*parent) : -1;
    joints[j].offset_m = j == 0 ? Eigen::Vector3d::Zero() : RestOffset(joint);
  }
  const int num_frames = std::max(1, static_cast<int>(std::lround(seconds * fps)));
  const double cycle_s = keys.back().time_s;
  std::vector<std::vector<Eigen::Quaterniond>> rotations(num_frames);
  std::vector<Eigen::Vector3d> roots(num_frames, RestOffset(J::kSpineBase));
  for (int f = 0; f < num_frames; ++f) {
    const double t = std::fmod(f / fps, cycle_s);
    rotations[f].resize(joints.size());
    for (int j = 0; j < body::kNumKinectV2Joints; ++j) {
      rotations[f][j] = Interpolate(keys, static_cast<J>(j), t);
    }
  }
  body::MotionInfo info;
  info.path = absl::StrCat("builtin:", std::string(name));
  info.format = "builtin";
  info.num_frames = num_frames;
  info.fps = fps;
  info.metres_per_unit = 1.0;
  info.unit_source = body::UnitSource::kGiven;
  info.joint_set = body::JointSetId::kKinectV2;
  // Keep the lower foot on the floor: lower the root by how far the feet rose.
  body::Motion draft(info, joints, rotations, roots);
  for (int f = 0; f < num_frames; ++f) {
    const auto world = draft.WorldFromJoints(f);
    double lowest = 1e9;
    for (J foot : {J::kFootLeft, J::kFootRight, J::kAnkleLeft, J::kAnkleRight}) {
      const double floor_offset = (foot == J::kAnkleLeft || foot == J::kAnkleRight) ? 0.05 : 0.0;
      lowest = std::min(lowest, world[body::Index(foot)].translation().y() - floor_offset);
    }
    roots[f].y() -= lowest;
  }
  return body::Motion(info, std::move(joints), std::move(rotations), std::move(roots));
}

}  // namespace reenact::synth
