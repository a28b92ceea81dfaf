// The BVH namings beyond CMU's (Daz/Poser, Genesis, Mixamo, MakeHuman,
// Rigify) and users' joint maps: each naming from a small BVH written here,
// a hierarchy and two frames, whose joints sit where the test figure's
// anatomy says, so that a joint mapped to the wrong source joint shows as a
// position error.
#include <filesystem>
#include <fstream>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

#include "common/body/joint_set.h"
#include "common/body/motion.h"
#include "common/testing/test_data.h"

namespace reenact::body {
namespace {

using J = KinectV2Joint;
using V = Eigen::Vector3d;

constexpr double kMm = 1e-3;
constexpr double kMetresPerCm = 0.01;

// The test figure, centimetres, +Y up, facing +Z, its left at +X: where each
// canonical joint lies. The left side; the right mirrors it.
std::map<J, V> FigureCm() {
  std::map<J, V> at = {{J::kSpineBase, {0, 100, 0}},
                       {J::kSpineMid, {0, 125, 0}},
                       {J::kSpineShoulder, {0, 150, 0}},
                       {J::kNeck, {0, 155, 0}},
                       {J::kHead, {0, 160, 0}}};
  const std::vector<std::pair<std::pair<J, J>, V>> sided = {
      {{J::kShoulderLeft, J::kShoulderRight}, {18, 146, 0}},
      {{J::kElbowLeft, J::kElbowRight}, {46, 146, 0}},
      {{J::kWristLeft, J::kWristRight}, {72, 146, 0}},
      {{J::kHandLeft, J::kHandRight}, {81, 146, 0}},
      {{J::kHandTipLeft, J::kHandTipRight}, {89, 146, 0}},
      {{J::kThumbLeft, J::kThumbRight}, {80, 146, 6}},
      {{J::kHipLeft, J::kHipRight}, {9, 95, 0}},
      {{J::kKneeLeft, J::kKneeRight}, {9, 52, 0}},
      {{J::kAnkleLeft, J::kAnkleRight}, {9, 8, 0}},
      {{J::kFootLeft, J::kFootRight}, {9, 1, 12}},
  };
  for (const auto& [joints, left] : sided) {
    at[joints.first] = left;
    at[joints.second] = V(-left.x(), left.y(), left.z());
  }
  return at;
}

// One joint of a test skeleton: its rest position (cm, figure frame). A name
// "<parent>_end" under that parent is written as the parent's End Site.
struct Bone {
  std::string name;
  std::string parent;  // Empty for the root.
  V at_cm;
};

// Bones of both sides: `make(side, sign)` for the left ("L" side names, +X)
// and the right.
template <typename Make>
std::vector<Bone> BothSides(std::vector<Bone> bones, Make make) {
  for (const auto& [side, sign] : {std::pair{'L', 1.0}, std::pair{'R', -1.0}}) {
    for (Bone bone : make(side, sign)) bones.push_back(std::move(bone));
  }
  return bones;
}

V S(double sign, double x, double y, double z) { return V(sign * x, y, z); }

// Writes `bones` as BVH text in centimetres: two frames, the first at rest,
// the second with the root moved 10 cm along +X. `z_up` writes the file Z-up
// as Blender does: figure (x, y, z) -> file (x, -z, y).
class BvhWriter {
 public:
  BvhWriter(const std::vector<Bone>& bones, bool z_up) : bones_(bones), z_up_(z_up) {}

  std::string Text() {
    std::string text = "HIERARCHY\n";
    Write(0, 0, V::Zero(), text);
    text += "MOTION\nFrames: 2\nFrame Time: 0.0333333\n";
    for (int frame = 0; frame < 2; ++frame) {
      text += frame == 0 ? "0 0 0" : "10 0 0";
      for (int c = 3; c < channels_; ++c) text += " 0";
      text += "\n";
    }
    return text;
  }

 private:
  V File(const V& figure) const { return z_up_ ? V(figure.x(), -figure.z(), figure.y()) : figure; }

