// What a synthetic take knows about the performance it shows (its
// /ground_truth channels, ground_truth.proto) as plain values: the true
// body's topology and appearance, its posed meshes and its joints, by frame
// index. common/io/take_convert.h reads them from a take file; evaluation
// (clients/view/evaluation.h) measures reenactments against them.
#pragma once

#include <array>
#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "common/body/joint_set.h"
#include "common/model/sensor_calibration.h"

namespace reenact {

// The true body's mesh (one for the whole take) and how it looks.
struct GroundTruthTopology {
  std::string model_name;
  int vertex_count = 0;
  std::vector<Eigen::Vector3i> triangles;  // Over the vertices.
  // Texture coordinates and their triangles (parallel to `triangles`);
  // empty when the take has no appearance.
  std::vector<Eigen::Vector2f> uvs;
  std::vector<Eigen::Vector3i> uv_triangles;
  std::string albedo_png;  // Empty: none.
  // The light the colour was rendered under: the direction towards it
  // (zero: a headlight) and its ambient and diffuse weights.
  Eigen::Vector3d direction_to_light_in_world = Eigen::Vector3d::Zero();
  float ambient = 0.0f;
  float diffuse = 0.0f;
};

using TrueJoints = std::array<Eigen::Vector3d, body::kNumKinectV2Joints>;

struct GroundTruth {
  GroundTruthTopology topology;
  // The posed true mesh (3 x vertex_count, world, metres) of the frames
  // that were asked for.
  std::map<int64_t, Eigen::Matrix3Xd> meshes;
  // The true joints (25 Kinect v2 joints, world, metres) of every frame
  // that has all of them.
  std::map<int64_t, TrueJoints> joints;
  // The take's sensors, by id (where a novel view is placed when the
  // reenactment names none).
  std::vector<SensorCalibration> sensors;
};

}  // namespace reenact
