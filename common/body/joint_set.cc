#include "common/body/joint_set.h"

#include <algorithm>
#include <unordered_set>

namespace reenact::body {
namespace {

using J = KinectV2Joint;

constexpr std::array<std::string_view, kNumKinectV2Joints> kKinectV2Names = {
    "SpineBase",     "SpineMid",    "Neck",      "Head",          "ShoulderLeft",
    "ElbowLeft",     "WristLeft",   "HandLeft",  "ShoulderRight", "ElbowRight",
    "WristRight",    "HandRight",   "HipLeft",   "KneeLeft",      "AnkleLeft",
    "FootLeft",      "HipRight",    "KneeRight", "AnkleRight",    "FootRight",
    "SpineShoulder", "HandTipLeft", "ThumbLeft", "HandTipRight",  "ThumbRight",
};

// Every table below names, for each canonical joint, the source joint that
// sits at that joint's position. For hierarchies made of bones (BVH joints,
// ASF bones, MakeHuman bones) that is the bone whose START (head) lies on the
// canonical joint; end sites appear as "<parent>_end" (see motion.h).

std::vector<JointMapping> KinectV2Table() {
  std::vector<JointMapping> table;
  for (int j = 0; j < kNumKinectV2Joints; ++j) {
    table.push_back({std::string(kKinectV2Names[j]), static_cast<KinectV2Joint>(j)});
  }
  return table;
}

// Kinect for Windows SDK 1.x (NUI_SKELETON_POSITION_*): 20 joints, no hand
// tips, thumbs or separate neck.
std::vector<JointMapping> KinectV1Table() {
  return {
      {"HipCenter", J::kSpineBase},
      {"Spine", J::kSpineMid},
      {"ShoulderCenter", J::kSpineShoulder},
      {"Head", J::kHead},
      {"ShoulderLeft", J::kShoulderLeft},
      {"ElbowLeft", J::kElbowLeft},
      {"WristLeft", J::kWristLeft},
      {"HandLeft", J::kHandLeft},
      {"ShoulderRight", J::kShoulderRight},
      {"ElbowRight", J::kElbowRight},
      {"WristRight", J::kWristRight},
      {"HandRight", J::kHandRight},
      {"HipLeft", J::kHipLeft},
      {"KneeLeft", J::kKneeLeft},
      {"AnkleLeft", J::kAnkleLeft},
      {"FootLeft", J::kFootLeft},
      {"HipRight", J::kHipRight},
      {"KneeRight", J::kKneeRight},
      {"AnkleRight", J::kAnkleRight},
      {"FootRight", J::kFootRight},
  };
}

// cgspeed's BVH conversion of the CMU database. LowerBack and Neck sit where
// Hips and Spine1 sit (zero offsets); Spine is a third of the way up the
// torso, Neck at the base of the neck; LeftHand is the wrist.
std::vector<JointMapping> CmuBvhCgspeedTable() {
  return {
      {"Hips", J::kSpineBase},
      {"Spine", J::kSpineMid},
      {"Neck", J::kSpineShoulder},
      {"Neck1", J::kNeck},
      {"Head", J::kHead},
      {"LeftArm", J::kShoulderLeft},
      {"LeftForeArm", J::kElbowLeft},
      {"LeftHand", J::kWristLeft},
      {"LFingers", J::kHandLeft},
      {"LFingers_end", J::kHandTipLeft},
      {"LThumb_end", J::kThumbLeft},
      {"RightArm", J::kShoulderRight},
      {"RightForeArm", J::kElbowRight},
      {"RightHand", J::kWristRight},
      {"RFingers", J::kHandRight},
      {"RFingers_end", J::kHandTipRight},
      {"RThumb_end", J::kThumbRight},
      {"LeftUpLeg", J::kHipLeft},
      {"LeftLeg", J::kKneeLeft},
      {"LeftFoot", J::kAnkleLeft},
      {"LeftToeBase", J::kFootLeft},
      {"RightUpLeg", J::kHipRight},
      {"RightLeg", J::kKneeRight},
      {"RightFoot", J::kAnkleRight},
      {"RightToeBase", J::kFootRight},
  };
}

// The CMU BVH files in 3dsMax naming: the joint called LeftShoulder is the
// glenohumeral joint (LeftCollar is the clavicle), LeftHip the hip joint.
std::vector<JointMapping> CmuBvh3dsMaxTable() {
  return {
      {"Hips", J::kSpineBase},
      {"Chest", J::kSpineMid},
      {"lowerneck", J::kSpineShoulder},
      {"Neck", J::kNeck},
      {"Head", J::kHead},
      {"LeftShoulder", J::kShoulderLeft},
      {"LeftElbow", J::kElbowLeft},
      {"LeftWrist", J::kWristLeft},
      {"LFingers", J::kHandLeft},
      {"LFingers_end", J::kHandTipLeft},
      {"LThumb_end", J::kThumbLeft},
      {"RightShoulder", J::kShoulderRight},
      {"RightElbow", J::kElbowRight},
      {"RightWrist", J::kWristRight},
      {"RFingers", J::kHandRight},
      {"RFingers_end", J::kHandTipRight},
      {"RThumb_end", J::kThumbRight},
      {"LeftHip", J::kHipLeft},
      {"LeftKnee", J::kKneeLeft},
      {"LeftAnkle", J::kAnkleLeft},
      {"LeftToe", J::kFootLeft},
      {"RightHip", J::kHipRight},
      {"RightKnee", J::kKneeRight},
      {"RightAnkle", J::kAnkleRight},
      {"RightToe", J::kFootRight},
  };
}

// CMU ASF bones. An ASF bone starts where its parent ends, so each canonical
// joint maps to the bone that STARTS there: lfemur starts at the hip, ltibia at
// the knee, lfoot at the ankle, lhumerus at the shoulder, lradius at the elbow,
// lwrist at the wrist. The spine: lowerback, upperback and thorax each span a
// third of the torso; lowerneck starts at the base of the neck.
std::vector<JointMapping> CmuAsfTable() {
  return {
      {"root", J::kSpineBase},
      {"thorax", J::kSpineMid},
      {"lowerneck", J::kSpineShoulder},
      {"upperneck", J::kNeck},
      {"head", J::kHead},
      {"lhumerus", J::kShoulderLeft},
      {"lradius", J::kElbowLeft},
      {"lwrist", J::kWristLeft},
      {"lhand", J::kHandLeft},
      {"lfingers_end", J::kHandTipLeft},
      {"lthumb_end", J::kThumbLeft},
      {"rhumerus", J::kShoulderRight},
      {"rradius", J::kElbowRight},
      {"rwrist", J::kWristRight},
      {"rhand", J::kHandRight},
      {"rfingers_end", J::kHandTipRight},
      {"rthumb_end", J::kThumbRight},
      {"lfemur", J::kHipLeft},
      {"ltibia", J::kKneeLeft},
      {"lfoot", J::kAnkleLeft},
      {"ltoes", J::kFootLeft},
      {"rfemur", J::kHipRight},
      {"rtibia", J::kKneeRight},
      {"rfoot", J::kAnkleRight},
      {"rtoes", J::kFootRight},
  };
}

// MakeHuman's default skeleton (rigs/default.mhskel). A MakeHuman bone rotates
// about its head, so each canonical joint maps to the bone whose HEAD lies on
// it. spine05's head is the pelvis centre (root's head lies behind the body);
// spine02 starts a third of the way up the torso; neck01 at the base of the
// neck; the hand is the middle finger's knuckle (finger3-1), the hand tip the
// head of its last phalanx, the thumb the head of the thumb's last phalanx,
// the foot the ball of the foot (toe3-1).
std::vector<JointMapping> MakeHumanTable() {
  return {
      {"spine05", J::kSpineBase},
      {"spine02", J::kSpineMid},
      {"neck01", J::kSpineShoulder},
      {"neck02", J::kNeck},
      {"head", J::kHead},
      {"upperarm01.L", J::kShoulderLeft},
      {"lowerarm01.L", J::kElbowLeft},
      {"wrist.L", J::kWristLeft},
      {"finger3-1.L", J::kHandLeft},
      {"finger3-3.L", J::kHandTipLeft},
      {"finger1-3.L", J::kThumbLeft},
      {"upperarm01.R", J::kShoulderRight},
      {"lowerarm01.R", J::kElbowRight},
      {"wrist.R", J::kWristRight},
      {"finger3-1.R", J::kHandRight},
      {"finger3-3.R", J::kHandTipRight},
      {"finger1-3.R", J::kThumbRight},
      {"upperleg01.L", J::kHipLeft},
      {"lowerleg01.L", J::kKneeLeft},
      {"foot.L", J::kAnkleLeft},
      {"toe3-1.L", J::kFootLeft},
      {"upperleg01.R", J::kHipRight},
      {"lowerleg01.R", J::kKneeRight},
      {"foot.R", J::kAnkleRight},
      {"toe3-1.R", J::kFootRight},
  };
}

constexpr std::array<JointSetId, 6> kAllJointSets = {
    JointSetId::kKinectV2,     JointSetId::kKinectV1, JointSetId::kCmuBvhCgspeed,
    JointSetId::kCmuBvh3dsMax, JointSetId::kCmuAsf,   JointSetId::kMakeHuman,
};

// The joints a source must cover for DetectJointSet to accept its table.
constexpr std::array<KinectV2Joint, 10> kCoreJoints = {
    J::kSpineBase,  J::kSpineMid, J::kShoulderLeft, J::kShoulderRight, J::kElbowLeft,
    J::kElbowRight, J::kHipLeft,  J::kHipRight,     J::kKneeLeft,      J::kKneeRight,
};

}  // namespace

std::string_view KinectV2JointName(KinectV2Joint joint) {
  const int index = Index(joint);
  if (index < 0 || index >= kNumKinectV2Joints) return "";
  return kKinectV2Names[index];
}

std::optional<KinectV2Joint> KinectV2JointFromName(std::string_view name) {
  for (int j = 0; j < kNumKinectV2Joints; ++j) {
    if (kKinectV2Names[j] == name) return static_cast<KinectV2Joint>(j);
  }
  return std::nullopt;
}

std::optional<KinectV2Joint> KinectV2Parent(KinectV2Joint joint) {
  switch (joint) {
    case J::kSpineBase:
      return std::nullopt;
    case J::kSpineMid:
      return J::kSpineBase;
    case J::kSpineShoulder:
      return J::kSpineMid;
    case J::kNeck:
    case J::kShoulderLeft:
    case J::kShoulderRight:
      return J::kSpineShoulder;
    case J::kHead:
      return J::kNeck;
    case J::kElbowLeft:
      return J::kShoulderLeft;
    case J::kWristLeft:
      return J::kElbowLeft;
    case J::kHandLeft:
    case J::kThumbLeft:
      return J::kWristLeft;
    case J::kHandTipLeft:
      return J::kHandLeft;
    case J::kElbowRight:
      return J::kShoulderRight;
    case J::kWristRight:
      return J::kElbowRight;
    case J::kHandRight:
    case J::kThumbRight:
      return J::kWristRight;
    case J::kHandTipRight:
      return J::kHandRight;
    case J::kHipLeft:
    case J::kHipRight:
      return J::kSpineBase;
    case J::kKneeLeft:
      return J::kHipLeft;
    case J::kAnkleLeft:
      return J::kKneeLeft;
    case J::kFootLeft:
      return J::kAnkleLeft;
    case J::kKneeRight:
      return J::kHipRight;
    case J::kAnkleRight:
      return J::kKneeRight;
    case J::kFootRight:
      return J::kAnkleRight;
  }
  return std::nullopt;
}

const std::vector<JointMapping>& JointMappingTable(JointSetId set) {
  static const auto* kinect_v2 = new std::vector<JointMapping>(KinectV2Table());
  static const auto* kinect_v1 = new std::vector<JointMapping>(KinectV1Table());
  static const auto* cgspeed = new std::vector<JointMapping>(CmuBvhCgspeedTable());
  static const auto* max3ds = new std::vector<JointMapping>(CmuBvh3dsMaxTable());
  static const auto* asf = new std::vector<JointMapping>(CmuAsfTable());
  static const auto* makehuman = new std::vector<JointMapping>(MakeHumanTable());
  switch (set) {
    case JointSetId::kKinectV2:
      return *kinect_v2;
    case JointSetId::kKinectV1:
      return *kinect_v1;
    case JointSetId::kCmuBvhCgspeed:
      return *cgspeed;
    case JointSetId::kCmuBvh3dsMax:
      return *max3ds;
    case JointSetId::kCmuAsf:
      return *asf;
    case JointSetId::kMakeHuman:
      return *makehuman;
  }
  return *kinect_v2;
}

std::optional<JointSetId> DetectJointSet(const std::vector<std::string>& source_names) {
  const std::unordered_set<std::string> names(source_names.begin(), source_names.end());
  std::optional<JointSetId> best;
  int best_matches = 0;
  for (JointSetId set : kAllJointSets) {
    std::array<bool, kNumKinectV2Joints> covered{};
    int matches = 0;
    for (const JointMapping& row : JointMappingTable(set)) {
      if (names.count(row.source_name)) {
        covered[Index(row.target)] = true;
        ++matches;
      }
    }
    const bool has_core = std::all_of(kCoreJoints.begin(), kCoreJoints.end(),
                                      [&](KinectV2Joint j) { return covered[Index(j)]; });
    if (has_core && matches > best_matches) {
      best = set;
      best_matches = matches;
    }
  }
  return best;
}

std::string_view JointSetName(JointSetId set) {
  switch (set) {
    case JointSetId::kKinectV2:
      return "kinect_v2";
    case JointSetId::kKinectV1:
      return "kinect_v1";
    case JointSetId::kCmuBvhCgspeed:
      return "cmu_bvh_cgspeed";
    case JointSetId::kCmuBvh3dsMax:
      return "cmu_bvh_3dsmax";
    case JointSetId::kCmuAsf:
      return "cmu_asf";
    case JointSetId::kMakeHuman:
      return "makehuman";
  }
  return "unknown";
}

}  // namespace reenact::body
