// The statistical body model of Reenact, in the SMPL formulation (Loper et
// al., "SMPL: A Skinned Multi-Person Linear Model", SIGGRAPH Asia 2015):
//   T(beta, theta) = T_bar + B_S(beta) + B_P(theta)
//   J(beta)        = R_J * (T_bar + B_S(beta))          (joint regressor)
//   v_i            = sum_j w_ij G_j(theta, J) G_j(0, J)^-1 t_i   (LBS)
// One format, two sources: the procedural template (procedural_body.h) and
// the MakeHuman importer (makehuman_importer.h). The thesis (ch. 4) uses TenBo
// in the same role; see DESIGN.md.
#pragma once

#include <array>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <Eigen/SparseCore>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "common/body/joint_set.h"

namespace reenact::body {

inline constexpr int kMaxInfluences = 4;

struct BodyModel {
  std::string name;  // e.g. "procedural" or "makehuman".

  // Rest-pose template T_bar, metres: +Y up, facing +Z, feet on y = 0. 3 x V.
  Eigen::Matrix3Xd template_vertices_m;
  // Triangles, counter-clockwise seen from outside, indices into the vertices.
  std::vector<Eigen::Vector3i> triangles;
  // Texture coordinates in [0,1]^2 (v up, glTF flips on export) and, per
  // triangle, the indices of its three corners' uvs (seams share positions but
  // not uvs, so the surface stays one closed mesh).
  std::vector<Eigen::Vector2f> uvs;
  std::vector<Eigen::Vector3i> uv_triangles;

  // Joint regressor R_J: kNumKinectV2Joints x V, rows sum to 1. Rest joints =
  // R_J * template^T. The kinematic tree is the Kinect v2 tree (KinectV2Parent).
  Eigen::SparseMatrix<double, Eigen::RowMajor> joint_regressor;

  // Linear blend skinning: up to kMaxInfluences (joint, weight) per vertex,
  // weights >= 0 summing to 1; unused slots have weight 0.
  std::vector<std::array<int, kMaxInfluences>> skin_joints;
  std::vector<std::array<float, kMaxInfluences>> skin_weights;

  // Shape space B_S: shape_directions_m[k] is 3 x V, scaled so that beta_k = 1
  // is one standard deviation of the population it was learned from.
  std::vector<Eigen::Matrix3Xd> shape_directions_m;
  std::vector<std::string> shape_names;  // One per direction (e.g. "pc0", "height").

  // Optional pose correctives B_P (SMPL Eq. 9): 9 * (kNumKinectV2Joints - 1)
  // directions of 3 x V each, driven by (R_j - I) of the non-root joints.
  // Empty when the model has none.
  std::vector<Eigen::Matrix3Xd> pose_correctives_m;

  int num_vertices() const { return static_cast<int>(template_vertices_m.cols()); }
  int num_shape_components() const { return static_cast<int>(shape_directions_m.size()); }
};

// Pose theta: per canonical joint, its rotation relative to the rest pose,
// expressed in the world-aligned rest frame of that joint (SMPL convention:
// G_j = G_parent(j) * [R_j | J_j - J_parent(j)]), plus the world translation
// of the root (SpineBase) joint, metres.
struct BodyPose {
  std::array<Eigen::Quaterniond, kNumKinectV2Joints> local_rotation;
  Eigen::Vector3d root_translation_m{0, 0, 0};
  BodyPose() { local_rotation.fill(Eigen::Quaterniond::Identity()); }
};

struct PosedBody {
  Eigen::Matrix3Xd vertices_m;                                         // 3 x V, world frame.
  std::array<Eigen::Vector3d, kNumKinectV2Joints> joints_m;            // World joint positions.
  std::array<Eigen::Isometry3d, kNumKinectV2Joints> world_from_joint;  // G_j (rest-aligned axes).
};

// Checks sizes, index ranges, weight sums and finiteness; InvalidArgument
// naming the first problem.
absl::Status ValidateBodyModel(const BodyModel& model);

// Shaped rest vertices T_bar + B_S(beta). `shape` may be shorter than the
// number of components (missing ones are 0); longer is InvalidArgument.
absl::StatusOr<Eigen::Matrix3Xd> ShapedRestVertices(const BodyModel& model,
                                                    const Eigen::VectorXd& shape);

// Poses the model: shape blend, joint regression, pose correctives, LBS.
absl::StatusOr<PosedBody> PoseBody(const BodyModel& model, const BodyPose& pose,
                                   const Eigen::VectorXd& shape);

// Linear blend skinning of rest vertices that already carry their shape (and
// correctives) about the rest joints `rest_joints_m`, by per-vertex skinning
// (`skin_joints`/`skin_weights` as in BodyModel, one entry per column of
// `rest_vertices_m`). PoseBody is ShapedRestVertices + RestJointPositions +
// correctives + this. InvalidArgument for mismatched sizes, a bad joint id
// or a non-finite pose.
absl::StatusOr<PosedBody> SkinRestVertices(
    const std::vector<std::array<int, kMaxInfluences>>& skin_joints,
    const std::vector<std::array<float, kMaxInfluences>>& skin_weights,
    const Eigen::Matrix3Xd& rest_vertices_m,
    const std::array<Eigen::Vector3d, kNumKinectV2Joints>& rest_joints_m, const BodyPose& pose);

// Canonical joint ids ordered so that every parent precedes its children
// (SpineBase first), for forward kinematics over the Kinect v2 tree.
const std::array<int, kNumKinectV2Joints>& KinectV2JointsParentsFirst();

// Rest-pose joint positions J(beta) = R_J * (T_bar + B_S(beta)), metres, world
// frame of the template. Errors as for ShapedRestVertices.
absl::StatusOr<std::array<Eigen::Vector3d, kNumKinectV2Joints>> RestJointPositions(
    const BodyModel& model, const Eigen::VectorXd& shape);

// The model file format (".rbm": a small versioned binary); Load validates.
absl::Status SaveBodyModel(const BodyModel& model, const std::string& path);
absl::StatusOr<BodyModel> LoadBodyModel(const std::string& path);

}  // namespace reenact::body
