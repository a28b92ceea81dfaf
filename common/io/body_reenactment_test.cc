#include "common/io/body_reenactment.h"

#include <string>

#include <gtest/gtest.h>

#include "common/io/reenactment_file.h"
#include "common/io/testing/small_reenactment.h"
#include "common/testing/test_data.h"

namespace reenact {
namespace {

using testing::MakeTestBodyReenactment;
using testing::TestBodyModel;
using testing::TestBodyPose;

// Posing the stored mesh reproduces posing the model it was made from: the
// shape folded into the rest vertices and joints, float32 storage aside.
TEST(BodyReenactment, PosedMeshMatchesTheModelWithin0p01Mm) {
  const body::BodyModel& model = TestBodyModel();
  Eigen::VectorXd shape(2);
  shape << 0.5, -0.5;
  auto mesh = MakeBodyMesh(model, shape, "");
  ASSERT_TRUE(mesh.ok()) << mesh.status();
  auto decoded = DecodeBodyMesh(*mesh);
  ASSERT_TRUE(decoded.ok()) << decoded.status();
  ASSERT_EQ(decoded->num_vertices(), model.num_vertices());
  EXPECT_GE(decoded->texture_vertex_source.size(), static_cast<size_t>(model.num_vertices()));
  for (int f : {0, 3, 7}) {
    const body::BodyPose pose = TestBodyPose(f);
    auto expected = body::PoseBody(model, pose, shape);
    ASSERT_TRUE(expected.ok());
    auto got = PoseBodyMesh(*decoded, BodyPoseToProto(pose));
    ASSERT_TRUE(got.ok()) << got.status();
    const double worst_mm =
        1000.0 * (got->vertices_m - expected->vertices_m).colwise().norm().maxCoeff();
    EXPECT_LT(worst_mm, 0.01) << "frame " << f;
    for (int j = 0; j < body::kNumKinectV2Joints; ++j) {
      EXPECT_LT(1000.0 * (got->joints_m[j] - expected->joints_m[j]).norm(), 0.01);
    }
  }
}

TEST(BodyReenactment, OffsetsAreAddedToTheSkinnedVertices) {
  const ReenactmentData data = MakeTestBodyReenactment(3);
  auto decoded = DecodeBodyMesh(data.body.front());
  ASSERT_TRUE(decoded.ok());
  v1::BodyPose plain = data.frames[1].body();
  plain.clear_vertex_offsets_50um_i16();
  auto with = PoseBodyMesh(*decoded, data.frames[1].body());
  auto without = PoseBodyMesh(*decoded, plain);
  ASSERT_TRUE(with.ok() && without.ok());
  const Eigen::Matrix3Xd d = with->vertices_m - without->vertices_m;
  EXPECT_NEAR(1000.0 * d.row(2).minCoeff(), 5.0, 1e-3);
  EXPECT_NEAR(1000.0 * d.row(2).maxCoeff(), 5.0, 1e-3);
  EXPECT_NEAR(1000.0 * d.topRows(2).cwiseAbs().maxCoeff(), 0.0, 1e-3);
}

TEST(BodyReenactment, FileRoundTripKeepsEveryMessage) {
  const std::string path = testing::MakeTempDir("body_reen") + "/b.reen";
  const ReenactmentData data = MakeTestBodyReenactment(6);
  ASSERT_TRUE(WriteReenactmentFile(data, path).ok());
  auto read = ReadReenactmentFile(path);
  ASSERT_TRUE(read.ok()) << read.status();
  ASSERT_TRUE(read->is_body());
  EXPECT_EQ(read->body.front().SerializeAsString(), data.body.front().SerializeAsString());
  ASSERT_EQ(read->frames.size(), data.frames.size());
  for (size_t f = 0; f < data.frames.size(); ++f) {
    EXPECT_EQ(read->frames[f].SerializeAsString(), data.frames[f].SerializeAsString());
  }
}

TEST(BodyReenactment, BadMeshesAndPosesAreInvalidArgument) {
  const ReenactmentData good = MakeTestBodyReenactment(2);
  ASSERT_TRUE(ValidateReenactment(good).ok());
  {
    ReenactmentData bad = good;
    bad.body.front().mutable_skin_joints_u8()->resize(7);
    EXPECT_EQ(ValidateReenactment(bad).code(), absl::StatusCode::kInvalidArgument);
  }
  {
    ReenactmentData bad = good;
    bad.body.front().set_triangle_indices(0, 1u << 30);
    EXPECT_EQ(ValidateReenactment(bad).code(), absl::StatusCode::kInvalidArgument);
  }
  {
    ReenactmentData bad = good;
    bad.frames[0].mutable_body()->mutable_local_rotations(3)->set_w(std::nan(""));
    const absl::Status status = ValidateReenactment(bad);
    EXPECT_EQ(status.code(), absl::StatusCode::kInvalidArgument);
    EXPECT_NE(status.message().find("frame 0"), std::string::npos) << status;
  }
  {
    ReenactmentData bad = good;
    bad.frames[1].mutable_body()->mutable_vertex_offsets_50um_i16()->resize(12);
    EXPECT_EQ(ValidateReenactment(bad).code(), absl::StatusCode::kInvalidArgument);
  }
  {
    ReenactmentData bad = good;
    bad.frames[0].clear_body();
    EXPECT_EQ(ValidateReenactment(bad).code(), absl::StatusCode::kInvalidArgument);
  }
  {
    ReenactmentData bad = good;
    bad.info.add_part_names("head");
    EXPECT_EQ(ValidateReenactment(bad).code(), absl::StatusCode::kInvalidArgument);
  }
}

}  // namespace
}  // namespace reenact
