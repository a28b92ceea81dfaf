#include <fstream>
#include <sstream>
#include <string>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "clients/cli/commands.h"
#include "common/body/motion.h"
#include "common/testing/test_data.h"

namespace reenact::cli {
namespace {

std::string Cmu(const std::string& name) {
  return reenact::testing::TestDataPath("mocap/cmu/" + name);
}

// The frame count that the "Frames:" line of a BVH file declares.
int DeclaredFrames(const std::string& path) {
  std::ifstream in(path);
  std::string word;
  while (in >> word) {
    if (word == "Frames:") {
      int frames = -1;
      in >> frames;
      return frames;
    }
  }
  return -1;
}

TEST(RunMotionInfo, ReportsFramesRateJointsAndUnit) {
  const std::string path = Cmu("01_01.bvh");
  REENACT_REQUIRE_TEST_FILE(path);
  std::ostringstream out, err;
  ASSERT_EQ(RunMotionInfo({path, "--json"}, out, err), kExitOk) << err.str();
  const nlohmann::json info = nlohmann::json::parse(out.str());
  EXPECT_EQ(info["frames"].get<int>(), DeclaredFrames(path));
  EXPECT_NEAR(info["fps"].get<double>(), 120.0, 0.01);  // Frame Time .0083333 s.
  EXPECT_NEAR(info["duration_s"].get<double>(), DeclaredFrames(path) / 120.0, 0.01);
  EXPECT_EQ(info["joint_set"], "cmu_bvh_cgspeed");
  EXPECT_EQ(info["unit_source"], "detected_from_stature");
  EXPECT_EQ(info["joint_count"].get<size_t>(), info["joints"].size());
  EXPECT_EQ(info["joints"][0], "Hips");
  // The detected unit makes the rest pose 1.7 m tall: CMU units are ~6 cm.
  EXPECT_NEAR(info["metres_per_unit"].get<double>(), 0.06, 0.01);
}

TEST(RunMotionInfo, AmcNeedsItsSkeleton) {
  REENACT_REQUIRE_TEST_FILE(Cmu("07_05-walk.amc"));
  std::ostringstream out, err;
  EXPECT_EQ(RunMotionInfo({Cmu("07_05-walk.amc")}, out, err), kExitUsage);
  EXPECT_NE(err.str().find("--asf"), std::string::npos) << err.str();
  std::ostringstream out2, err2;
  ASSERT_EQ(RunMotionInfo({Cmu("07_05-walk.amc"), "--asf", Cmu("07-walk.asf")}, out2, err2),
            kExitOk)
      << err2.str();
  EXPECT_NE(out2.str().find("asf_header"), std::string::npos) << out2.str();
  EXPECT_NE(out2.str().find("frames:          517"), std::string::npos) << out2.str();
}

TEST(RunMotionJoints, MatchesCanonicalPoseWithinOneMicrometre) {
  const std::string path = Cmu("07_05-walk.amc");
  REENACT_REQUIRE_TEST_FILE(path);
  std::ostringstream out, err;
  ASSERT_EQ(
      RunMotionJoints({path, "--asf", Cmu("07-walk.asf"), "--frame", "42", "--json"}, out, err),
      kExitOk)
      << err.str();
  const nlohmann::json result = nlohmann::json::parse(out.str());
  EXPECT_EQ(result["frame"].get<int>(), 42);
  EXPECT_EQ(result["units"], "m");
  auto motion = body::ReadAsfAmc(Cmu("07-walk.asf"), path);
  ASSERT_TRUE(motion.ok()) << motion.status();
  const body::SkeletonPose pose = motion->CanonicalPose(42);
  ASSERT_EQ(result["joints"].size(), static_cast<size_t>(body::kNumKinectV2Joints));
  for (int j = 0; j < body::kNumKinectV2Joints; ++j) {
    const std::string name(body::KinectV2JointName(static_cast<body::KinectV2Joint>(j)));
    ASSERT_TRUE(result["joints"].contains(name)) << name;
    const nlohmann::json& xyz = result["joints"][name];
    for (int k = 0; k < 3; ++k) {
      EXPECT_NEAR(xyz[k].get<double>(), pose.position_m[j][k], 1e-6) << name;  // metres
    }
  }
}

TEST(RunMotionJoints, FrameOutOfRangeIsAUsageError) {
  const std::string path = Cmu("131_01.bvh");
  REENACT_REQUIRE_TEST_FILE(path);
  const int frames = DeclaredFrames(path);
  std::ostringstream out, err;
  EXPECT_EQ(RunMotionJoints({path, "--frame", std::to_string(frames), "--json"}, out, err),
            kExitUsage);
  EXPECT_NE(err.str().find("out of range"), std::string::npos) << err.str();
  EXPECT_NE(err.str().find(std::to_string(frames) + " frames"), std::string::npos) << err.str();
  std::ostringstream out2, err2;
  EXPECT_EQ(RunMotionJoints({path, "--json"}, out2, err2), kExitUsage);  // No --frame.
  std::ostringstream out3, err3;
  EXPECT_EQ(RunMotionJoints({path, "--frame", std::to_string(frames - 1), "--json"}, out3, err3),
            kExitOk)
      << err3.str();
}

TEST(RunMotionJoints, UnreadableFileIsAFailure) {
  const std::string missing = reenact::testing::MakeTempDir("cli_motion") + "/absent.bvh";
  std::ostringstream out, err;
  EXPECT_EQ(RunMotionJoints({missing, "--frame", "0", "--json"}, out, err), kExitFailure);
  EXPECT_NE(err.str().find(missing), std::string::npos) << err.str();
  EXPECT_TRUE(out.str().empty());
}

}  // namespace
}  // namespace reenact::cli
