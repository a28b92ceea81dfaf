#include "common/body/joint_set.h"

#include <fstream>
#include <iostream>
#include <map>
#include <set>
#include <sstream>
#include <string>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "common/testing/test_data.h"

namespace reenact::body {
namespace {

using J = KinectV2Joint;

constexpr double kMm = 1e-3;

TEST(KinectV2Parent, EveryJointReachesSpineBaseWithoutCycles) {
  for (int j = 0; j < kNumKinectV2Joints; ++j) {
    J joint = static_cast<J>(j);
    int steps = 0;
    while (auto parent = KinectV2Parent(joint)) {
      joint = *parent;
      ASSERT_LT(++steps, kNumKinectV2Joints) << KinectV2JointName(static_cast<J>(j));
    }
    EXPECT_EQ(joint, J::kSpineBase);
  }
  EXPECT_EQ(KinectV2Parent(J::kThumbLeft), J::kWristLeft);
  EXPECT_EQ(KinectV2Parent(J::kShoulderRight), J::kSpineShoulder);
}

TEST(KinectV2JointName, RoundTripsThroughTheName) {
  for (int j = 0; j < kNumKinectV2Joints; ++j) {
    const J joint = static_cast<J>(j);
    EXPECT_EQ(KinectV2JointFromName(KinectV2JointName(joint)), joint);
  }
  EXPECT_EQ(KinectV2JointName(J::kSpineShoulder), "SpineShoulder");
  EXPECT_FALSE(KinectV2JointFromName("Pelvis").has_value());
}

TEST(JointMappingTable, EachTableMapsDistinctJoints) {
  const std::map<JointSetId, int> expected_rows = {
      {JointSetId::kKinectV2, 25},      {JointSetId::kKinectV1, 20},
      {JointSetId::kCmuBvhCgspeed, 25}, {JointSetId::kCmuBvh3dsMax, 25},
      {JointSetId::kCmuAsf, 25},        {JointSetId::kMakeHuman, 25},
  };
  for (const auto& [set, rows] : expected_rows) {
    const std::vector<JointMapping>& table = JointMappingTable(set);
    EXPECT_EQ(static_cast<int>(table.size()), rows) << JointSetName(set);
    std::set<int> targets;
    std::set<std::string> sources;
    for (const JointMapping& row : table) {
      targets.insert(Index(row.target));
      sources.insert(row.source_name);
    }
    EXPECT_EQ(targets.size(), table.size()) << JointSetName(set);
    EXPECT_EQ(sources.size(), table.size()) << JointSetName(set);
  }
}

// Joint names the header of a file declares, as the readers name them.
std::vector<std::string> BvhNames(const std::string& path) {
  std::ifstream in(path);
  std::vector<std::string> names;
  std::string word, last;
  while (in >> word && word != "MOTION") {
    if (last == "ROOT" || last == "JOINT") names.push_back(word);
    if (last == "End") names.push_back(names.back() + "_end");
    last = word;
  }
  return names;
}

TEST(DetectJointSet, RecognisesEachCmuNamingAndKinect) {
  const std::string dir = reenact::testing::TestDataPath("mocap/cmu/");
  REENACT_REQUIRE_TEST_FILE(dir + "01_01.bvh");
  EXPECT_EQ(DetectJointSet(BvhNames(dir + "01_01.bvh")), JointSetId::kCmuBvhCgspeed);
  EXPECT_EQ(DetectJointSet(BvhNames(dir + "131_01.bvh")), JointSetId::kCmuBvh3dsMax);
  EXPECT_EQ(
      DetectJointSet({"root", "lhipjoint", "lfemur", "ltibia", "rfemur", "rtibia", "lowerback",
                      "upperback", "thorax", "lhumerus", "lradius", "rhumerus", "rradius"}),
      JointSetId::kCmuAsf);

  const std::string precog = reenact::testing::TestDataPath("skeleton/precog-kinect1/Seq1_1.csv");
  REENACT_REQUIRE_TEST_FILE(precog);
  std::ifstream in(precog);
  std::string header;
  std::getline(in, header);
  std::vector<std::string> names;
  std::stringstream fields(header);
  for (std::string name; std::getline(fields, name, ';');) {
    name.erase(0, name.find_first_not_of(" \r"));
    name.erase(name.find_last_not_of(" \r") + 1);
    names.push_back(name);
  }
  EXPECT_EQ(DetectJointSet(names), JointSetId::kKinectV1);

  std::vector<std::string> v2;
  for (int j = 0; j < kNumKinectV2Joints; ++j) {
    v2.emplace_back(KinectV2JointName(static_cast<J>(j)));
  }
  EXPECT_EQ(DetectJointSet(v2), JointSetId::kKinectV2);
  EXPECT_FALSE(DetectJointSet({"Hips", "Head", "tail", "wing.L"}).has_value());
}

// MakeHuman joint positions: each named joint is the mean of a group of
// base-mesh vertices (decimetres).
class MakeHumanRig {
 public:
  bool Load() {
    const std::string dir = reenact::testing::TestDataPath("body/makehuman/");
    std::ifstream obj(dir + "3dobjs/base.obj");
    for (std::string line; std::getline(obj, line);) {
      if (line.rfind("v ", 0) != 0) continue;
      std::istringstream in(line.substr(2));
      Eigen::Vector3d v;
      in >> v.x() >> v.y() >> v.z();
      vertices_dm_.push_back(v);
    }
    std::ifstream skel(dir + "rigs/default.mhskel");
    skeleton_ = nlohmann::json::parse(skel, nullptr, false);
    return !vertices_dm_.empty() && !skeleton_.is_discarded();
  }

