#include "common/bodyfit/body_terms.h"

#include <cmath>
#include <utility>

#include <ceres/rotation.h>

#include "common/body/joint_set.h"

namespace reenact::bodyfit {
namespace {

Eigen::Matrix3d Skew(const Eigen::Vector3d& v) {
  Eigen::Matrix3d m;
  m << 0, -v.z(), v.y(), v.z(), 0, -v.x(), -v.y(), v.x(), 0;
  return m;
}

// Right Jacobian of the SO(3) exponential: exp(a + da) ~ exp(a) exp(Jr(a) da).
Eigen::Matrix3d RightJacobian(const Eigen::Vector3d& a) {
  const double theta2 = a.squaredNorm();
  const Eigen::Matrix3d k = Skew(a);
  if (theta2 < 1e-10) return Eigen::Matrix3d::Identity() - 0.5 * k + k * k / 6.0;
  const double theta = std::sqrt(theta2);
  return Eigen::Matrix3d::Identity() - (1.0 - std::cos(theta)) / theta2 * k +
         (theta - std::sin(theta)) / (theta2 * theta) * k * k;
}

Eigen::Matrix3d Exp(const Eigen::Vector3d& a) {
  const double theta = a.norm();
  if (theta < 1e-12) return Eigen::Matrix3d::Identity() + Skew(a);
  return Eigen::AngleAxisd(theta, a / theta).toRotationMatrix();
}

// Shared by the point and skeleton terms: kinematics of the parameters,
// with the shape either free or fixed.
class SkinnedTerm : public ceres::CostFunction {
 public:
  SkinnedTerm(const ModelData& data, const ShapedRest* fixed)
      : data_(data), fit_shape_(fixed == nullptr && data.num_shape() > 0), fixed_(fixed) {
    // Blocks: 25 joints, translation, [shape].
    std::vector<int32_t>* sizes = mutable_parameter_block_sizes();
    sizes->assign(kJoints, 3);
    sizes->push_back(3);
    if (fit_shape_) sizes->push_back(data.num_shape());
    if (!fit_shape_ && fixed_ == nullptr) {  // A model without shape directions.
      own_ = std::make_unique<ShapedRest>();
      data.Shaped(Eigen::VectorXd(), &own_->vertices_m, &own_->joints_m);
      fixed_ = own_.get();
    }
  }

 protected:
  void Kinematic(double const* const* parameters, bool shape_derivatives, Kinematics* kin) const {
    ComputeKinematics(
        data_, parameters, parameters[kJoints], fit_shape_ ? parameters[kJoints + 1] : nullptr,
        fit_shape_ ? nullptr : &fixed_->joints_m, fit_shape_ && shape_derivatives, kin);
  }
  Eigen::Vector3d Rest(int v, double const* const* parameters) const {
    if (!fit_shape_) return fixed_->vertices_m.col(v);
    const Eigen::Map<const Eigen::VectorXd> beta(parameters[kJoints + 1], data_.num_shape());
    return data_.template_m.col(v) + data_.shape_basis.middleRows<3>(3 * v) * beta;
  }

