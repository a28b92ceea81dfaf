#include "common/body/joint_set.h"

#include <algorithm>
#include <unordered_map>
#include <unordered_set>

#include <nlohmann/json.hpp>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "common/base/files.h"

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
  table.reserve(kNumKinectV2Joints);
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

// The canonical joints of one side of the body, and the side's name in
// each naming ("l", "Left", ".L").
struct Side {
  std::string_view daz, mixamo, rigify;
  J shoulder, elbow, wrist, hand, hand_tip, thumb, hip, knee, ankle, foot;
};

constexpr std::array<Side, 2> kSides = {{
    {"l", "Left", ".L", J::kShoulderLeft, J::kElbowLeft, J::kWristLeft, J::kHandLeft,
     J::kHandTipLeft, J::kThumbLeft, J::kHipLeft, J::kKneeLeft, J::kAnkleLeft, J::kFootLeft},
    {"r", "Right", ".R", J::kShoulderRight, J::kElbowRight, J::kWristRight, J::kHandRight,
     J::kHandTipRight, J::kThumbRight, J::kHipRight, J::kKneeRight, J::kAnkleRight, J::kFootRight},
}};

// Daz Studio and Poser figures: the Poser/Genesis 1 names (hip, abdomen,
// chest, neck, head, lCollar, lShldr, lForeArm, lHand, lThigh, lShin, lFoot,
// lToe) as in CMU's Daz-friendly BVH, and the Genesis 2/3/8 names that split
// bones in two (chestLower/chestUpper, neckLower/neckUpper, lShldrBend/
// lShldrTwist, lForearmBend, lThighBend), the first half's head being the
// joint. As for CMU: the chest starts about half way up the torso, the neck
// at its base; a single neck bone puts the Kinect Neck half way along it;
// the hand is the middle finger's knuckle (lMid1); the foot is lToe (the ball
// of the foot) or, without toes, the foot's end site (the ball in the CMU
// files, 12.6 cm ahead of the ankle).
std::vector<JointMapping> DazPoserTable() {
  std::vector<JointMapping> table = {
      {"hip", J::kSpineBase},           {"chestLower", J::kSpineMid}, {"chest", J::kSpineMid},
      {"neckLower", J::kSpineShoulder}, {"neck", J::kSpineShoulder},  {"neckUpper", J::kNeck},
      {"neck", J::kNeck, "head", 0.5},  {"head", J::kHead},
  };
  for (const Side& side : kSides) {
    const std::string s(side.daz);
    for (JointMapping row : std::vector<JointMapping>{
             {s + "ShldrBend", side.shoulder},
             {s + "Shldr", side.shoulder},
             {s + "ForearmBend", side.elbow},
             {s + "ForeArm", side.elbow},
             {s + "Hand", side.wrist},
             {s + "Mid1", side.hand},
             {s + "Mid3_end", side.hand_tip},
             {s + "Mid2_end", side.hand_tip},
             {s + "Thumb3_end", side.thumb},
             {s + "Thumb2_end", side.thumb},
             {s + "ThighBend", side.hip},
             {s + "Thigh", side.hip},
             {s + "Shin", side.knee},
             {s + "Foot", side.ankle},
             {s + "Toe", side.foot},
             {s + "Foot_end", side.foot},
         }) {
      table.push_back(std::move(row));
    }
  }
  return table;
}

// Mixamo's rig (names with or without the "mixamorig:" namespace, which
// DetectJointSet strips). Hips, Spine, Spine1, Spine2, Neck, Head: Spine1
// starts about half way up the torso, Neck at the base of the neck, and the
// single neck bone puts the Kinect Neck half way along it. LeftArm starts at
// the shoulder joint (LeftShoulder is the clavicle); the hand is the middle
// finger's knuckle, the tips the last finger joints (Middle4, Thumb4).
std::vector<JointMapping> MixamoTable() {
  std::vector<JointMapping> table = {
      {"Hips", J::kSpineBase},         {"Spine1", J::kSpineMid}, {"Neck", J::kSpineShoulder},
      {"Neck", J::kNeck, "Head", 0.5}, {"Head", J::kHead},
  };
  for (const Side& side : kSides) {
    const std::string s(side.mixamo);
    for (JointMapping row : std::vector<JointMapping>{
             {s + "Arm", side.shoulder},
             {s + "ForeArm", side.elbow},
             {s + "Hand", side.wrist},
             {s + "HandMiddle1", side.hand},
             {s + "HandMiddle4", side.hand_tip},
             {s + "HandMiddle3_end", side.hand_tip},
             {s + "HandThumb4", side.thumb},
             {s + "HandThumb3_end", side.thumb},
             {s + "UpLeg", side.hip},
             {s + "Leg", side.knee},
             {s + "Foot", side.ankle},
             {s + "ToeBase", side.foot},
         }) {
      table.push_back(std::move(row));
    }
  }
  return table;
}