  bool HasBone(const std::string& bone) const { return skeleton_["bones"].contains(bone); }

  // Position (metres) of the head of `bone`.
  Eigen::Vector3d HeadM(const std::string& bone) const {
    const std::string joint = skeleton_["bones"][bone]["head"];
    Eigen::Vector3d sum_dm = Eigen::Vector3d::Zero();
    int count = 0;
    for (int index : skeleton_["joints"][joint]) {
      sum_dm += vertices_dm_.at(static_cast<size_t>(index));
      ++count;
    }
    return sum_dm / count * 0.1;
  }

 private:
  std::vector<Eigen::Vector3d> vertices_dm_;
  nlohmann::json skeleton_;
};

TEST(JointMappingTable, MakeHumanJointsAreAnatomical) {
  REENACT_REQUIRE_TEST_FILE(reenact::testing::TestDataPath("body/makehuman/rigs/default.mhskel"));
  MakeHumanRig rig;
  ASSERT_TRUE(rig.Load());
  std::map<J, Eigen::Vector3d> at_m;
  for (const JointMapping& row : JointMappingTable(JointSetId::kMakeHuman)) {
    ASSERT_TRUE(rig.HasBone(row.source_name)) << row.source_name;
    at_m[row.target] = rig.HeadM(row.source_name);
  }
  // The model faces +Z with +Y up, so the person's left is +X.
  for (auto [left, right] : {std::pair{J::kShoulderLeft, J::kShoulderRight},
                             {J::kElbowLeft, J::kElbowRight},
                             {J::kWristLeft, J::kWristRight},
                             {J::kHandLeft, J::kHandRight},
                             {J::kHandTipLeft, J::kHandTipRight},
                             {J::kThumbLeft, J::kThumbRight},
                             {J::kHipLeft, J::kHipRight},
                             {J::kKneeLeft, J::kKneeRight},
                             {J::kAnkleLeft, J::kAnkleRight},
                             {J::kFootLeft, J::kFootRight}}) {
    EXPECT_GT(at_m[left].x(), 0.02) << KinectV2JointName(left);
    const Eigen::Vector3d mirrored(-at_m[right].x(), at_m[right].y(), at_m[right].z());
    EXPECT_LT((at_m[left] - mirrored).norm(), 1 * kMm) << KinectV2JointName(left);
  }
  // Chains run in order along the body, each link at least 2 cm long.
  const std::vector<std::vector<J>> chains = {
      {J::kSpineBase, J::kSpineMid, J::kSpineShoulder, J::kNeck, J::kHead},
      {J::kShoulderLeft, J::kElbowLeft, J::kWristLeft, J::kHandLeft, J::kHandTipLeft},
      {J::kHipLeft, J::kKneeLeft, J::kAnkleLeft}};
  for (const std::vector<J>& chain : chains) {
    for (size_t k = 0; k + 2 < chain.size(); ++k) {
      const Eigen::Vector3d a = at_m[chain[k]], b = at_m[chain[k + 1]], c = at_m[chain[k + 2]];
      EXPECT_GT((b - a).norm(), 0.02) << KinectV2JointName(chain[k + 1]);
      // b lies between a and c: it projects inside the segment a-c.
      const double t = (b - a).dot(c - a) / (c - a).squaredNorm();
      EXPECT_GT(t, 0.0) << KinectV2JointName(chain[k + 1]);
      EXPECT_LT(t, 1.0) << KinectV2JointName(chain[k + 1]);
    }
  }
  const double stature_m = at_m[J::kHead].y() - at_m[J::kAnkleLeft].y();
  std::cout << "MakeHuman: ankle to head-joint height " << stature_m << " m\n";
  EXPECT_GT(stature_m, 1.2);
  EXPECT_LT(stature_m, 1.8);
  EXPECT_LT(at_m[J::kFootLeft].y(), at_m[J::kAnkleLeft].y());
  EXPECT_GT(at_m[J::kFootLeft].z(), at_m[J::kAnkleLeft].z() + 0.05);  // Toes point forward.
}

}  // namespace
}  // namespace reenact::body
