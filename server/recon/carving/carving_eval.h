// Test helpers: accuracy of a carved reenactment against the ground truth of
// a synthetic take (common/synth): distances between the posed part meshes
// and the true body surface, and between the registered part frames and the
// true joints.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "absl/status/statusor.h"
#include "common/body/joint_set.h"
#include "common/geometry/surface_distance.h"
#include "common/io/proto_convert.h"
#include "common/io/take.h"
#include "common/model/reenactment.h"
#include "server/recon/body_parts.h"
#include "server/recon/take_frames.h"
#include "server/recon/texturing.h"

namespace reenact::recon::carving::testing {

// Distance from points to a triangle mesh (common/geometry's exact index),
// clamped at 4 cells (16 cm): farther points count as that far, so that a
// stray part does not swamp the mean.
class SurfaceDistance {
 public:
  SurfaceDistance(const std::vector<Eigen::Vector3d>& vertices,
                  const std::vector<Eigen::Vector3i>& triangles, double cell_m = 0.04)
      : clamp_m_(4 * cell_m) {
    Eigen::Matrix3Xd matrix(3, static_cast<Eigen::Index>(vertices.size()));
    for (size_t v = 0; v < vertices.size(); ++v)
      matrix.col(static_cast<Eigen::Index>(v)) = vertices[v];
    absl::StatusOr<TriangleSurfaceIndex> index =
        TriangleSurfaceIndex::Build(matrix, triangles, cell_m);
    if (index.ok()) index_.emplace(*std::move(index));
  }

  // Distance from `p` to the nearest triangle, metres, at most the clamp
  // (also for an empty or invalid mesh).
  double Distance(const Eigen::Vector3d& p) const {
    return index_.has_value() ? std::min(index_->Distance(p), clamp_m_) : clamp_m_;
  }