  const ModelData& data_;
  const bool fit_shape_;
  const ShapedRest* fixed_;
  std::unique_ptr<ShapedRest> own_;
};

class PointTerm final : public SkinnedTerm {
 public:
  PointTerm(const ModelData& data, std::vector<Correspondence> matches, double weight,
            const ShapedRest* fixed)
      : SkinnedTerm(data, fixed), matches_(std::move(matches)), sqrt_weight_(std::sqrt(weight)) {
    set_num_residuals(static_cast<int>(matches_.size()));
  }

  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override {
    const int n = static_cast<int>(matches_.size());
    const bool shape_jacobian = fit_shape_ && jacobians && jacobians[kJoints + 1];
    Kinematics kin;
    Kinematic(parameters, shape_jacobian, &kin);
    if (jacobians) {
      for (int j = 0; j < kJoints; ++j) {
        if (jacobians[j]) std::fill(jacobians[j], jacobians[j] + 3 * n, 0.0);
      }
    }
    const int k_shape = data_.num_shape();
    std::array<Eigen::Vector3d, kJoints> s;
    std::array<bool, kJoints> touched{};
    for (int i = 0; i < n; ++i) {
      const Correspondence& m = matches_[i];
      const Eigen::Vector3d x = Rest(m.vertex, parameters);
      std::array<Eigen::Vector3d, body::kMaxInfluences> y;
      Eigen::Vector3d v = Eigen::Vector3d::Zero();
      for (int c = 0; c < body::kMaxInfluences; ++c) {
        const double w = data_.skin_weights[m.vertex][c];
        if (w == 0.0) continue;
        const int k = data_.skin_joints[m.vertex][c];
        y[c] = kin.world_rotation[k] * (x - kin.rest_joints_m[k]) + kin.position_m[k];
        v += w * y[c];
      }
      residuals[i] = sqrt_weight_ * m.normal.dot(v - m.point_m);
      if (!jacobians) continue;
      touched.fill(false);
      for (int c = 0; c < body::kMaxInfluences; ++c) {
        const double w = data_.skin_weights[m.vertex][c];
        if (w == 0.0) continue;
        for (int j : data_.chain[data_.skin_joints[m.vertex][c]]) {
          if (!touched[j]) s[j].setZero();
          touched[j] = true;
          s[j] += w * (y[c] - kin.position_m[j]);
        }
      }
      for (int j = 0; j < kJoints; ++j) {
        if (!touched[j] || !jacobians[j]) continue;
        const Eigen::RowVector3d row =
            sqrt_weight_ * s[j].cross(m.normal).transpose() * kin.omega_from_da[j];
        Eigen::Map<Eigen::RowVector3d>(jacobians[j] + 3 * i) = row;
      }
      if (jacobians[kJoints]) {
        Eigen::Map<Eigen::RowVector3d>(jacobians[kJoints] + 3 * i) =
            sqrt_weight_ * m.normal.transpose();
      }
      if (shape_jacobian) {
        Eigen::MatrixXd dv = Eigen::MatrixXd::Zero(3, k_shape);
        for (int c = 0; c < body::kMaxInfluences; ++c) {
          const double w = data_.skin_weights[m.vertex][c];
          if (w == 0.0) continue;
          const int k = data_.skin_joints[m.vertex][c];
          dv += w * (kin.world_rotation[k] * (data_.shape_basis.middleRows<3>(3 * m.vertex) -
                                              data_.joint_shape_basis[k]) +
                     kin.position_shape[k]);
        }
        Eigen::Map<Eigen::RowVectorXd>(jacobians[kJoints + 1] + k_shape * i, k_shape) =
            sqrt_weight_ * m.normal.transpose() * dv;
      }
    }
    return true;
  }

 private:
  std::vector<Correspondence> matches_;
  double sqrt_weight_;
};

class SkeletonTerm final : public SkinnedTerm {
 public:
  SkeletonTerm(const ModelData& data, const std::array<Eigen::Vector3d, kJoints>& targets_m,
               double weight, const ShapedRest* fixed)
      : SkinnedTerm(data, fixed), sqrt_weight_(std::sqrt(weight)) {
    for (int j = 0; j < kJoints; ++j) {
      if (targets_m[j].allFinite()) targets_.emplace_back(j, targets_m[j]);
    }
    set_num_residuals(3 * static_cast<int>(targets_.size()));
  }

  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override {
    const int n = num_residuals();
    const bool shape_jacobian = fit_shape_ && jacobians && jacobians[kJoints + 1];
    Kinematics kin;
    Kinematic(parameters, shape_jacobian, &kin);
    if (jacobians) {
      for (int j = 0; j <= kJoints; ++j) {
        if (jacobians[j]) std::fill(jacobians[j], jacobians[j] + 3 * n, 0.0);
      }
    }
    const int k_shape = data_.num_shape();
    for (size_t t = 0; t < targets_.size(); ++t) {
      const auto& [joint, target] = targets_[t];
      Eigen::Map<Eigen::Vector3d>(residuals + 3 * t) =
          sqrt_weight_ * (kin.position_m[joint] - target);
      if (!jacobians) continue;
      for (int i : data_.chain[joint]) {
        if (i == joint || !jacobians[i]) continue;
        // Row-major 3 x 3 block at rows 3t .. 3t+2.
        Eigen::Map<Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>> block(jacobians[i], n,
                                                                                    3);
        block.middleRows<3>(3 * static_cast<Eigen::Index>(t)) =
            -sqrt_weight_ * Skew(kin.position_m[joint] - kin.position_m[i]) * kin.omega_from_da[i];
      }
      if (jacobians[kJoints]) {
        Eigen::Map<Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>> block(
            jacobians[kJoints], n, 3);
        block.middleRows<3>(3 * static_cast<Eigen::Index>(t)) =
            sqrt_weight_ * Eigen::Matrix3d::Identity();
      }
      if (shape_jacobian) {
        Eigen::Map<Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>> block(
            jacobians[kJoints + 1], n, k_shape);
        block.middleRows(3 * static_cast<Eigen::Index>(t), 3) =
            sqrt_weight_ * kin.position_shape[joint];
      }
    }
    return true;
  }