// Blender's Rigify: the metarig (Blender 2.8+: spine = pelvis, spine.001 to
// spine.003 up the torso, spine.004 the neck's base, spine.005 its middle,
// spine.006 the head; older metarigs: hips, spine, chest, neck, head) and the
// generated rig, whose deform bones ("DEF-" prefix) come first because its
// plain-named bones ("hips", "chest", "neck") are controls placed elsewhere.
// upper_arm starts at the shoulder joint, forearm at the elbow, hand at the
// wrist; f_middle.01 at the middle finger's knuckle; thigh, shin, foot, toe
// at hip, knee, ankle and the ball of the foot.
std::vector<JointMapping> RigifyTable() {
  std::vector<JointMapping> table = {
      {"DEF-hips", J::kSpineBase},
      {"DEF-spine", J::kSpineBase},
      {"hips", J::kSpineBase},
      {"spine", J::kSpineBase},
      {"DEF-spine.002", J::kSpineMid},
      {"DEF-chest", J::kSpineMid},
      {"spine.002", J::kSpineMid},
      {"chest", J::kSpineMid},
      {"DEF-spine.004", J::kSpineShoulder},
      {"DEF-neck", J::kSpineShoulder},
      {"spine.004", J::kSpineShoulder},
      {"neck", J::kSpineShoulder},
      {"DEF-spine.005", J::kNeck},
      {"spine.005", J::kNeck},
      {"DEF-neck", J::kNeck, "DEF-head", 0.5},
      {"neck", J::kNeck, "head", 0.5},
      {"DEF-spine.006", J::kHead},
      {"DEF-head", J::kHead},
      {"spine.006", J::kHead},
      {"head", J::kHead},
  };
  for (const Side& side : kSides) {
    const std::string s(side.rigify);
    const std::vector<std::pair<std::string, J>> bones = {
        {"upper_arm" + s, side.shoulder},
        {"forearm" + s, side.elbow},
        {"hand" + s, side.wrist},
        {"f_middle.01" + s, side.hand},
        {"f_middle.03" + s + "_end", side.hand_tip},
        {"thumb.03" + s + "_end", side.thumb},
        {"thigh" + s, side.hip},
        {"shin" + s, side.knee},
        {"foot" + s, side.ankle},
        {"toe" + s, side.foot},
    };
    for (const auto& [name, target] : bones) {
      table.push_back({"DEF-" + name, target});
      table.push_back({name, target});
    }
  }
  return table;
}

// Recognised namings in the order DetectJointSet prefers them on a tie.
constexpr std::array<JointSetId, 9> kAllJointSets = {
    JointSetId::kKinectV2,     JointSetId::kKinectV1, JointSetId::kCmuBvhCgspeed,
    JointSetId::kCmuBvh3dsMax, JointSetId::kCmuAsf,   JointSetId::kMakeHuman,
    JointSetId::kDazPoser,     JointSetId::kMixamo,   JointSetId::kRigify,
};

// The joints a source must cover for DetectJointSet to accept its table.
constexpr std::array<KinectV2Joint, 10> kCoreJoints = {
    J::kSpineBase,  J::kSpineMid, J::kShoulderLeft, J::kShoulderRight, J::kElbowLeft,
    J::kElbowRight, J::kHipLeft,  J::kHipRight,     J::kKneeLeft,      J::kKneeRight,
};

// Joint names seen in an error message: the first kMaxNamesListed.
constexpr size_t kMaxNamesListed = 40;

// Source joint index by name. A name with a namespace ("mixamorig:Hips",
// "Character1:Hips") is also found by the part after its last ':', unless a
// joint carries that plain name itself.
using NameIndex = std::unordered_map<std::string, int>;

NameIndex IndexNames(const std::vector<std::string>& names) {
  NameIndex index;
  for (size_t i = 0; i < names.size(); ++i) index.emplace(names[i], static_cast<int>(i));
  for (size_t i = 0; i < names.size(); ++i) {
    const size_t colon = names[i].rfind(':');
    if (colon != std::string::npos && colon + 1 < names[i].size()) {
      index.emplace(names[i].substr(colon + 1), static_cast<int>(i));
    }
  }
  return index;
}