 private:
  std::optional<TriangleSurfaceIndex> index_;
  double clamp_m_;
};

// Ground truth of a synthetic take, by frame index (synthetic takes group
// their instants by frame index, so it is also the instant index).
struct Truth {
  std::vector<Eigen::Vector3i> triangles;
  std::map<int64_t, std::vector<Eigen::Vector3d>> mesh_by_frame;
  std::map<int64_t, JointArray> joints_by_frame;
};

inline absl::StatusOr<Truth> ReadTruth(const std::string& path) {
  ASSIGN_OR_RETURN(std::unique_ptr<TakeReader> reader, TakeReader::Open(path));
  Truth truth;
  ASSIGN_OR_RETURN(auto topology,
                   reader->ReadAll<v1::GroundTruthTopology>(kGroundTruthTopologyTopic));
  if (topology.empty()) return absl::NotFoundError("no ground-truth topology");
  for (int i = 0; i + 2 < topology[0].triangle_indices_size(); i += 3) {
    truth.triangles.emplace_back(topology[0].triangle_indices(i),
                                 topology[0].triangle_indices(i + 1),
                                 topology[0].triangle_indices(i + 2));
  }
  ASSIGN_OR_RETURN(auto meshes, reader->ReadAll<v1::GroundTruthMesh>(kGroundTruthMeshTopic));
  for (const v1::GroundTruthMesh& mesh : meshes) {
    ASSIGN_OR_RETURN(std::vector<float> values, UnpackFloats(mesh.positions_in_world_m_f32()));
    std::vector<Eigen::Vector3d>& vertices = truth.mesh_by_frame[mesh.frame_index()];
    for (size_t v = 0; v + 2 < values.size(); v += 3) {
      vertices.emplace_back(values[v], values[v + 1], values[v + 2]);
    }
  }
  ASSIGN_OR_RETURN(auto joints, reader->ReadAll<v1::GroundTruthJoints>(kGroundTruthJointsTopic));
  for (const v1::GroundTruthJoints& g : joints) {
    JointArray array = MissingJoints();
    for (int i = 0; i < g.joint_names_size() && i < g.positions_in_world_m_size(); ++i) {
      if (auto joint = body::KinectV2JointFromName(g.joint_names(i))) {
        array[body::Index(*joint)] = FromProto(g.positions_in_world_m(i));
      }
    }
    truth.joints_by_frame[g.frame_index()] = array;
  }
  return truth;
}

struct CarvedAccuracy {
  int frames = 0;
  // Posed carved vertices to the true surface, mm: mean and 90th percentile.
  double mean_mm = 0.0;
  double p90_mm = 0.0;
  std::array<double, kNumBodyParts> part_mean_mm{};
  // True vertices to the posed carved surface (completeness), mm.
  double truth_to_carved_mm = 0.0;
  // Registered part frames against the true joints: the frame origin vs the
  // proximal joint and (0, L, 0) vs the distal joint, mm; the same for the
  // fused sensor skeleton the method starts from.
  double joint_error_mm = 0.0;
  double skeleton_joint_error_mm = 0.0;
};

// Compares every `stride`-th frame of `data` with the truth.
inline absl::StatusOr<CarvedAccuracy> Evaluate(const Reenactment& data, const Truth& truth,
                                               int stride) {
  CarvedAccuracy accuracy;
  const std::vector<PartMesh>& parts = data.parts;
  std::vector<double> distances;
  std::array<double, kNumBodyParts> part_sum{};
  std::array<int64_t, kNumBodyParts> part_count{};
  double completeness_sum = 0.0;
  int64_t completeness_count = 0;
  double joint_sum = 0.0, skeleton_sum = 0.0;
  int64_t joint_count = 0;
  for (size_t f = 0; f < data.frames.size(); f += stride) {
    const ReenactmentFrame& frame = data.frames[f];
    auto mesh = truth.mesh_by_frame.find(frame.frame_index);
    auto joints = truth.joints_by_frame.find(frame.frame_index);
    if (mesh == truth.mesh_by_frame.end() || joints == truth.joints_by_frame.end()) continue;
    ++accuracy.frames;
    const SurfaceDistance truth_surface(mesh->second, truth.triangles);
    const std::vector<reenact::PartPose>& poses = frame.parts;
    std::vector<Eigen::Vector3d> carved_vertices;
    std::vector<Eigen::Vector3i> carved_triangles;
    JointArray fused = MissingJoints();
    for (size_t j = 0; j < frame.joints_in_world_m.size() && j < fused.size(); ++j) {
      fused[j] = frame.joints_in_world_m[j];
    }
    for (int p = 0; p < kNumBodyParts; ++p) {
      if (!poses[p].valid) continue;
      // Scaled parts (rigid-cylinders) too; carved parts have scale 1.
      const Eigen::Affine3d world_from_part = poses[p].WorldFromPartScaled();
      const int base = static_cast<int>(carved_vertices.size());
      for (Eigen::Index v = 0; v < parts[p].positions_in_part_m.cols(); ++v) {
        const Eigen::Vector3d world =
            world_from_part * parts[p].positions_in_part_m.col(v).cast<double>();
        carved_vertices.push_back(world);
        const double d = truth_surface.Distance(world);
        distances.push_back(d);
        part_sum[p] += d;
        ++part_count[p];
      }
      for (const Eigen::Vector3i& t : parts[p].triangles) {
        carved_triangles.push_back(t + Eigen::Vector3i::Constant(base));
      }
      const BodyPartInfo& info = BodyParts()[p];
      const Eigen::Vector3d& proximal = joints->second[body::Index(info.proximal)];
      const Eigen::Vector3d& distal = joints->second[body::Index(info.distal)];
      const double length = data.parts[p].reference_length_m;
      joint_sum += (world_from_part * Eigen::Vector3d::Zero() - proximal).norm() +
                   (world_from_part * Eigen::Vector3d(0, length, 0) - distal).norm();
      skeleton_sum += (fused[body::Index(info.proximal)] - proximal).norm() +
                      (fused[body::Index(info.distal)] - distal).norm();
      joint_count += 2;
    }
    const SurfaceDistance carved_surface(carved_vertices, carved_triangles);
    for (size_t v = 0; v < mesh->second.size(); v += 4) {
      completeness_sum += carved_surface.Distance(mesh->second[v]);
      ++completeness_count;
    }
  }
  if (distances.empty()) return absl::NotFoundError("no frame matched the ground truth");
  double sum = 0.0;
  for (double d : distances) sum += d;
  accuracy.mean_mm = 1e3 * sum / distances.size();
  std::nth_element(distances.begin(), distances.begin() + distances.size() * 9 / 10,
                   distances.end());
  accuracy.p90_mm = 1e3 * distances[distances.size() * 9 / 10];
  for (int p = 0; p < kNumBodyParts; ++p) {
    accuracy.part_mean_mm[p] = part_count[p] ? 1e3 * part_sum[p] / part_count[p] : 0.0;
  }
  accuracy.truth_to_carved_mm = 1e3 * completeness_sum / std::max<int64_t>(1, completeness_count);
  accuracy.joint_error_mm = 1e3 * joint_sum / std::max<int64_t>(1, joint_count);
  accuracy.skeleton_joint_error_mm = 1e3 * skeleton_sum / std::max<int64_t>(1, joint_count);
  return accuracy;
}

}  // namespace reenact::recon::carving::testing