  void Write(size_t index, int depth, const V& parent_at_cm, std::string& text) {
    const Bone& bone = bones_[index];
    const std::string indent(static_cast<size_t>(2 * depth), ' ');
    const bool end_site = !bone.parent.empty() && bone.name == bone.parent + "_end";
    text += indent + (depth == 0 ? "ROOT " + bone.name
                      : end_site ? "End Site"
                                 : "JOINT " + bone.name);
    const V offset = File(bone.at_cm - parent_at_cm);
    text += "\n" + indent + "{\n" + indent + "  OFFSET " + std::to_string(offset.x()) + " " +
            std::to_string(offset.y()) + " " + std::to_string(offset.z()) + "\n";
    if (depth == 0) {
      text += indent + "  CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation\n";
      channels_ += 6;
    } else if (!end_site) {
      text += indent + "  CHANNELS 3 Zrotation Xrotation Yrotation\n";
      channels_ += 3;
    }
    for (size_t child = 0; child < bones_.size(); ++child) {
      if (bones_[child].parent == bone.name) Write(child, depth + 1, bone.at_cm, text);
    }
    text += indent + "}\n";
  }

  const std::vector<Bone>& bones_;
  bool z_up_;
  int channels_ = 0;
};

std::string WriteBvhFile(const std::string& name, const std::vector<Bone>& bones, bool z_up) {
  const std::string path = reenact::testing::MakeTempDir("joint_naming_" + name) + "/" + name;
  std::ofstream(path) << BvhWriter(bones, z_up).Text();
  return path;
}

// Reads the BVH of `bones` (1 unit = 1 cm) and expects `set`, every canonical
// joint within 0.01 mm of the figure's anatomy on frame 0, and 10 cm further
// along +X on frame 1.
void ExpectFigure(const std::string& name, const std::vector<Bone>& bones, JointSetId set,
                  bool z_up = false, const std::vector<JointMapping>& joint_map = {}) {
  SCOPED_TRACE(name);
  const std::string path = WriteBvhFile(name + ".bvh", bones, z_up);
  const absl::StatusOr<Motion> motion =
      ReadBvh(path, {.metres_per_unit = kMetresPerCm, .joint_map = joint_map});
  ASSERT_TRUE(motion.ok()) << motion.status();
  EXPECT_EQ(motion->info().joint_set, set) << JointSetName(motion->info().joint_set);
  EXPECT_EQ(motion->info().turned_from_z_up, z_up);
  ASSERT_EQ(motion->num_frames(), 2);
  const SkeletonPose rest = motion->CanonicalPose(0);
  const SkeletonPose moved = motion->CanonicalPose(1);
  for (const auto& [joint, at_cm] : FigureCm()) {
    const int j = Index(joint);
    ASSERT_TRUE(rest.valid[j]) << KinectV2JointName(joint);
    EXPECT_LT((rest.position_m[j] - at_cm * kMetresPerCm).norm(), 0.01 * kMm)
        << KinectV2JointName(joint) << " at " << rest.position_m[j].transpose() << " m";
    EXPECT_LT((moved.position_m[j] - rest.position_m[j] - V(0.1, 0, 0)).norm(), 0.01 * kMm)
        << KinectV2JointName(joint);
  }
}

// CMU's Daz-friendly release: hip, abdomen, chest, neck, head; lCollar,
// lShldr, lForeArm, lHand, lMid1-2, lThumb1-2; lButtock, lThigh, lShin,
// lFoot and its end site (no toes).
std::vector<Bone> DazPoserBones() {
  return BothSides({{"hip", "", {0, 100, 0}},
                    {"abdomen", "hip", {0, 112, 0}},
                    {"chest", "abdomen", {0, 125, 0}},
                    {"neck", "chest", {0, 150, 0}},
                    {"head", "neck", {0, 160, 0}},
                    {"leftEye", "head", {3, 168, 8}},
                    {"leftEye_end", "leftEye", {4, 168, 8}}},
                   [](char side, double k) {
                     const std::string s(1, side == 'L' ? 'l' : 'r');
                     return std::vector<Bone>{
                         {s + "Collar", "chest", S(k, 3, 146, 0)},
                         {s + "Shldr", s + "Collar", S(k, 18, 146, 0)},
                         {s + "ForeArm", s + "Shldr", S(k, 46, 146, 0)},
                         {s + "Hand", s + "ForeArm", S(k, 72, 146, 0)},
                         {s + "Thumb1", s + "Hand", S(k, 75, 146, 3)},
                         {s + "Thumb2", s + "Thumb1", S(k, 78, 146, 5)},
                         {s + "Thumb2_end", s + "Thumb2", S(k, 80, 146, 6)},
                         {s + "Mid1", s + "Hand", S(k, 81, 146, 0)},
                         {s + "Mid2", s + "Mid1", S(k, 84.5, 146, 0)},
                         {s + "Mid2_end", s + "Mid2", S(k, 89, 146, 0)},
                         {s + "Buttock", "hip", S(k, 9, 104, 0)},
                         {s + "Thigh", s + "Buttock", S(k, 9, 95, 0)},
                         {s + "Shin", s + "Thigh", S(k, 9, 52, 0)},
                         {s + "Foot", s + "Shin", S(k, 9, 8, 0)},
                         {s + "Foot_end", s + "Foot", S(k, 9, 1, 12)},
                     };
                   });
}

// Daz Genesis 3/8: split torso, neck and limb bones (Bend then Twist),
// carpals, three finger joints, metatarsals and toes.
std::vector<Bone> DazGenesisBones() {
  return BothSides({{"hip", "", {0, 100, 0}},
                    {"pelvis", "hip", {0, 98, 0}},
                    {"abdomenLower", "hip", {0, 104, 0}},
                    {"abdomenUpper", "abdomenLower", {0, 114, 0}},
                    {"chestLower", "abdomenUpper", {0, 125, 0}},
                    {"chestUpper", "chestLower", {0, 138, 0}},
                    {"neckLower", "chestUpper", {0, 150, 0}},
                    {"neckUpper", "neckLower", {0, 155, 0}},
                    {"head", "neckUpper", {0, 160, 0}}},
                   [](char side, double k) {
                     const std::string s(1, side == 'L' ? 'l' : 'r');
                     return std::vector<Bone>{
                         {s + "Collar", "chestUpper", S(k, 3, 146, 0)},
                         {s + "ShldrBend", s + "Collar", S(k, 18, 146, 0)},
                         {s + "ShldrTwist", s + "ShldrBend", S(k, 32, 146, 0)},
                         {s + "ForearmBend", s + "ShldrTwist", S(k, 46, 146, 0)},
                         {s + "ForearmTwist", s + "ForearmBend", S(k, 59, 146, 0)},
                         {s + "Hand", s + "ForearmTwist", S(k, 72, 146, 0)},
                         {s + "Thumb1", s + "Hand", S(k, 75, 146, 3)},
                         {s + "Thumb2", s + "Thumb1", S(k, 78, 146, 5)},
                         {s + "Thumb3", s + "Thumb2", S(k, 79, 146, 5.5)},
                         {s + "Thumb3_end", s + "Thumb3", S(k, 80, 146, 6)},
                         {s + "Carpal3", s + "Hand", S(k, 76, 146, 0)},
                         {s + "Mid1", s + "Carpal3", S(k, 81, 146, 0)},
                         {s + "Mid2", s + "Mid1", S(k, 84.5, 146, 0)},
                         {s + "Mid3", s + "Mid2", S(k, 87, 146, 0)},
                         {s + "Mid3_end", s + "Mid3", S(k, 89, 146, 0)},
                         {s + "ThighBend", "pelvis", S(k, 9, 95, 0)},
                         {s + "ThighTwist", s + "ThighBend", S(k, 9, 75, 0)},
                         {s + "Shin", s + "ThighTwist", S(k, 9, 52, 0)},
                         {s + "Foot", s + "Shin", S(k, 9, 8, 0)},
                         {s + "Metatarsals", s + "Foot", S(k, 9, 4, 6)},
                         {s + "Toe", s + "Metatarsals", S(k, 9, 1, 12)},
                         {s + "Toe_end", s + "Toe", S(k, 9, 0, 18)},
                     };
                   });
}

// Mixamo, every name under the namespace `ns` ("mixamorig:" or none).
std::vector<Bone> MixamoBones(const std::string& ns) {
  std::vector<Bone> bones =
      BothSides({{"Hips", "", {0, 100, 0}},
                 {"Spine", "Hips", {0, 110, 0}},
                 {"Spine1", "Spine", {0, 125, 0}},
                 {"Spine2", "Spine1", {0, 138, 0}},
                 {"Neck", "Spine2", {0, 150, 0}},
                 {"Head", "Neck", {0, 160, 0}},
                 {"HeadTop_End", "Head", {0, 178, 0}}},
                [](char side, double k) {
                  const std::string s = side == 'L' ? "Left" : "Right";
                  return std::vector<Bone>{
                      {s + "Shoulder", "Spine2", S(k, 3, 146, 0)},
                      {s + "Arm", s + "Shoulder", S(k, 18, 146, 0)},
                      {s + "ForeArm", s + "Arm", S(k, 46, 146, 0)},
                      {s + "Hand", s + "ForeArm", S(k, 72, 146, 0)},
                      {s + "HandThumb1", s + "Hand", S(k, 75, 146, 3)},
                      {s + "HandThumb2", s + "HandThumb1", S(k, 78, 146, 5)},
                      {s + "HandThumb3", s + "HandThumb2", S(k, 79, 146, 5.5)},
                      {s + "HandThumb4", s + "HandThumb3", S(k, 80, 146, 6)},
                      {s + "HandMiddle1", s + "Hand", S(k, 81, 146, 0)},
                      {s + "HandMiddle2", s + "HandMiddle1", S(k, 84.5, 146, 0)},
                      {s + "HandMiddle3", s + "HandMiddle2", S(k, 87, 146, 0)},
                      {s + "HandMiddle4", s + "HandMiddle3", S(k, 89, 146, 0)},
                      {s + "UpLeg", "Hips", S(k, 9, 95, 0)},
                      {s + "Leg", s + "UpLeg", S(k, 9, 52, 0)},
                      {s + "Foot", s + "Leg", S(k, 9, 8, 0)},
                      {s + "ToeBase", s + "Foot", S(k, 9, 1, 12)},
                      {s + "Toe_End", s + "ToeBase", S(k, 9, 0, 18)},
                  };
                });
  for (Bone& bone : bones) {
    bone.name = ns + bone.name;
    if (!bone.parent.empty()) bone.parent = ns + bone.parent;
  }
  return bones;
}

// MakeHuman's default skeleton as poses/tpose.bvh names it (root behind the
// body, spine05 at the pelvis, neck01-03, clavicle, shoulder01, upperarm01-02,
// lowerarm01-02, wrist, metacarpals, fingers, pelvis.L, upperleg01-02, ...).
std::vector<Bone> MakeHumanBones() {
  return BothSides({{"root", "", {0, 100, -5}},
                    {"spine05", "root", {0, 100, 0}},
                    {"spine04", "spine05", {0, 108, 0}},
                    {"spine03", "spine04", {0, 116, 0}},
                    {"spine02", "spine03", {0, 125, 0}},
                    {"spine01", "spine02", {0, 138, 0}},
                    {"neck01", "spine01", {0, 150, 0}},
                    {"neck02", "neck01", {0, 155, 0}},
                    {"neck03", "neck02", {0, 157.5, 0}},
                    {"head", "neck03", {0, 160, 0}}},
                   [](char side, double k) {
                     const std::string s = side == 'L' ? ".L" : ".R";
                     return std::vector<Bone>{
                         {"clavicle" + s, "spine01", S(k, 3, 146, 0)},
                         {"shoulder01" + s, "clavicle" + s, S(k, 12, 146, 0)},
                         {"upperarm01" + s, "shoulder01" + s, S(k, 18, 146, 0)},
                         {"upperarm02" + s, "upperarm01" + s, S(k, 32, 146, 0)},
                         {"lowerarm01" + s, "upperarm02" + s, S(k, 46, 146, 0)},
                         {"lowerarm02" + s, "lowerarm01" + s, S(k, 59, 146, 0)},
                         {"wrist" + s, "lowerarm02" + s, S(k, 72, 146, 0)},
                         {"finger1-1" + s, "wrist" + s, S(k, 75, 146, 3)},
                         {"finger1-2" + s, "finger1-1" + s, S(k, 78, 146, 5)},
                         {"finger1-3" + s, "finger1-2" + s, S(k, 80, 146, 6)},
                         {"metacarpal2" + s, "wrist" + s, S(k, 76, 146, 0)},
                         {"finger3-1" + s, "metacarpal2" + s, S(k, 81, 146, 0)},
                         {"finger3-2" + s, "finger3-1" + s, S(k, 85, 146, 0)},
                         {"finger3-3" + s, "finger3-2" + s, S(k, 89, 146, 0)},
                         {"pelvis" + s, "root", S(k, 4, 100, 0)},
                         {"upperleg01" + s, "pelvis" + s, S(k, 9, 95, 0)},
                         {"upperleg02" + s, "upperleg01" + s, S(k, 9, 80, 0)},
                         {"lowerleg01" + s, "upperleg02" + s, S(k, 9, 52, 0)},
                         {"lowerleg02" + s, "lowerleg01" + s, S(k, 9, 30, 0)},
                         {"foot" + s, "lowerleg02" + s, S(k, 9, 8, 0)},
                         {"metatarsal3" + s, "foot" + s, S(k, 9, 4, 6)},
                         {"toe3-1" + s, "metatarsal3" + s, S(k, 9, 1, 12)},
                     };
                   });
}

// Rigify limbs, each bone named `prefix` + name ("DEF-" for a generated
// rig's deform bones), split into two halves (".001") when `split`.
std::vector<Bone> RigifyLimbs(char side, double k, const std::string& prefix,
                              const std::string& chest, const std::string& hips, bool split) {
  const std::string s = side == 'L' ? ".L" : ".R";
  const auto n = [&](const std::string& name) { return prefix + name + s; };
  const std::string upper_arm_end = split ? n("upper_arm") + ".001" : n("upper_arm");
  const std::string forearm_end = split ? n("forearm") + ".001" : n("forearm");
  const std::string thigh_end = split ? n("thigh") + ".001" : n("thigh");
  std::vector<Bone> bones = {
      {n("shoulder"), chest, S(k, 3, 146, 0)},
      {n("upper_arm"), n("shoulder"), S(k, 18, 146, 0)},
      {n("forearm"), upper_arm_end, S(k, 46, 146, 0)},
      {n("hand"), forearm_end, S(k, 72, 146, 0)},
      {n("thumb.01"), n("hand"), S(k, 75, 146, 3)},
      {n("thumb.02"), n("thumb.01"), S(k, 78, 146, 5)},
      {n("thumb.03"), n("thumb.02"), S(k, 79, 146, 5.5)},
      {n("thumb.03") + "_end", n("thumb.03"), S(k, 80, 146, 6)},
      {n("palm.03"), n("hand"), S(k, 76, 146, 0)},
      {n("f_middle.01"), n("palm.03"), S(k, 81, 146, 0)},
      {n("f_middle.02"), n("f_middle.01"), S(k, 84.5, 146, 0)},
      {n("f_middle.03"), n("f_middle.02"), S(k, 87, 146, 0)},
      {n("f_middle.03") + "_end", n("f_middle.03"), S(k, 89, 146, 0)},
      {n("thigh"), hips, S(k, 9, 95, 0)},
      {n("shin"), thigh_end, S(k, 9, 52, 0)},
      {n("foot"), n("shin"), S(k, 9, 8, 0)},
      {n("toe"), n("foot"), S(k, 9, 1, 12)},
  };
  if (split) {
    bones.push_back({n("upper_arm") + ".001", n("upper_arm"), S(k, 32, 146, 0)});
    bones.push_back({n("forearm") + ".001", n("forearm"), S(k, 59, 146, 0)});
    bones.push_back({n("thigh") + ".001", n("thigh"), S(k, 9, 75, 0)});
  }
  return bones;
}

// Blender 2.8+ metarig: spine (the pelvis) to spine.006 (the head).
std::vector<Bone> RigifyMetarigBones() {
  return BothSides({{"spine", "", {0, 100, 0}},
                    {"spine.001", "spine", {0, 112, 0}},
                    {"spine.002", "spine.001", {0, 125, 0}},
                    {"spine.003", "spine.002", {0, 138, 0}},
                    {"spine.004", "spine.003", {0, 150, 0}},
                    {"spine.005", "spine.004", {0, 155, 0}},
                    {"spine.006", "spine.005", {0, 160, 0}},
                    {"spine.006_end", "spine.006", {0, 178, 0}}},
                   [](char side, double k) {
                     std::vector<Bone> bones =
                         RigifyLimbs(side, k, "", "spine.003", "spine", false);
                     bones.push_back({std::string("pelvis") + (side == 'L' ? ".L" : ".R"), "spine",
                                      S(k, 4, 100, 0)});  // Not mapped.
                     return bones;
                   });
}

// A generated rig in the older hips/spine/chest/neck/head naming: deform
// bones ("DEF-", split limbs) beside controls with plain names placed
// elsewhere (behind the body), which must not be taken.
std::vector<Bone> RigifyGeneratedBones() {
  return BothSides({{"root", "", {0, 0, 0}},
                    {"hips", "root", {0, 110, -30}},
                    {"chest", "root", {0, 140, -30}},
                    {"neck", "root", {0, 150, -30}},
                    {"head", "root", {0, 170, -30}},
                    {"DEF-hips", "root", {0, 100, 0}},
                    {"DEF-spine", "DEF-hips", {0, 112, 0}},
                    {"DEF-chest", "DEF-spine", {0, 125, 0}},
                    {"DEF-neck", "DEF-chest", {0, 150, 0}},
                    {"DEF-head", "DEF-neck", {0, 160, 0}},
                    {"DEF-head_end", "DEF-head", {0, 178, 0}}},
                   [](char side, double k) {
                     return RigifyLimbs(side, k, "DEF-", "DEF-chest", "DEF-hips", true);
                   });
}

TEST(BvhNaming, DazPoserAsInCmuDazReleaseIsRecognised) {
  ExpectFigure("daz_poser", DazPoserBones(), JointSetId::kDazPoser);
}

TEST(BvhNaming, DazGenesisSplitBonesAreRecognised) {
  ExpectFigure("daz_genesis", DazGenesisBones(), JointSetId::kDazPoser);
}

TEST(BvhNaming, MixamoIsRecognisedWithOrWithoutItsNamespace) {
  ExpectFigure("mixamo_namespace", MixamoBones("mixamorig:"), JointSetId::kMixamo);
  ExpectFigure("mixamo_numbered_namespace", MixamoBones("mixamorig1:"), JointSetId::kMixamo);
  ExpectFigure("mixamo_plain", MixamoBones(""), JointSetId::kMixamo);
}

TEST(BvhNaming, MakeHumanDefaultSkeletonIsRecognised) {
  ExpectFigure("makehuman", MakeHumanBones(), JointSetId::kMakeHuman);
}

TEST(BvhNaming, RigifyMetarigIsRecognised) {
  ExpectFigure("rigify_metarig", RigifyMetarigBones(), JointSetId::kRigify);
}

TEST(BvhNaming, RigifyDeformBonesOfAZUpExportWinOverControls) {
  ExpectFigure("rigify_generated_z_up", RigifyGeneratedBones(), JointSetId::kRigify,
               /*z_up=*/true);
}

TEST(BvhNaming, CmuNamingsStillWinOnTheirOwnFiles) {
  // cgspeed's Motionbuilder release shares most names with Mixamo; its own
  // table still covers more of it.
  const std::string dir = reenact::testing::TestDataPath("mocap/");
  REENACT_REQUIRE_TEST_FILE(dir + "cmu-train/02_01.bvh");
  for (const auto& [file, set] : {std::pair{"cmu/01_01.bvh", JointSetId::kCmuBvhCgspeed},
                                  {"cmu-train/02_01.bvh", JointSetId::kCmuBvhCgspeed},
                                  {"cmu-train/94_01.bvh", JointSetId::kCmuBvh3dsMax},
                                  {"cmu/131_01.bvh", JointSetId::kCmuBvh3dsMax}}) {
    const absl::StatusOr<Motion> motion = ReadBvh(dir + file);
    ASSERT_TRUE(motion.ok()) << motion.status();
    EXPECT_EQ(motion->info().joint_set, set) << file;
    EXPECT_FALSE(motion->info().turned_from_z_up) << file;
  }
}

// A naming no table knows: the Daz figure renamed.
std::vector<Bone> UnknownNamingBones() {
  std::vector<Bone> bones = DazPoserBones();
  const std::map<std::string, std::string> renamed = {
      {"hip", "Pelvis"},          {"chest", "Ribcage"},       {"neck", "NeckBase"},
      {"head", "Skull"},          {"lShldr", "L_UpperArm"},   {"rShldr", "R_UpperArm"},
      {"lForeArm", "L_LowerArm"}, {"rForeArm", "R_LowerArm"}, {"lThigh", "L_UpperLeg"},
      {"rThigh", "R_UpperLeg"},   {"lShin", "L_LowerLeg"},    {"rShin", "R_LowerLeg"},
  };
  for (Bone& bone : bones) {
    if (renamed.count(bone.name)) bone.name = renamed.at(bone.name);
    if (renamed.count(bone.parent)) bone.parent = renamed.at(bone.parent);
  }
  return bones;
}

TEST(BvhNaming, UnknownNamingListsMissingJointsAndNamesSeen) {
  const std::string path = WriteBvhFile("unknown.bvh", UnknownNamingBones(), false);
  const absl::Status status = ReadBvh(path).status();
  ASSERT_EQ(status.code(), absl::StatusCode::kInvalidArgument) << status;
  const std::string message(status.message());
  // The closest naming (Daz) lacks the renamed core joints.
  for (const char* words :
       {"missing Kinect v2 joints: SpineBase, SpineMid, ShoulderLeft, ShoulderRight, ElbowLeft, "
        "ElbowRight, HipLeft, HipRight, KneeLeft, KneeRight",
        "closest naming: daz_poser", "joint names seen (37): Pelvis, abdomen, Ribcage",
        "--joint-map"}) {
    EXPECT_NE(message.find(words), std::string::npos) << words << "\n" << message;
  }
  EXPECT_EQ(message.find(path), 0u) << message;
}

TEST(BvhNaming, JointMapMakesAnUnknownNamingReadable) {
  const std::string map_path =
      reenact::testing::MakeTempDir("joint_naming_map") + "/unknown_map.json";
  std::ofstream(map_path) << R"({"Pelvis": "SpineBase", "Ribcage": "SpineMid",
      "NeckBase": "SpineShoulder", "Skull": "Head", "L_UpperArm": "ShoulderLeft",
      "R_UpperArm": "ShoulderRight", "L_LowerArm": "ElbowLeft", "R_LowerArm": "ElbowRight",
      "L_UpperLeg": "HipLeft", "R_UpperLeg": "HipRight", "L_LowerLeg": "KneeLeft",
      "R_LowerLeg": "KneeRight"})";
  const absl::StatusOr<std::vector<JointMapping>> joint_map = ReadJointMap(map_path);
  ASSERT_TRUE(joint_map.ok()) << joint_map.status();
  ASSERT_EQ(joint_map->size(), 12u);
  // The map places the renamed joints, the Daz table the rest (hands, feet;
  // not Neck, whose half-way point needed "neck" and "head").
  const std::string path = WriteBvhFile("unknown_mapped.bvh", UnknownNamingBones(), false);
  const absl::StatusOr<Motion> motion =
      ReadBvh(path, {.metres_per_unit = kMetresPerCm, .joint_map = *joint_map});
  ASSERT_TRUE(motion.ok()) << motion.status();
  EXPECT_EQ(motion->info().joint_set, JointSetId::kDazPoser);
  const SkeletonPose pose = motion->CanonicalPose(0);
  const std::map<J, V> figure = FigureCm();
  int placed = 0;
  for (const auto& [joint, at_cm] : figure) {
    if (!pose.valid[Index(joint)]) continue;
    ++placed;
    EXPECT_LT((pose.position_m[Index(joint)] - at_cm * kMetresPerCm).norm(), 0.01 * kMm)
        << KinectV2JointName(joint);
  }
  EXPECT_EQ(placed, kNumKinectV2Joints - 1);
  EXPECT_FALSE(pose.valid[Index(J::kNeck)]);

