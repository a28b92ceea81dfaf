#include "common/io/reenactment_convert.h"

#include <gtest/gtest.h>

#include "common/io/body_reenactment.h"
#include "common/io/testing/small_reenactment.h"
#include "common/testing/test_data.h"

namespace reenact {
namespace {

// Largest difference between two quaternions as rotations, radians.
double QuaternionAngle(const v1::Quaternion& a, const v1::Quaternion& b) {
  const Eigen::Quaterniond qa(a.w(), a.x(), a.y(), a.z());
  const Eigen::Quaterniond qb(b.w(), b.x(), b.y(), b.z());
  return qa.normalized().angularDistance(qb.normalized());
}

TEST(ReenactmentConvert, RigidRoundTripKeepsEveryValue) {
  const ReenactmentData original = testing::MakeTestReenactment();
  absl::StatusOr<Reenactment> plain = ReenactmentFromProto(original);
  ASSERT_TRUE(plain.ok()) << plain.status();
  ASSERT_EQ(plain->parts.size(), original.parts.size());
  EXPECT_FALSE(plain->is_body());
  EXPECT_EQ(plain->info.method, "rigid-carved");
  EXPECT_EQ(plain->info.sensors.size(), 1u);
  EXPECT_EQ(plain->parts[0].num_vertices(), 24);
  EXPECT_EQ(plain->parts[0].triangles.size(), 12u);

  const ReenactmentData back = ReenactmentToProto(*plain);
  ASSERT_TRUE(ValidateReenactment(back).ok());
  // Meshes, keyframes and the info come back byte for byte.
  for (size_t p = 0; p < original.parts.size(); ++p) {
    EXPECT_EQ(back.parts[p].SerializeAsString(), original.parts[p].SerializeAsString()) << p;
  }
  for (size_t k = 0; k < original.keyframes.size(); ++k) {
    EXPECT_EQ(back.keyframes[k].SerializeAsString(), original.keyframes[k].SerializeAsString());
  }
  EXPECT_EQ(back.info.method(), original.info.method());
  EXPECT_EQ(back.info.figures().at("registration_rms_mm"), 3.5);
  EXPECT_EQ(back.info.sensors(0).color_intrinsics().width_px(), 64);
  // Poses: the same rotation (to 1e-12 rad) and translation, the same scale.
  ASSERT_EQ(back.frames.size(), original.frames.size());
  for (size_t f = 0; f < original.frames.size(); ++f) {
    for (int p = 0; p < original.frames[f].parts_size(); ++p) {
      const v1::PartPose& a = original.frames[f].parts(p);
      const v1::PartPose& b = back.frames[f].parts(p);
      EXPECT_LT(QuaternionAngle(a.world_from_part().rotation(), b.world_from_part().rotation()),
                1e-12);
      EXPECT_EQ(a.world_from_part().translation_m().x(), b.world_from_part().translation_m().x());
      EXPECT_EQ(a.scale(), b.scale());
      EXPECT_EQ(a.valid(), b.valid());
    }
  }
}

TEST(ReenactmentConvert, BodyRoundTripKeepsMeshPosesAndOffsets) {
  const ReenactmentData original = testing::MakeTestBodyReenactment(3);
  absl::StatusOr<Reenactment> plain = ReenactmentFromProto(original);
  ASSERT_TRUE(plain.ok()) << plain.status();
  ASSERT_TRUE(plain->is_body());
  ASSERT_TRUE(plain->frames[1].body.has_value());
  // Frame 1 carries 5 mm offsets along +Z: 100 steps of 0.05 mm.
  ASSERT_GT(plain->frames[1].body->vertex_offsets_50um.cols(), 0);
  EXPECT_EQ(plain->frames[1].body->vertex_offsets_50um(2, 0), 100);
  EXPECT_NEAR(plain->frames[1].body->OffsetsMetres()(2, 0), 0.005, 1e-12);

  const ReenactmentData back = ReenactmentToProto(*plain);
  ASSERT_TRUE(ValidateReenactment(back).ok());
  EXPECT_EQ(back.body[0].SerializeAsString(), original.body[0].SerializeAsString());
  for (size_t f = 0; f < original.frames.size(); ++f) {
    const v1::BodyPose& a = original.frames[f].body();
    const v1::BodyPose& b = back.frames[f].body();
    EXPECT_EQ(a.vertex_offsets_50um_i16(), b.vertex_offsets_50um_i16()) << f;
    for (int j = 0; j < a.local_rotations_size(); ++j) {
      EXPECT_LT(QuaternionAngle(a.local_rotations(j), b.local_rotations(j)), 1e-12);
    }
    EXPECT_EQ(a.valid(), b.valid());
  }
  // The posed body is the same through either type.
  absl::StatusOr<DecodedBodyMesh> mesh = DecodeBodyMesh(original.body[0]);
  ASSERT_TRUE(mesh.ok());
  absl::StatusOr<body::PosedBody> from_proto = PoseBodyMesh(*mesh, original.frames[1].body());
  absl::StatusOr<body::PosedBody> from_plain = PoseBodyMesh(*plain->body, *plain->frames[1].body);
  ASSERT_TRUE(from_proto.ok() && from_plain.ok());
  EXPECT_LT((from_proto->vertices_m - from_plain->vertices_m).cwiseAbs().maxCoeff(), 1e-12);
}

TEST(ReenactmentConvert, FileRoundTripThroughPlainTypes) {
  const std::string path = testing::MakeTempDir("reen_convert") + "/r.reen";
  absl::StatusOr<Reenactment> plain = ReenactmentFromProto(testing::MakeTestReenactment());
  ASSERT_TRUE(plain.ok());
  ASSERT_TRUE(WriteReenactment(*plain, path).ok());
  absl::StatusOr<Reenactment> read = ReadReenactment(path);
  ASSERT_TRUE(read.ok()) << read.status();
  EXPECT_EQ(read->frames.size(), plain->frames.size());
  EXPECT_EQ(read->keyframes.size(), plain->keyframes.size());
  EXPECT_TRUE(read->parts[1].positions_in_part_m.isApprox(plain->parts[1].positions_in_part_m));
  absl::StatusOr<Reenactment> no_keyframes = ReadReenactment(path, /*skip_keyframes=*/true);
  ASSERT_TRUE(no_keyframes.ok());
  EXPECT_TRUE(no_keyframes->keyframes.empty());
}

TEST(ReenactmentConvert, BadInputIsInvalidArgumentNotACrash) {
  ReenactmentData bad_sensor = testing::MakeTestReenactment();
  bad_sensor.info.mutable_sensors(0)->mutable_world_from_depth()->mutable_rotation()->set_w(NAN);
  absl::StatusOr<Reenactment> plain = ReenactmentFromProto(bad_sensor);
  ASSERT_FALSE(plain.ok());
  EXPECT_EQ(plain.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_NE(plain.status().message().find("world_from_depth"), std::string::npos);

  ReenactmentData short_mesh = testing::MakeTestReenactment();
  short_mesh.parts[0].mutable_positions_in_part_m_f32()->resize(7);
  EXPECT_EQ(ReenactmentFromProto(short_mesh).status().code(), absl::StatusCode::kInvalidArgument);

  EXPECT_EQ(ReadReenactment("/nonexistent/r.reenactment").status().code(),
            absl::StatusCode::kNotFound);
}

}  // namespace
}  // namespace reenact