// Fills the canonical joints still unplaced in `sources` from `rows`, in
// order. A row with `toward` needs that joint to be a child of the source
// joint (not checked when `parents` is empty).
void ApplyRows(const std::vector<JointMapping>& rows, const NameIndex& index,
               const std::vector<int>& parents, CanonicalSources& sources) {
  for (const JointMapping& row : rows) {
    CanonicalSource& slot = sources[static_cast<size_t>(Index(row.target))];
    if (slot.joint >= 0) continue;
    const auto joint = index.find(row.source_name);
    if (joint == index.end()) continue;
    CanonicalSource found{joint->second, -1, 0.0};
    if (!row.toward.empty()) {
      const auto toward = index.find(row.toward);
      if (toward == index.end()) continue;
      if (!parents.empty() && parents[static_cast<size_t>(toward->second)] != joint->second) {
        continue;
      }
      found.toward = toward->second;
      found.fraction = row.fraction;
    }
    slot = found;
  }
}

CanonicalSources Resolve(JointSetId set, const std::vector<JointMapping>& user_map,
                         const NameIndex& index, const std::vector<int>& parents) {
  CanonicalSources sources;
  ApplyRows(user_map, index, parents, sources);
  ApplyRows(JointMappingTable(set), index, parents, sources);
  return sources;
}

int CountCovered(const CanonicalSources& sources) {
  return static_cast<int>(std::count_if(sources.begin(), sources.end(),
                                        [](const CanonicalSource& s) { return s.joint >= 0; }));
}

std::vector<std::string> MissingCore(const CanonicalSources& sources) {
  std::vector<std::string> missing;
  for (J joint : kCoreJoints) {
    if (sources[static_cast<size_t>(Index(joint))].joint < 0) {
      missing.emplace_back(KinectV2JointName(joint));
    }
  }
  return missing;
}

// "a, b, c" of at most kMaxNamesListed names, then "... and N more".
std::string ListNames(const std::vector<std::string>& names) {
  const size_t shown = std::min(names.size(), kMaxNamesListed);
  std::string list = absl::StrJoin(names.begin(), names.begin() + static_cast<long>(shown), ", ");
  if (names.size() > shown) absl::StrAppend(&list, ", ... and ", names.size() - shown, " more");
  return list;
}

// The InvalidArgument of MatchJointSet when nothing covers the core joints.
absl::Status NoMatchError(const std::vector<std::string>& names,
                          const std::vector<JointMapping>& user_map, const NameIndex& index,
                          const std::vector<int>& parents, const std::string& what) {
  JointSetId closest = JointSetId::kUserMap;
  CanonicalSources closest_sources = Resolve(closest, user_map, index, parents);
  for (JointSetId set : kAllJointSets) {
    CanonicalSources sources = Resolve(set, user_map, index, parents);
    if (CountCovered(sources) > CountCovered(closest_sources)) {
      closest = set;
      closest_sources = sources;
    }
  }
  std::string message = absl::StrCat(
      what,
      ": joint names match no known joint set (Kinect, CMU, MakeHuman, Daz/Poser, Mixamo, "
      "Rigify)");
  if (!user_map.empty()) absl::StrAppend(&message, " even with the joint map");
  absl::StrAppend(
      &message, "; missing Kinect v2 joints: ", absl::StrJoin(MissingCore(closest_sources), ", "));
  if (closest != JointSetId::kUserMap) {
    absl::StrAppend(&message, " (closest naming: ", std::string(JointSetName(closest)), ")");
  }
  std::vector<std::string> absent;
  for (const JointMapping& row : user_map) {
    if (!index.count(row.source_name)) absent.push_back(row.source_name);
  }
  if (!absent.empty()) {
    absl::StrAppend(&message, "; joint map names not in the file: ", ListNames(absent));
  }
  absl::StrAppend(&message, "; joint names seen (", names.size(), "): ", ListNames(names),
                  "; name the missing joints with a joint map (--joint-map FILE: JSON "
                  "{\"their name\": \"SpineBase\", ...})");
  return absl::InvalidArgumentError(message);
}

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
  static const auto* daz = new std::vector<JointMapping>(DazPoserTable());
  static const auto* mixamo = new std::vector<JointMapping>(MixamoTable());
  static const auto* rigify = new std::vector<JointMapping>(RigifyTable());
  static const auto* none = new std::vector<JointMapping>();
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
    case JointSetId::kDazPoser:
      return *daz;
    case JointSetId::kMixamo:
      return *mixamo;
    case JointSetId::kRigify:
      return *rigify;
    case JointSetId::kUserMap:
      return *none;
  }
  return *none;
}