  // The map alone, without any recognised naming: only its own joints.
  std::vector<Bone> bare;
  for (const Bone& bone : UnknownNamingBones()) {
    bare.push_back(bone);
    if (bone.name.find("Thumb") != std::string::npos || bone.name.find("Mid") != std::string::npos)
      bare.back().name = "x" + bone.name;
    if (bone.parent.find("Thumb") != std::string::npos ||
        bone.parent.find("Mid") != std::string::npos)
      bare.back().parent = "x" + bone.parent;
  }
  for (Bone& bone : bare) {
    for (std::string* name : {&bone.name, &bone.parent}) {
      for (const char* daz : {"Collar", "Hand", "Foot", "Buttock", "abdomen", "Eye"}) {
        if (name->find(daz) != std::string::npos) *name = "y" + *name;
      }
    }
  }
  const std::string bare_path = WriteBvhFile("user_map_only.bvh", bare, false);
  const absl::StatusOr<Motion> mapped_only =
      ReadBvh(bare_path, {.metres_per_unit = kMetresPerCm, .joint_map = *joint_map});
  ASSERT_TRUE(mapped_only.ok()) << mapped_only.status();
  EXPECT_EQ(mapped_only->info().joint_set, JointSetId::kUserMap);
  const SkeletonPose mapped_pose = mapped_only->CanonicalPose(0);
  int mapped = 0;
  for (int j = 0; j < kNumKinectV2Joints; ++j) mapped += mapped_pose.valid[j] ? 1 : 0;
  EXPECT_EQ(mapped, 12);
  EXPECT_LT((mapped_pose.position_m[Index(J::kShoulderLeft)] - V(0.18, 1.46, 0)).norm(),
            0.01 * kMm);
}

