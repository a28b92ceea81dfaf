// The terms of the body fit (body_fit.h) as Ceres cost functions with
// analytic Jacobians of linear blend skinning, and the model arrays they
// share. Exposed for the fitter and for gradient checks in tests.
//
// Parameters: per Kinect v2 joint j an angle-axis a_j (its local rotation
// R_j = exp(a_j), body_model.h), the root translation t (metres), and, when a
// term fits the shape, the shape coefficients beta (K). Forward kinematics:
//   Q_root = R_root,           p_root = J_root + t,
//   Q_j = Q_parent R_j,        p_j = p_parent + Q_parent (J_j - J_parent),
//   y_k(x) = Q_k (x - J_k) + p_k,   v = sum_k w_k y_k(x)
// with rest vertices x = T + S_x beta and rest joints J = J_0 + S_J beta.
// Derivatives: a change da_j turns every joint below j (j included) about
// p_j by omega = Q_j Jr(a_j) da_j (Jr: the right Jacobian of SO(3)), so
//   dv/da_j = -[s_j]_x Q_j Jr(a_j),  s_j = sum_{k below j} w_k (y_k - p_j);
// dv/dt = I; dv/dbeta = sum_k w_k (Q_k (S_x - S_J,k) + dp_k/dbeta) with
// dp_j/dbeta = dp_parent/dbeta + Q_parent (S_J,j - S_J,parent).
#pragma once

#include <array>
#include <memory>
#include <vector>

#include <ceres/ceres.h>
#include <Eigen/Core>

#include "common/body/body_model.h"

namespace reenact::bodyfit {

inline constexpr int kJoints = body::kNumKinectV2Joints;

// Model arrays in the layout the terms need.
class ModelData {
 public:
  explicit ModelData(const body::BodyModel& model);

  int num_vertices() const { return static_cast<int>(template_m.cols()); }
  int num_shape() const { return static_cast<int>(shape_basis.cols()); }

  Eigen::Matrix3Xd template_m;  // T, 3 x V.
  Eigen::MatrixXd shape_basis;  // S_x, 3V x K (rows 3v .. 3v+2 for vertex v).
  std::array<Eigen::Vector3d, kJoints> rest_joints_template_m;  // J_0.
  std::array<Eigen::MatrixXd, kJoints> joint_shape_basis;       // S_J,j: 3 x K.
  std::vector<std::array<int, body::kMaxInfluences>> skin_joints;
  std::vector<std::array<float, body::kMaxInfluences>> skin_weights;
  std::vector<Eigen::Vector3i> triangles;
  std::array<int, kJoints> parent;  // -1 for the root.
  std::array<int, kJoints> parents_first;
  // Joint j's chain: j, its parent, ..., the root.
  std::array<std::vector<int>, kJoints> chain;
  // False for joints whose rotation moves no vertex (no skin weight on them
  // or below them): their parameters are held.
  std::array<bool, kJoints> active;

  // Shaped rest vertices and joints for `shape` (missing coefficients 0).
  void Shaped(const Eigen::VectorXd& shape, Eigen::Matrix3Xd* rest_m,
              std::array<Eigen::Vector3d, kJoints>* rest_joints_m) const;
};

// Rest vertices and joints of one shape (ModelData::Shaped), for terms
// that hold the shape.
struct ShapedRest {
  Eigen::Matrix3Xd vertices_m;
  std::array<Eigen::Vector3d, kJoints> joints_m;
};

// Forward kinematics of one parameter vector.
struct Kinematics {
  std::array<Eigen::Matrix3d, kJoints> world_rotation;  // Q_j.
  std::array<Eigen::Vector3d, kJoints> position_m;      // p_j.
  std::array<Eigen::Matrix3d, kJoints> omega_from_da;   // Q_j Jr(a_j).
  std::array<Eigen::Vector3d, kJoints> rest_joints_m;   // J_j (shaped).
  std::array<Eigen::MatrixXd, kJoints> position_shape;  // dp_j/dbeta (when asked).
};

// `angle_axis[j]` points at joint j's 3 parameters. `shape` (K) may be
// null: then `fixed_rest_joints_m` gives J. With `shape_derivatives`,
// position_shape is filled (shape must be given).
void ComputeKinematics(const ModelData& data, const double* const* angle_axis,
                       const double* translation_m, const double* shape,
                       const std::array<Eigen::Vector3d, kJoints>* fixed_rest_joints_m,
                       bool shape_derivatives, Kinematics* out);

// The posed position of vertex v with rest position `rest_m`.
Eigen::Vector3d PoseVertex(const ModelData& data, const Kinematics& kin, int v,
                           const Eigen::Vector3d& rest_m);

// All posed vertices (3 x V) of shaped rest vertices `rest_m`.
void PoseAllVertices(const ModelData& data, const Kinematics& kin, const Eigen::Matrix3Xd& rest_m,
                     Eigen::Matrix3Xd* posed_m);

// One point-to-plane correspondence: vertex `vertex` against `point_m`
// along `normal` (unit).
struct Correspondence {
  int vertex = 0;
  Eigen::Vector3d point_m;
  Eigen::Vector3d normal;
};

// Point term (Eq. 4.5, point-to-plane, body_fit.h): residual n . (v - z) per
// correspondence, times sqrt(weight). Parameter blocks: 25 joints (3 each),
// translation (3), and the shape (K) when `fixed` is null; otherwise the
// shape is held at `fixed` (which must outlive the term).
ceres::CostFunction* NewPointTerm(const ModelData& data, std::vector<Correspondence> matches,
                                  double weight, const ShapedRest* fixed);

// Skeleton prior: sqrt(weight) (p_j - target_j) for every finite target
// joint. Parameter blocks as NewPointTerm.
ceres::CostFunction* NewSkeletonTerm(const ModelData& data,
                                     const std::array<Eigen::Vector3d, kJoints>& targets_m,
                                     double weight, const ShapedRest* fixed);

// Pose smoothness of one joint (Eq. 4.6): sqrt(weight) (R(a) - R_previous),
// 9 residuals; one parameter block of 3 (autodiff).
ceres::CostFunction* NewSmoothnessTerm(const Eigen::Matrix3d& previous_rotation, double weight);

// Shape prior: sqrt(weight) beta, K residuals; one parameter block of K.
ceres::CostFunction* NewShapePrior(int num_shape, double weight);

}  // namespace reenact::bodyfit
