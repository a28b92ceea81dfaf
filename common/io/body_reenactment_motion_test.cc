#include "common/io/body_reenactment_motion.h"

#include <algorithm>
#include <cstdio>
#include <string>

#include <gtest/gtest.h>

#include "common/io/body_reenactment.h"
#include "common/io/testing/small_reenactment.h"
#include "common/testing/test_data.h"

namespace reenact {
namespace {

// The test body reenactment; frame 5 turns every joint.
ReenactmentData TurnedBody() {
  ReenactmentData data = testing::MakeTestBodyReenactment(6);
  testing::TurnEveryJoint(&data, 5);
  return data;
}

// The joints of `motion` at `frame` in Kinect v2 order, metres.
std::array<Eigen::Vector3d, body::kNumKinectV2Joints> MotionJoints(const body::Motion& motion,
                                                                   int frame) {
  const std::vector<Eigen::Isometry3d> world = motion.WorldFromJoints(frame);
  std::array<Eigen::Vector3d, body::kNumKinectV2Joints> out;
  for (int j = 0; j < body::kNumKinectV2Joints; ++j) {
    const int source = motion.canonical_to_source()[j];
    EXPECT_GE(source, 0) << body::KinectV2JointName(static_cast<body::KinectV2Joint>(j));
    out[j] =
        source >= 0 ? Eigen::Vector3d(world[source].translation()) : Eigen::Vector3d::Constant(NAN);
  }
  return out;
}

// The worst distance, metres, over joints and frames, of `motion`'s joints
// to PoseBodyMesh's.
double WorstJointError(const ReenactmentData& data, const body::Motion& motion) {
  auto mesh = DecodeBodyMesh(data.body[0]);
  EXPECT_TRUE(mesh.ok()) << mesh.status();
  EXPECT_EQ(motion.num_frames(), static_cast<int>(data.frames.size()));
  double worst_m = 0.0;
  for (int f = 0; f < motion.num_frames(); ++f) {
    auto posed = PoseBodyMesh(*mesh, data.frames[f].body());
    EXPECT_TRUE(posed.ok()) << posed.status();
    const auto joints = MotionJoints(motion, f);
    for (int j = 0; j < body::kNumKinectV2Joints; ++j) {
      worst_m = std::max(worst_m, (joints[j] - posed->joints_m[j]).norm());
    }
  }
  return worst_m;
}

TEST(BodyReenactmentMotion, ForwardKinematicsGivesThePosedJoints) {
  const ReenactmentData data = TurnedBody();
  auto motion = BodyReenactmentMotion(testing::ToPlain(data));
  ASSERT_TRUE(motion.ok()) << motion.status();
  ASSERT_EQ(motion->joints().size(), 25u);
  EXPECT_EQ(motion->joints()[0].name, "SpineBase");
  EXPECT_EQ(motion->joints()[0].parent, -1);
  EXPECT_DOUBLE_EQ(motion->fps(), 30.0);
  for (size_t j = 0; j < motion->joints().size(); ++j) {
    EXPECT_LT(motion->joints()[j].parent, static_cast<int>(j)) << "parent after child";
  }
  EXPECT_LT(WorstJointError(data, *motion), 1e-9);
}

// What BVH readers see: ReadBvh of the written file reproduces the posed
// joints of every frame (the BVH convention of rotations in the parent's
// frame meets the BodyPose's world-aligned rest frames).
TEST(BodyReenactmentMotion, WrittenAsBvhReadsBackToThePosedJoints) {
  const ReenactmentData data = TurnedBody();
  auto motion = BodyReenactmentMotion(testing::ToPlain(data));
  ASSERT_TRUE(motion.ok()) << motion.status();
  const std::string path = testing::MakeTempDir("body_bvh") + "/body.bvh";
  ASSERT_TRUE(body::WriteBvh(*motion, path).ok());
  body::BvhOptions options;
  options.metres_per_unit = 0.01;  // WriteBvh's default: centimetres.
  auto read = body::ReadBvh(path, options);
  ASSERT_TRUE(read.ok()) << read.status();
  EXPECT_EQ(read->info().joint_set, body::JointSetId::kKinectV2);
  EXPECT_NEAR(read->fps(), 30.0, 1e-6);
  const double worst_m = WorstJointError(data, *read);
  std::printf("BVH read back: worst joint error %.6f mm over %d frames\n", 1e3 * worst_m,
              read->num_frames());
  EXPECT_LT(worst_m, 0.1e-3);
}

TEST(BodyReenactmentMotion, RigidReenactmentsAreInvalidArgument) {
  EXPECT_EQ(BodyReenactmentMotion(testing::ToPlain(testing::MakeTestReenactment())).status().code(),
            absl::StatusCode::kInvalidArgument);
  Reenactment broken = testing::ToPlain(TurnedBody());
  broken.frames[2].body.reset();
  EXPECT_EQ(BodyReenactmentMotion(broken).status().code(), absl::StatusCode::kInvalidArgument);
}

}  // namespace
}  // namespace reenact