TEST(MatchJointSet, LongNameListsAreCutAtForty) {
  std::vector<std::string> names;
  std::vector<int> parents;
  for (int i = 0; i < 1000; ++i) {
    names.push_back("bone" + std::to_string(i));
    parents.push_back(i - 1);
  }
  const absl::StatusOr<JointSetMatch> match = MatchJointSet(names, parents, {}, "many.bvh");
  ASSERT_FALSE(match.ok());
  const std::string message(match.status().message());
  EXPECT_NE(message.find("joint names seen (1000): bone0, bone1,"), std::string::npos) << message;
  EXPECT_NE(message.find("bone39, ... and 960 more"), std::string::npos) << message;
  EXPECT_EQ(message.find("bone40"), std::string::npos) << message;
  EXPECT_LT(message.size(), 1200u);
}

TEST(ParseJointMap, BadMapsAreClearErrors) {
  const std::vector<std::pair<std::string, std::string>> cases = {
      {R"({"Pelvis": )", "not valid JSON"},
      {"", "not valid JSON"},
      {std::string("\xff\xfe\x00\x01", 4), "not valid JSON"},
      {"{}", "the joint map is empty"},
      {R"(["Pelvis", "SpineBase"])", "found JSON of type array"},
      {R"("SpineBase")", "found JSON of type string"},
      {R"({"Pelvis": 3})", "'Pelvis' maps to JSON of type number"},
      {R"({"Pelvis": {"to": "SpineBase"}})", "'Pelvis' maps to JSON of type object"},
      {R"({"Pelvis": "Pelvis"})",
       "'Pelvis' maps to 'Pelvis', not a Kinect v2 joint (one of "
       "SpineBase, SpineMid,"},
      {R"({"Pelvis": "spinebase"})", "not a Kinect v2 joint"},
      {R"({"": "SpineBase"})", "an empty joint name"},
      {R"({"a": "Head", "b": "Head"})", "both 'a' and 'b' map to Head"},
      {std::string(200000, '[') + std::string(200000, ']'), "found JSON of type array"},
  };
  for (const auto& [text, words] : cases) {
    const absl::StatusOr<std::vector<JointMapping>> map = ParseJointMap(text, "map.json");
    ASSERT_FALSE(map.ok()) << text.substr(0, 40);
    EXPECT_EQ(map.status().code(), absl::StatusCode::kInvalidArgument);
    const std::string message(map.status().message());
    EXPECT_EQ(message.rfind("map.json: ", 0), 0u) << message;
    EXPECT_NE(message.find(words), std::string::npos) << words << "\n" << message;
  }
  const absl::StatusOr<std::vector<JointMapping>> good =
      ParseJointMap(R"({"Pelvis": "SpineBase", "mixamorig:Head": "Head"})", "map.json");
  ASSERT_TRUE(good.ok()) << good.status();
  ASSERT_EQ(good->size(), 2u);
}

TEST(ReadJointMap, HugeAndUnreadableFilesAreClearErrors) {
  const std::string dir = reenact::testing::MakeTempDir("joint_map_files");
  const std::string huge = dir + "/huge.json";
  {
    std::ofstream out(huge);
    out << "{\"a\": \"" << std::string(kMaxJointMapBytes, 'x') << "\"}";
  }
  absl::Status status = ReadJointMap(huge).status();
  EXPECT_EQ(status.code(), absl::StatusCode::kInvalidArgument) << status;
  EXPECT_NE(std::string(status.message()).find("bytes allowed"), std::string::npos) << status;
  status = ReadJointMap(dir).status();
  EXPECT_NE(std::string(status.message()).find("not a regular file"), std::string::npos) << status;
  status = ReadJointMap(dir + "/absent.json").status();
  EXPECT_EQ(status.code(), absl::StatusCode::kNotFound) << status;
}

}  // namespace
}  // namespace reenact::body
