#include "common/io/take_convert.h"

#include <cmath>
#include <set>
#include <string>

#include <gtest/gtest.h>

#include "common/io/proto_convert.h"
#include "common/io/reenactment_file.h"
#include "common/io/take.h"
#include "common/testing/test_data.h"

namespace reenact {
namespace {

v1::GroundTruthTopology Triangle() {
  v1::GroundTruthTopology topology;
  topology.set_model_name("triangle");
  topology.set_vertex_count(3);
  for (int i : {0, 1, 2}) topology.add_triangle_indices(i);
  topology.set_uvs_f32(PackFloats({0.f, 0.f, 1.f, 0.f, 0.f, 1.f}));
  for (int i : {0, 1, 2}) topology.add_uv_triangle_indices(i);
  *topology.mutable_direction_to_light_in_world() = ToProto(Eigen::Vector3d(0, 1, 0));
  topology.set_ambient(0.25f);
  topology.set_diffuse(0.75f);
  return topology;
}

// A take with one sensor and the ground truth of frames 0..2 of a triangle
// moving up by 1 cm per frame.
std::string WriteTruthTake(const std::string& name, const v1::GroundTruthTopology& topology) {
  const std::string path = testing::MakeTempDir(name) + "/take.mcap";
  v1::TakeInfo info;
  info.set_name(name);
  info.set_fps(30.0);
  info.set_synthetic(true);
  auto writer = TakeWriter::Open(path, info);
  EXPECT_TRUE(writer.ok()) << writer.status();
  if (!writer.ok()) return path;
  v1::SensorCalibration sensor;
  sensor.set_sensor_id("k0");
  *sensor.mutable_world_from_depth() = ToProto(Rigid3d());
  EXPECT_TRUE((*writer)->AddSensor(sensor).ok());
  EXPECT_TRUE((*writer)->WriteGroundTruthTopology(topology).ok());
  for (int f = 0; f < 3; ++f) {
    v1::GroundTruthMesh mesh;
    mesh.set_frame_index(f);
    mesh.set_vertex_count(3);
    const float y = 0.01f * static_cast<float>(f);
    mesh.set_positions_in_world_m_f32(PackFloats({0.f, y, 2.f, 1.f, y, 2.f, 0.f, 1.f + y, 2.f}));
    EXPECT_TRUE((*writer)->WriteGroundTruthMesh(mesh).ok());
    v1::GroundTruthJoints joints;
    joints.set_frame_index(f);
    for (int j = 0; j < body::kNumKinectV2Joints; ++j) {
      *joints.add_positions_in_world_m() = ToProto(Eigen::Vector3d(0.1 * j, y, 2.0));
    }
    EXPECT_TRUE((*writer)->WriteGroundTruthJoints(joints).ok());
  }
  EXPECT_TRUE((*writer)->Close().ok());
  return path;
}

TEST(ReadGroundTruth, ReadsTheTopologyTheAskedMeshesAndEveryFramesJoints) {
  const std::string path = WriteTruthTake("gt_read", Triangle());
  auto take = TakeReader::Open(path);
  ASSERT_TRUE(take.ok()) << take.status();
  auto truth = ReadGroundTruth(**take, {0, 2});
  ASSERT_TRUE(truth.ok()) << truth.status();
  EXPECT_EQ(truth->topology.vertex_count, 3);
  ASSERT_EQ(truth->topology.triangles.size(), 1u);
  ASSERT_EQ(truth->topology.uvs.size(), 3u);
  EXPECT_EQ(truth->topology.uvs[2], Eigen::Vector2f(0.f, 1.f));
  EXPECT_EQ(truth->topology.uv_triangles.size(), 1u);
  EXPECT_EQ(truth->topology.direction_to_light_in_world, Eigen::Vector3d(0, 1, 0));
  EXPECT_FLOAT_EQ(truth->topology.ambient, 0.25f);
  ASSERT_EQ(truth->meshes.size(), 2u) << "only the frames asked for";
  EXPECT_NEAR(truth->meshes.at(2)(1, 0), 0.02, 1e-7);  // Metres.
  ASSERT_EQ(truth->joints.size(), 3u);
  EXPECT_NEAR(truth->joints.at(1)[24].x(), 2.4, 1e-12);
  ASSERT_EQ(truth->sensors.size(), 1u);
  EXPECT_EQ(truth->sensors[0].sensor_id, "k0");

  auto joints_only = ReadGroundTruth(**take, {});
  ASSERT_TRUE(joints_only.ok()) << joints_only.status();
  EXPECT_TRUE(joints_only->meshes.empty());
  EXPECT_EQ(joints_only->joints.size(), 3u);
}

TEST(ReadGroundTruth, BadTopologyIsDataLossAndNoTruthIsFailedPrecondition) {
  v1::GroundTruthTopology out_of_range = Triangle();
  out_of_range.set_triangle_indices(2, 3);
  const std::string bad = WriteTruthTake("gt_bad", out_of_range);
  auto take = TakeReader::Open(bad);
  ASSERT_TRUE(take.ok()) << take.status();
  EXPECT_EQ(ReadGroundTruth(**take, {0}).status().code(), absl::StatusCode::kDataLoss);

  v1::GroundTruthTopology wrong_count = Triangle();
  wrong_count.set_vertex_count(4);  // The meshes hold 3.
  const std::string short_meshes = WriteTruthTake("gt_short", wrong_count);
  auto take2 = TakeReader::Open(short_meshes);
  ASSERT_TRUE(take2.ok()) << take2.status();
  EXPECT_EQ(ReadGroundTruth(**take2, {1}).status().code(), absl::StatusCode::kDataLoss);

  const std::string plain = testing::MakeTempDir("gt_none") + "/take.mcap";
  v1::TakeInfo info;
  info.set_name("plain");
  auto writer = TakeWriter::Open(plain, info);
  ASSERT_TRUE(writer.ok()) << writer.status();
  ASSERT_TRUE((*writer)->Close().ok());
  auto take3 = TakeReader::Open(plain);
  ASSERT_TRUE(take3.ok()) << take3.status();
  EXPECT_EQ(ReadGroundTruth(**take3, {}).status().code(), absl::StatusCode::kFailedPrecondition);
}

}  // namespace
}  // namespace reenact