 private:
  std::vector<std::pair<int, Eigen::Vector3d>> targets_;
  double sqrt_weight_;
};

struct SmoothnessFunctor {
  Eigen::Matrix3d previous;  // Column-major, as ceres::AngleAxisToRotationMatrix writes.
  double sqrt_weight;
  template <typename T>
  bool operator()(const T* angle_axis, T* residuals) const {
    T rotation[9];
    ceres::AngleAxisToRotationMatrix(angle_axis, rotation);
    for (int i = 0; i < 9; ++i) residuals[i] = sqrt_weight * (rotation[i] - previous.data()[i]);
    return true;
  }
};

class ShapePrior final : public ceres::CostFunction {
 public:
  ShapePrior(int num_shape, double weight) : sqrt_weight_(std::sqrt(weight)) {
    set_num_residuals(num_shape);
    mutable_parameter_block_sizes()->push_back(num_shape);
  }
  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override {
    const int k = num_residuals();
    for (int i = 0; i < k; ++i) residuals[i] = sqrt_weight_ * parameters[0][i];
    if (jacobians && jacobians[0]) {
      Eigen::Map<Eigen::MatrixXd>(jacobians[0], k, k) =
          sqrt_weight_ * Eigen::MatrixXd::Identity(k, k);
    }
    return true;
  }