std::optional<JointSetId> DetectJointSet(const std::vector<std::string>& source_names) {
  const NameIndex index = IndexNames(source_names);
  std::optional<JointSetId> best;
  int best_covered = 0;
  for (JointSetId set : kAllJointSets) {
    const CanonicalSources sources = Resolve(set, {}, index, {});
    const int covered = CountCovered(sources);
    if (MissingCore(sources).empty() && covered > best_covered) {
      best = set;
      best_covered = covered;
    }
  }
  return best;
}

CanonicalSources ResolveJointSet(JointSetId set, const std::vector<JointMapping>& user_map,
                                 const std::vector<std::string>& names,
                                 const std::vector<int>& parents) {
  return Resolve(set, user_map, IndexNames(names), parents);
}

absl::StatusOr<JointSetMatch> MatchJointSet(const std::vector<std::string>& names,
                                            const std::vector<int>& parents,
                                            const std::vector<JointMapping>& user_map,
                                            const std::string& what) {
  const NameIndex index = IndexNames(names);
  JointSetMatch user_only{JointSetId::kUserMap,
                          Resolve(JointSetId::kUserMap, user_map, index, parents), 0};
  user_only.covered = CountCovered(user_only.sources);
  std::optional<JointSetMatch> best;
  for (JointSetId set : kAllJointSets) {
    JointSetMatch match{set, Resolve(set, user_map, index, parents), 0};
    match.covered = CountCovered(match.sources);
    // A naming counts only where it places joints the user's map does not.
    if (match.covered <= user_only.covered || !MissingCore(match.sources).empty()) continue;
    if (!best || match.covered > best->covered) best = match;
  }
  if (best) return *best;
  if (MissingCore(user_only.sources).empty()) return user_only;
  return NoMatchError(names, user_map, index, parents, what);
}

absl::StatusOr<std::vector<JointMapping>> ParseJointMap(std::string_view json_text,
                                                        const std::string& what) {
  const auto error = [&](const std::string& message) {
    return absl::InvalidArgumentError(absl::StrCat(what, ": ", message));
  };
  nlohmann::json json;
  try {
    json = nlohmann::json::parse(json_text.begin(), json_text.end());
  } catch (const nlohmann::json::exception& e) {
    return error(absl::StrCat("not valid JSON (", e.what(), ")"));
  }
  constexpr char kExpected[] =
      "expected a JSON object of \"their joint name\": \"Kinect v2 joint name\"";
  if (!json.is_object()) {
    return error(absl::StrCat(kExpected, ", found JSON of type ", json.type_name()));
  }
  if (json.empty()) return error(absl::StrCat("the joint map is empty; ", kExpected));
  std::vector<JointMapping> rows;
  std::array<std::string, kNumKinectV2Joints> mapped_from;
  for (const auto& [source, value] : json.items()) {
    if (source.empty()) return error("an empty joint name");
    if (!value.is_string()) {
      return error(
          absl::StrCat("'", source, "' maps to JSON of type ", value.type_name(), "; ", kExpected));
    }
    const std::string target_name = value.get<std::string>();
    const std::optional<KinectV2Joint> target = KinectV2JointFromName(target_name);
    if (!target) {
      return error(absl::StrCat(
          "'", source, "' maps to '", target_name, "', not a Kinect v2 joint (one of ",
          absl::StrJoin(std::vector<std::string>(kKinectV2Names.begin(), kKinectV2Names.end()),
                        ", "),
          ")"));
    }
    std::string& previous = mapped_from[static_cast<size_t>(Index(*target))];
    if (!previous.empty()) {
      return error(absl::StrCat("both '", previous, "' and '", source, "' map to ", target_name));
    }
    previous = source;
    rows.push_back({source, *target});
  }
  return rows;
}

absl::StatusOr<std::vector<JointMapping>> ReadJointMap(const std::string& path) {
  absl::StatusOr<std::string> text = ReadFileToString(path, kMaxJointMapBytes);
  if (!text.ok()) return text.status();
  return ParseJointMap(*text, path);
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
    case JointSetId::kDazPoser:
      return "daz_poser";
    case JointSetId::kMixamo:
      return "mixamo";
    case JointSetId::kRigify:
      return "rigify";
    case JointSetId::kUserMap:
      return "user_map";
  }
  return "unknown";
}

}  // namespace reenact::body
