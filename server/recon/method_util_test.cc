#include "server/recon/method_util.h"

#include <cmath>

#include <gtest/gtest.h>

#include "common/io/proto_convert.h"

namespace reenact::recon {
namespace {

TEST(StageProgress, MapsStagesOntoOneFraction) {
  std::vector<Progress> seen;
  StageProgress stages(
      [&](const Progress& p) {
        seen.push_back(p);
        return true;
      },
      {{"a", 1.0}, {"b", 3.0}});
  EXPECT_TRUE(stages.Report("a", 1, 2).ok());
  EXPECT_TRUE(stages.Report("b", 2, 4).ok());
  EXPECT_TRUE(stages.ForStage("b")({"inner", 1.0, 5, 5}));
  ASSERT_EQ(seen.size(), 3u);
  EXPECT_NEAR(seen[0].fraction, 0.125, 1e-12);
  EXPECT_NEAR(seen[1].fraction, 0.625, 1e-12);
  EXPECT_EQ(seen[2].stage, "b");
  EXPECT_NEAR(seen[2].fraction, 1.0, 1e-12);

  StageProgress cancel([](const Progress&) { return false; }, {{"a", 1.0}});
  EXPECT_EQ(cancel.Report("a", 0, 1).code(), absl::StatusCode::kCancelled);
  StageProgress none({}, {{"a", 1.0}});
  EXPECT_TRUE(none.Report("a", 0, 1).ok());
}

TEST(MakePartFrame, WritesPosesScalesAndFiniteJoints) {
  JointArray joints = MissingJoints();
  joints[body::Index(body::KinectV2Joint::kSpineBase)] = {0, 1, 0};
  joints[body::Index(body::KinectV2Joint::kSpineMid)] = {0, 1.2, 0};
  PartPoses poses;
  poses[2].valid = true;
  poses[2].length_m = 0.2;
  poses[2].world_from_part.translation() = Eigen::Vector3d(0, 1, 0);
  poses[2].world_from_part.linear() =
      Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitY()).toRotationMatrix();
  std::array<double, kNumBodyParts> scales;
  scales.fill(1.0);
  scales[2] = 1.25;
  const ReenactmentFrame frame = MakePartFrame(7, 123, poses, scales, joints);
  EXPECT_EQ(frame.frame_index, 7);
  EXPECT_EQ(frame.stamp_ns, 123);
  ASSERT_EQ(frame.parts.size(), static_cast<size_t>(kNumBodyParts));
  EXPECT_TRUE(frame.parts[2].valid);
  EXPECT_FALSE(frame.parts[0].valid);
  EXPECT_FLOAT_EQ(static_cast<float>(frame.parts[2].scale), 1.25f);
  EXPECT_NEAR(frame.parts[2].world_from_part.translation().y(), 1.0, 1e-12);
  EXPECT_LT((frame.parts[2].world_from_part.linear() - poses[2].world_from_part.linear())
                .cwiseAbs()
                .maxCoeff(),
            1e-12);
  ASSERT_EQ(frame.joints_in_world_m.size(), 25u);
  // SpineShoulder is missing: it takes its parent SpineMid's position.
  const Eigen::Vector3d shoulder =
      frame.joints_in_world_m[body::Index(body::KinectV2Joint::kSpineShoulder)];
  EXPECT_NEAR((shoulder - Eigen::Vector3d(0, 1.2, 0)).norm(), 0.0, 1e-12);
  for (const Eigen::Vector3d& j : frame.joints_in_world_m) EXPECT_TRUE(j.allFinite());
  // No joint at all: none written.
  EXPECT_TRUE(MakePartFrame(0, 0, poses, scales, MissingJoints()).joints_in_world_m.empty());
}

}  // namespace
}  // namespace reenact::recon