 private:
  double sqrt_weight_;
};

}  // namespace

ModelData::ModelData(const body::BodyModel& model) {
  template_m = model.template_vertices_m;
  const int v_count = model.num_vertices();
  const int k_count = model.num_shape_components();
  shape_basis.resize(3 * v_count, k_count);
  for (int k = 0; k < k_count; ++k) {
    shape_basis.col(k) =
        Eigen::Map<const Eigen::VectorXd>(model.shape_directions_m[k].data(), 3 * v_count);
  }
  for (int j = 0; j < kJoints; ++j) {
    rest_joints_template_m[j].setZero();
    joint_shape_basis[j] = Eigen::MatrixXd::Zero(3, k_count);
  }
  for (int j = 0; j < model.joint_regressor.outerSize(); ++j) {
    for (Eigen::SparseMatrix<double, Eigen::RowMajor>::InnerIterator it(model.joint_regressor, j);
         it; ++it) {
      rest_joints_template_m[j] += it.value() * template_m.col(it.col());
      joint_shape_basis[j] += it.value() * shape_basis.middleRows<3>(3 * it.col());
    }
  }
  skin_joints = model.skin_joints;
  skin_weights = model.skin_weights;
  triangles = model.triangles;
  parents_first = body::KinectV2JointsParentsFirst();
  for (int j = 0; j < kJoints; ++j) {
    const auto p = body::KinectV2Parent(static_cast<body::KinectV2Joint>(j));
    parent[j] = p.has_value() ? body::Index(*p) : -1;
  }
  for (int j = 0; j < kJoints; ++j) {
    for (int i = j; i >= 0; i = parent[i]) chain[j].push_back(i);
  }
  active.fill(false);
  for (int v = 0; v < v_count; ++v) {
    for (int c = 0; c < body::kMaxInfluences; ++c) {
      if (skin_weights[v][c] == 0.0f) continue;
      for (int j : chain[skin_joints[v][c]]) active[j] = true;
    }
  }
}

void ModelData::Shaped(const Eigen::VectorXd& shape, Eigen::Matrix3Xd* rest_m,
                       std::array<Eigen::Vector3d, kJoints>* rest_joints_m) const {
  Eigen::VectorXd beta = Eigen::VectorXd::Zero(num_shape());
  const Eigen::Index n = std::min<Eigen::Index>(shape.size(), beta.size());
  beta.head(n) = shape.head(n);
  *rest_m = template_m;
  if (num_shape() > 0) {
    const Eigen::VectorXd offsets = shape_basis * beta;
    *rest_m += Eigen::Map<const Eigen::Matrix3Xd>(offsets.data(), 3, num_vertices());
  }
  for (int j = 0; j < kJoints; ++j) {
    (*rest_joints_m)[j] = rest_joints_template_m[j];
    if (num_shape() > 0) (*rest_joints_m)[j] += joint_shape_basis[j] * beta;
  }
}

void ComputeKinematics(const ModelData& data, const double* const* angle_axis,
                       const double* translation_m, const double* shape,
                       const std::array<Eigen::Vector3d, kJoints>* fixed_rest_joints_m,
                       bool shape_derivatives, Kinematics* out) {
  const int k_shape = data.num_shape();
  for (int j = 0; j < kJoints; ++j) {
    if (shape != nullptr) {
      const Eigen::Map<const Eigen::VectorXd> beta(shape, k_shape);
      out->rest_joints_m[j] = data.rest_joints_template_m[j];
      if (k_shape > 0) out->rest_joints_m[j] += data.joint_shape_basis[j] * beta;
    } else {
      out->rest_joints_m[j] = (*fixed_rest_joints_m)[j];
    }
  }
  const Eigen::Map<const Eigen::Vector3d> t(translation_m);
  for (int j : data.parents_first) {
    const Eigen::Map<const Eigen::Vector3d> a(angle_axis[j]);
    const Eigen::Matrix3d local = Exp(a);
    const int p = data.parent[j];
    if (p < 0) {
      out->world_rotation[j] = local;
      out->position_m[j] = out->rest_joints_m[j] + t;
      if (shape_derivatives) out->position_shape[j] = data.joint_shape_basis[j];
    } else {
      out->world_rotation[j] = out->world_rotation[p] * local;
      out->position_m[j] = out->position_m[p] +
                           out->world_rotation[p] * (out->rest_joints_m[j] - out->rest_joints_m[p]);
      if (shape_derivatives) {
        out->position_shape[j] =
            out->position_shape[p] +
            out->world_rotation[p] * (data.joint_shape_basis[j] - data.joint_shape_basis[p]);
      }
    }
    out->omega_from_da[j] = out->world_rotation[j] * RightJacobian(a);
  }
}

Eigen::Vector3d PoseVertex(const ModelData& data, const Kinematics& kin, int v,
                           const Eigen::Vector3d& rest_m) {
  Eigen::Vector3d out = Eigen::Vector3d::Zero();
  for (int c = 0; c < body::kMaxInfluences; ++c) {
    const double w = data.skin_weights[v][c];
    if (w == 0.0) continue;
    const int k = data.skin_joints[v][c];
    out += w * (kin.world_rotation[k] * (rest_m - kin.rest_joints_m[k]) + kin.position_m[k]);
  }
  return out;
}

void PoseAllVertices(const ModelData& data, const Kinematics& kin, const Eigen::Matrix3Xd& rest_m,
                     Eigen::Matrix3Xd* posed_m) {
  std::array<Eigen::Matrix<double, 3, 4>, kJoints> transform;
  for (int k = 0; k < kJoints; ++k) {
    transform[k].leftCols<3>() = kin.world_rotation[k];
    transform[k].col(3) = kin.position_m[k] - kin.world_rotation[k] * kin.rest_joints_m[k];
  }
  posed_m->resize(3, rest_m.cols());
  for (Eigen::Index v = 0; v < rest_m.cols(); ++v) {
    Eigen::Matrix<double, 3, 4> blended = Eigen::Matrix<double, 3, 4>::Zero();
    for (int c = 0; c < body::kMaxInfluences; ++c) {
      const double w = data.skin_weights[v][c];
      if (w != 0.0) blended += w * transform[data.skin_joints[v][c]];
    }
    posed_m->col(v) = blended.leftCols<3>() * rest_m.col(v) + blended.col(3);
  }
}

ceres::CostFunction* NewPointTerm(const ModelData& data, std::vector<Correspondence> matches,
                                  double weight, const ShapedRest* fixed) {
  return new PointTerm(data, std::move(matches), weight, fixed);
}

ceres::CostFunction* NewSkeletonTerm(const ModelData& data,
                                     const std::array<Eigen::Vector3d, kJoints>& targets_m,
                                     double weight, const ShapedRest* fixed) {
  return new SkeletonTerm(data, targets_m, weight, fixed);
}

ceres::CostFunction* NewSmoothnessTerm(const Eigen::Matrix3d& previous_rotation, double weight) {
  return new ceres::AutoDiffCostFunction<SmoothnessFunctor, 9, 3>(
      new SmoothnessFunctor{previous_rotation, std::sqrt(weight)});
}

ceres::CostFunction* NewShapePrior(int num_shape, double weight) {
  return new ShapePrior(num_shape, weight);
}

}  // namespace reenact::bodyfit
