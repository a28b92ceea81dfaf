#include "common/bodyfit/body_fit.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <unordered_map>
#include <utility>

#include <ceres/ceres.h>
#include <ceres/rotation.h>
#include <Eigen/Geometry>
#include <Eigen/SparseCholesky>

#include "absl/strings/str_cat.h"
#include "common/base/status_macros.h"
#include "common/body/joint_set.h"
#include "common/bodyfit/body_terms.h"

namespace reenact::bodyfit {
namespace {

using body::KinectV2Joint;

// Area-weighted unit vertex normals of a posed mesh.
void VertexNormals(const Eigen::Matrix3Xd& vertices_m,
                   const std::vector<Eigen::Vector3i>& triangles, Eigen::Matrix3Xd* normals) {
  normals->setZero(3, vertices_m.cols());
  for (const Eigen::Vector3i& t : triangles) {
    const Eigen::Vector3d n = (vertices_m.col(t[1]) - vertices_m.col(t[0]))
                                  .cross(vertices_m.col(t[2]) - vertices_m.col(t[0]));
    for (int c = 0; c < 3; ++c) normals->col(t[c]) += n;
  }
  for (Eigen::Index v = 0; v < normals->cols(); ++v) {
    const double norm = normals->col(v).norm();
    if (norm > 0) normals->col(v) /= norm;
  }
}

// A uniform grid over posed vertices for the normal-aware nearest vertex of
// Eq. 4.8.
class VertexGrid {
 public:
  // Cells of `cell_m`: Nearest sees every vertex within cell_m of a point
  // (and some farther).
  VertexGrid(const Eigen::Matrix3Xd& vertices_m, const Eigen::Matrix3Xd& normals, double cell_m)
      : vertices_(vertices_m), normals_(normals), inverse_cell_(1.0 / cell_m) {
    // A dense grid over the vertices' bounding box (one cell of margin),
    // vertices bucketed by cell (counting sort).
    const Eigen::Vector3d low = vertices_m.rowwise().minCoeff();
    const Eigen::Vector3d high = vertices_m.rowwise().maxCoeff();
    // A mesh spread far (a diverged fit) gets coarser cells, not a huge grid.
    for (;;) {
      origin_ = low - Eigen::Vector3d::Constant(1.0 / inverse_cell_);
      for (int c = 0; c < 3; ++c) {
        size_[c] =
            static_cast<int>(std::min(std::floor((high[c] - origin_[c]) * inverse_cell_), 1e6)) + 2;
      }
      if (static_cast<double>(size_.x()) * size_.y() * size_.z() <= (1 << 22)) break;
      inverse_cell_ *= 0.5;
    }
    const size_t cells = static_cast<size_t>(size_.x()) * size_.y() * size_.z();
    start_.assign(cells + 1, 0);
    std::vector<int> cell_of(vertices_m.cols());
    for (Eigen::Index v = 0; v < vertices_m.cols(); ++v) {
      cell_of[v] = Flat(Cell(vertices_m.col(v)));
      ++start_[cell_of[v] + 1];
    }
    for (size_t c = 0; c < cells; ++c) start_[c + 1] += start_[c];
    order_.resize(vertices_m.cols());
    std::vector<int> next(start_.begin(), start_.end() - 1);
    for (Eigen::Index v = 0; v < vertices_m.cols(); ++v)
      order_[next[cell_of[v]]++] = static_cast<int>(v);
  }

  // argmin_y |y - z| (epsilon - n_y . n_z) over vertices within the 27
  // cells around z (Eq. 4.8), with |y - z| <= max_distance and
  // n_y . n_z >= min_dot; -1 when none.
  int Nearest(const Eigen::Vector3d& z, const Eigen::Vector3d& n_z, double epsilon,
              double max_distance_m, double min_dot) const {
    const Eigen::Vector3i c = Cell(z);
    int best = -1;
    double best_score = std::numeric_limits<double>::infinity();
    // A vertex at distance d scores at least d (epsilon - 1).
    double prune2 = max_distance_m * max_distance_m;
    for (int dz = -1; dz <= 1; ++dz) {
      for (int dy = -1; dy <= 1; ++dy) {
        for (int dx = -1; dx <= 1; ++dx) {
          const Eigen::Vector3i q = c + Eigen::Vector3i(dx, dy, dz);
          if ((q.array() < 0).any() || (q.array() >= size_.array()).any()) continue;
          const int cell = Flat(q);
          for (int k = start_[cell]; k < start_[cell + 1]; ++k) {
            const int v = order_[k];
            const double d2 = (vertices_.col(v) - z).squaredNorm();
            if (d2 > prune2) continue;
            const double dot = normals_.col(v).dot(n_z);
            if (dot < min_dot) continue;
            const double score = std::sqrt(d2) * (epsilon - dot);
            if (score < best_score) {
              best_score = score;
              best = v;
              const double reach = best_score / (epsilon - 1.0);
              prune2 = std::min(prune2, reach * reach);
            }
          }
        }
      }
    }
    return best;
  }

 private:
  // The cell of `p`, clamped to the grid for vertices; points outside give
  // cells whose neighbourhoods miss the grid (and find nothing).
  Eigen::Vector3i Cell(const Eigen::Vector3d& p) const {
    const Eigen::Vector3d g = (p - origin_) * inverse_cell_;
    Eigen::Vector3i c;
    for (int k = 0; k < 3; ++k) {
      c[k] =
          static_cast<int>(std::clamp(std::floor(g[k]), -4.0, static_cast<double>(size_[k] + 3)));
    }
    return c;
  }
  int Flat(const Eigen::Vector3i& c) const {
    return (c.z() * size_.y() + c.y()) * size_.x() + c.x();
  }

  const Eigen::Matrix3Xd& vertices_;
  const Eigen::Matrix3Xd& normals_;
  double inverse_cell_;
  Eigen::Vector3d origin_;
  Eigen::Vector3i size_;
  std::vector<int> start_;  // Per cell, its first index into order_; one more at the end.
  std::vector<int> order_;  // Vertices by cell.
};

// Ceres parameter memory of one pose.
struct PoseBlocks {
  std::array<std::array<double, 3>, kJoints> angle_axis;
  std::array<double, 3> translation;

  explicit PoseBlocks(const PoseParameters& p) {
    for (int j = 0; j < kJoints; ++j) {
      for (int c = 0; c < 3; ++c) angle_axis[j][c] = p.angle_axis[j][c];
    }
    for (int c = 0; c < 3; ++c) translation[c] = p.translation_m[c];
  }
  PoseParameters Parameters() const {
    PoseParameters p;
    for (int j = 0; j < kJoints; ++j) {
      p.angle_axis[j] = Eigen::Vector3d(angle_axis[j][0], angle_axis[j][1], angle_axis[j][2]);
    }
    p.translation_m = Eigen::Vector3d(translation[0], translation[1], translation[2]);
    return p;
  }
  std::vector<double*> Blocks(double* shape) {
    std::vector<double*> out;
    for (auto& a : angle_axis) out.push_back(a.data());
    out.push_back(translation.data());
    if (shape != nullptr) out.push_back(shape);
    return out;
  }
  std::array<const double*, kJoints> AngleAxisPointers() const {
    std::array<const double*, kJoints> out;
    for (int j = 0; j < kJoints; ++j) out[j] = angle_axis[j].data();
    return out;
  }
};

Eigen::Matrix3d RotationOf(const Eigen::Vector3d& a) {
  const double theta = a.norm();
  if (theta < 1e-12) return Eigen::Matrix3d::Identity();
  return Eigen::AngleAxisd(theta, a / theta).toRotationMatrix();
}

ceres::Solver::Options SolverOptions(int iterations, bool sparse) {
  ceres::Solver::Options options;
  options.linear_solver_type =
      sparse ? ceres::SPARSE_NORMAL_CHOLESKY : ceres::DENSE_NORMAL_CHOLESKY;
  options.max_num_iterations = iterations;
  options.num_threads = 1;
  options.logging_type = ceres::SILENT;
  options.minimizer_progress_to_stdout = false;
  options.function_tolerance = 1e-7;
  options.parameter_tolerance = 1e-8;
  return options;
}

// Evenly spread indices of the cloud, at most `count`, starting at `phase`.
std::vector<int> SamplePoints(size_t size, int count, int phase) {
  std::vector<int> out;
  if (size == 0) return out;
  const size_t stride = std::max<size_t>(1, (size + count - 1) / static_cast<size_t>(count));
  for (size_t i = static_cast<size_t>(phase) % stride; i < size; i += stride) {
    out.push_back(static_cast<int>(i));
  }
  return out;
}

// Ranges of one sensor's points along lines of sight from its centre, on a
// grid over the tangent plane of its mean viewing direction (cells of
// kSightCell, about 3 cm at 3 m): per cell, the range of the nearest
// point. Lets DiagnoseFit tell a vertex the sensor saw from one hidden
// behind what it saw and from one where it saw nothing.
class SightGrid {
 public:
  static constexpr double kSightCell = 0.01;  // Radians (tangent units).
  static constexpr int kMaxSide = 1024;

  SightGrid(const Eigen::Vector3d& centre, const PointCloud& cloud, size_t begin, size_t end)
      : centre_(centre) {
    Eigen::Vector3d forward = Eigen::Vector3d::Zero();
    for (size_t i = begin; i < end; ++i) {
      forward += (cloud.points_m[i].cast<double>() - centre).normalized();
    }
    if (!(forward.norm() > 1e-9)) return;
    forward.normalize();
    Eigen::Index least = 0;
    forward.cwiseAbs().minCoeff(&least);
    right_ = forward.cross(Eigen::Vector3d::Unit(least)).normalized();
    up_ = forward.cross(right_);
    forward_ = forward;
    Eigen::Vector2d low = Eigen::Vector2d::Constant(std::numeric_limits<double>::infinity());
    Eigen::Vector2d high = -low;
    for (size_t i = begin; i < end; ++i) {
      Eigen::Vector2d t;
      if (!Tangent(cloud.points_m[i].cast<double>(), &t)) continue;
      low = low.cwiseMin(t);
      high = high.cwiseMax(t);
    }
    if (!(low.x() <= high.x())) return;
    cell_ = kSightCell;
    // Stray points far off spread the grid: coarser cells, not a huge grid.
    while ((high - low).maxCoeff() / cell_ + 3 > kMaxSide) cell_ *= 2.0;
    origin_ = low - Eigen::Vector2d::Constant(cell_);
    width_ = static_cast<int>((high.x() - origin_.x()) / cell_) + 2;
    height_ = static_cast<int>((high.y() - origin_.y()) / cell_) + 2;
    nearest_.assign(static_cast<size_t>(width_) * height_, std::numeric_limits<double>::infinity());
    for (size_t i = begin; i < end; ++i) {
      const Eigen::Vector3d p = cloud.points_m[i].cast<double>();
      Eigen::Vector2d t;
      if (!Tangent(p, &t)) continue;
      double& r = nearest_[Index(CellOf(t))];
      r = std::min(r, (p - centre_).norm());
    }
  }

  bool usable() const { return width_ > 0; }

  // How the sensor's view meets a surface point at `p` (range r): hidden
  // behind a nearer point of the same cell (-1), seen (a point within
  // `tolerance_m` of r in its cell or a neighbouring one: 1), or not seen (0).
  int Meet(const Eigen::Vector3d& p, double tolerance_m) const {
    Eigen::Vector2d t;
    if (!Tangent(p, &t)) return 0;
    const Eigen::Vector2i c = CellOf(t);
    const double r = (p - centre_).norm();
    if (Inside(c) && nearest_[Index(c)] < r - tolerance_m) return -1;
    for (int dy = -1; dy <= 1; ++dy) {
      for (int dx = -1; dx <= 1; ++dx) {
        const Eigen::Vector2i q = c + Eigen::Vector2i(dx, dy);
        if (Inside(q) && std::abs(nearest_[Index(q)] - r) <= tolerance_m) return 1;
      }
    }
    return 0;
  }

 private:
  bool Tangent(const Eigen::Vector3d& p, Eigen::Vector2d* t) const {
    const Eigen::Vector3d d = p - centre_;
    const double z = d.dot(forward_);
    if (!(z > 0.05)) return false;
    *t = Eigen::Vector2d(d.dot(right_) / z, d.dot(up_) / z);
    return true;
  }
  Eigen::Vector2i CellOf(const Eigen::Vector2d& t) const {
    const Eigen::Vector2d g = (t - origin_) / cell_;
    return Eigen::Vector2i(static_cast<int>(std::clamp(std::floor(g.x()), -2.0, width_ + 1.0)),
                           static_cast<int>(std::clamp(std::floor(g.y()), -2.0, height_ + 1.0)));
  }
  bool Inside(const Eigen::Vector2i& c) const {
    return c.x() >= 0 && c.y() >= 0 && c.x() < width_ && c.y() < height_;
  }
  size_t Index(const Eigen::Vector2i& c) const {
    return static_cast<size_t>(c.y()) * width_ + c.x();
  }

  Eigen::Vector3d centre_;
  Eigen::Vector3d forward_ = Eigen::Vector3d::UnitZ();
  Eigen::Vector3d right_ = Eigen::Vector3d::UnitX();
  Eigen::Vector3d up_ = Eigen::Vector3d::UnitY();
  Eigen::Vector2d origin_ = Eigen::Vector2d::Zero();
  double cell_ = kSightCell;
  int width_ = 0;
  int height_ = 0;
  std::vector<double> nearest_;  // Per cell; infinity where the sensor saw nothing.
};

// ExplainPose's figures for a posed mesh: over `sample` points of the cloud
// from `phase` (-1: every point).
Explanation Explain(const Eigen::Matrix3Xd& posed, const Eigen::Matrix3Xd& normals,
                    const PointCloud& cloud, const BodyFitOptions& o, int sample, int phase) {
  Explanation out;
  if (cloud.size() == 0 || posed.cols() == 0) return out;
  const VertexGrid grid(posed, normals, o.explained_m);
  const double unexplained = o.explained_m * o.explained_m;
  const auto visit = [&](size_t i) {
    const Eigen::Vector3d z = cloud.points_m[i].cast<double>();
    const int v = grid.Nearest(z, cloud.normals[i].cast<double>(), o.normal_epsilon, o.explained_m,
                               o.min_normal_dot);
    ++out.points;
    if (v < 0) {
      out.cost += unexplained;
      return;
    }
    ++out.explained;
    const double plane = normals.col(v).dot(z - posed.col(v));
    out.cost += std::min(plane * plane, unexplained);
  };
  if (sample < 0) {
    for (size_t i = 0; i < cloud.size(); ++i) visit(i);
  } else {
    for (int i : SamplePoints(cloud.size(), sample, phase)) visit(static_cast<size_t>(i));
  }
  if (out.points > 0) out.cost /= out.points;
  return out;
}

// Adds one frame's terms of Eq. 4.7 to `problem`: the point term over the
// Eq. 4.8 correspondences of round `round`'s subset of the cloud (against
// the posed mesh `posed`/`normals`), the skeleton prior and Eq. 4.6 towards
// `smooth_to`. `shape_block` (may be null: shape held at `shape`) is shared.
void AddFrameTerms(const ModelData& data, const BodyFitOptions& o, const PointCloud& cloud,
                   const Eigen::Matrix3Xd& posed, const Eigen::Matrix3Xd& normals, int round,
                   const SkeletonJoints& skeleton_m, const PoseParameters& smooth_to,
                   double* shape_block, const ShapedRest* fixed, PoseBlocks* blocks,
                   ceres::Problem* problem) {
  // The first round reaches max_distance_m; later ones, close to the
  // surface already, search half as far (a quarter of the cells' volume).
  const VertexGrid grid(posed, normals, round == 0 ? o.max_distance_m : 0.5 * o.max_distance_m);
  std::vector<Correspondence> matches;
  const std::vector<int> sample = SamplePoints(cloud.size(), o.max_points, round);
  for (int i : sample) {
    const Eigen::Vector3d z = cloud.points_m[i].cast<double>();
    const Eigen::Vector3d n = cloud.normals[i].cast<double>();
    const int v = grid.Nearest(z, n, o.normal_epsilon, o.max_distance_m, o.min_normal_dot);
    if (v >= 0) matches.push_back({v, z, n});
  }
  std::vector<double*> parameters = blocks->Blocks(shape_block);
  if (!matches.empty()) {
    // The sample stands for the whole cloud: Eq. 4.5 sums over every point.
    const double weight = o.point_weight * cloud.size() / sample.size();
    problem->AddResidualBlock(NewPointTerm(data, std::move(matches), weight, fixed),
                              new ceres::HuberLoss(std::sqrt(weight) * o.huber_m), parameters);
  }
  if (o.skeleton_weight > 0) {
    problem->AddResidualBlock(NewSkeletonTerm(data, skeleton_m, o.skeleton_weight, fixed), nullptr,
                              parameters);
  }
  for (int j = 0; j < kJoints; ++j) {
    if (!problem->HasParameterBlock(parameters[j])) continue;
    if (!data.active[j]) {
      problem->SetParameterBlockConstant(parameters[j]);
    } else if (o.smoothness_weight > 0) {
      problem->AddResidualBlock(
          NewSmoothnessTerm(RotationOf(smooth_to.angle_axis[j]), o.smoothness_weight), nullptr,
          parameters[j]);
    }
  }
}

}  // namespace

const char* HypothesisName(Hypothesis hypothesis) {
  switch (hypothesis) {
    case Hypothesis::kFollowSkeleton:
      return "follow_skeleton";
    case Hypothesis::kPrevious:
      return "previous";
    case Hypothesis::kArmsSwapped:
      return "arms_swapped";
    case Hypothesis::kLegsSwapped:
      return "legs_swapped";
    case Hypothesis::kSkeleton:
      return "skeleton";
  }
  return "unknown";
}

namespace {

SkeletonJoints SwapPairs(const SkeletonJoints& skeleton_m,
                         std::initializer_list<std::pair<KinectV2Joint, KinectV2Joint>> pairs) {
  SkeletonJoints out = skeleton_m;
  for (const auto& [left, right] : pairs)
    std::swap(out[body::Index(left)], out[body::Index(right)]);
  return out;
}

// Whether the skeleton's limb of `pairs` (left, right) may have changed
// sides against `before` (the previous fit's joints): its left joints lie
// about as near the previous right ones as the left ones, or nearer. Far
// apart limbs that kept their sides need no swapped start; a start is made
// for every limb the points could tell either way (crossed, or close).
bool MayHaveSwapped(const SkeletonJoints& skeleton_m,
                    const std::array<Eigen::Vector3d, kJoints>& before,
                    std::initializer_list<std::pair<KinectV2Joint, KinectV2Joint>> pairs) {
  // Per pair: how much nearer the same sides must be for a swap to be ruled out.
  constexpr double kMarginM = 0.1;
  double same = 0.0;
  double cross = 0.0;
  int counted = 0;
  for (const auto& [left, right] : pairs) {
    const Eigen::Vector3d& l = skeleton_m[body::Index(left)];
    const Eigen::Vector3d& r = skeleton_m[body::Index(right)];
    if (!l.allFinite() || !r.allFinite()) continue;
    const Eigen::Vector3d& bl = before[body::Index(left)];
    const Eigen::Vector3d& br = before[body::Index(right)];
    same += (l - bl).norm() + (r - br).norm();
    cross += (l - br).norm() + (r - bl).norm();
    ++counted;
  }
  return counted > 0 && cross < same + kMarginM * counted;
}

}  // namespace

SkeletonJoints SwapArms(const SkeletonJoints& skeleton_m) {
  return SwapPairs(skeleton_m, {{KinectV2Joint::kShoulderLeft, KinectV2Joint::kShoulderRight},
                                {KinectV2Joint::kElbowLeft, KinectV2Joint::kElbowRight},
                                {KinectV2Joint::kWristLeft, KinectV2Joint::kWristRight},
                                {KinectV2Joint::kHandLeft, KinectV2Joint::kHandRight},
                                {KinectV2Joint::kHandTipLeft, KinectV2Joint::kHandTipRight},
                                {KinectV2Joint::kThumbLeft, KinectV2Joint::kThumbRight}});
}

SkeletonJoints SwapLegs(const SkeletonJoints& skeleton_m) {
  return SwapPairs(skeleton_m, {{KinectV2Joint::kKneeLeft, KinectV2Joint::kKneeRight},
                                {KinectV2Joint::kAnkleLeft, KinectV2Joint::kAnkleRight},
                                {KinectV2Joint::kFootLeft, KinectV2Joint::kFootRight}});
}

SkeletonJoints NoSkeletonJoints() {
  SkeletonJoints out;
  out.fill(Eigen::Vector3d::Constant(std::numeric_limits<double>::quiet_NaN()));
  return out;
}

bool HasTorso(const SkeletonJoints& skeleton_m) {
  const auto ok = [&](KinectV2Joint j) { return skeleton_m[body::Index(j)].allFinite(); };
  return ok(KinectV2Joint::kSpineBase) && ok(KinectV2Joint::kSpineShoulder) &&
         ((ok(KinectV2Joint::kHipLeft) && ok(KinectV2Joint::kHipRight)) ||
          (ok(KinectV2Joint::kShoulderLeft) && ok(KinectV2Joint::kShoulderRight)));
}

absl::Status BodyFitOptions::Validate() const {
  const auto bad = [](const std::string& what) {
    return absl::InvalidArgumentError(absl::StrCat("body fit: ", what));
  };
  if (!(point_weight > 0)) return bad("point_weight must be > 0");
  if (!(smoothness_weight >= 0) || !(skeleton_weight >= 0) || !(shape_prior_weight >= 0)) {
    return bad("weights must be >= 0");
  }
  if (!(normal_epsilon > 1)) return bad("normal_epsilon must be > 1 (Eq. 4.8)");
  if (!(lost_rms_mm > 0)) return bad("lost_rms_mm must be > 0");
  if (!(explained_m > 0 && explained_m <= 1)) return bad("explained_m must be in (0, 1] m");
  if (!(max_distance_m > 0) || !(refine_max_distance_m > 0) || !(huber_m > 0)) {
    return bad("distances must be > 0");
  }
  if (!(min_normal_dot >= -1 && min_normal_dot <= 1)) return bad("min_normal_dot outside [-1, 1]");
  if (max_points < 10 || rounds < 1 || iterations_per_round < 1 || shape_frames < 1 ||
      shape_rounds < 0) {
    return bad("max_points >= 10, rounds, iterations_per_round and shape_frames >= 1");
  }
  return absl::OkStatus();
}

PoseParameters PoseParameters::FromPose(const body::BodyPose& pose) {
  PoseParameters p;
  for (int j = 0; j < kJoints; ++j) {
    const Eigen::AngleAxisd aa(pose.local_rotation[j].normalized());
    double angle = aa.angle();
    Eigen::Vector3d axis = aa.axis();
    if (angle > M_PI) {
      angle = 2 * M_PI - angle;
      axis = -axis;
    }
    p.angle_axis[j] = angle * axis;
  }
  p.translation_m = pose.root_translation_m;
  return p;
}

body::BodyPose PoseParameters::ToPose() const {
  body::BodyPose pose;
  for (int j = 0; j < kJoints; ++j)
    pose.local_rotation[j] = Eigen::Quaterniond(RotationOf(angle_axis[j]));
  pose.root_translation_m = translation_m;
  return pose;
}

BodyFitter::BodyFitter(const body::BodyModel& model, const BodyFitOptions& options)
    : model_(model), options_(options) {}

BodyFitter::~BodyFitter() = default;

absl::StatusOr<std::unique_ptr<BodyFitter>> BodyFitter::Create(const body::BodyModel& model,
                                                               const BodyFitOptions& options) {
  RETURN_IF_ERROR(options.Validate());
  RETURN_IF_ERROR(body::ValidateBodyModel(model));
  std::unique_ptr<BodyFitter> fitter(new BodyFitter(model, options));
  fitter->data_ = std::make_unique<ModelData>(model);
  fitter->shape_ = Eigen::VectorXd::Zero(model.num_shape_components());
  fitter->rest_ = std::make_unique<ShapedRest>();
  fitter->data_->Shaped(fitter->shape_, &fitter->rest_->vertices_m, &fitter->rest_->joints_m);
  return fitter;
}

absl::Status BodyFitter::set_shape(const Eigen::VectorXd& shape) {
  if (shape.size() != model_.num_shape_components() || !shape.allFinite()) {
    return absl::InvalidArgumentError(absl::StrCat(
        "shape has ", shape.size(), " coefficients, the model ", model_.num_shape_components()));
  }
  shape_ = shape;
  data_->Shaped(shape_, &rest_->vertices_m, &rest_->joints_m);
  return absl::OkStatus();
}

absl::StatusOr<body::BodyPose> BodyFitter::PoseFromSkeleton(
    const SkeletonJoints& skeleton_m) const {
  const auto at = [&](KinectV2Joint j) { return skeleton_m[body::Index(j)]; };
  const Eigen::Vector3d base = at(KinectV2Joint::kSpineBase);
  const Eigen::Vector3d top = at(KinectV2Joint::kSpineShoulder);
  Eigen::Vector3d left = at(KinectV2Joint::kHipLeft) - at(KinectV2Joint::kHipRight);
  const Eigen::Vector3d shoulders =
      at(KinectV2Joint::kShoulderLeft) - at(KinectV2Joint::kShoulderRight);
  if (!left.allFinite()) left = shoulders;
  if (!base.allFinite() || !top.allFinite() || !left.allFinite()) {
    return absl::FailedPreconditionError(
        "the skeleton lacks the torso joints (spine base and shoulder, hips or shoulders)");
  }
  const std::array<Eigen::Vector3d, kJoints>& rest_joints = rest_->joints_m;
  const auto frame = [](const Eigen::Vector3d& up_in, const Eigen::Vector3d& left_in) {
    const Eigen::Vector3d up = up_in.normalized();
    const Eigen::Vector3d l = (left_in - left_in.dot(up) * up).normalized();
    Eigen::Matrix3d f;
    f << l, up, l.cross(up);
    return f;
  };
  const auto rj = [&](KinectV2Joint j) { return rest_joints[body::Index(j)]; };
  const Eigen::Matrix3d target = frame(top - base, left);
  const Eigen::Matrix3d model_frame =
      frame(rj(KinectV2Joint::kSpineShoulder) - rj(KinectV2Joint::kSpineBase),
            rj(KinectV2Joint::kHipLeft) - rj(KinectV2Joint::kHipRight));
  if (!target.allFinite()) return absl::FailedPreconditionError("degenerate skeleton torso");
  PoseParameters start;
  for (auto& a : start.angle_axis) a.setZero();
  Eigen::AngleAxisd root(target * model_frame.transpose());
  start.angle_axis[body::Index(KinectV2Joint::kSpineBase)] = root.angle() * root.axis();
  start.translation_m = base - rj(KinectV2Joint::kSpineBase);

  return FollowSkeleton(start.ToPose(), skeleton_m, 1e-4);
}

absl::StatusOr<body::BodyPose> BodyFitter::FollowSkeleton(const body::BodyPose& start,
                                                          const SkeletonJoints& skeleton_m,
                                                          double stay_weight) const {
  PoseBlocks blocks(PoseParameters::FromPose(start));
  const PoseParameters from = blocks.Parameters();
  ceres::Problem problem;
  std::vector<double*> parameters = blocks.Blocks(nullptr);
  problem.AddResidualBlock(NewSkeletonTerm(*data_, skeleton_m, 1.0, rest_.get()), nullptr,
                           parameters);
  // A weak pull to the start: joint positions leave twists open.
  for (int j = 0; j < kJoints; ++j) {
    if (!data_->active[j]) {
      problem.SetParameterBlockConstant(parameters[j]);
      continue;
    }
    problem.AddResidualBlock(NewSmoothnessTerm(RotationOf(from.angle_axis[j]), stay_weight),
                             nullptr, parameters[j]);
  }
  ceres::Solver::Summary summary;
  ceres::Solve(SolverOptions(30, false), &problem, &summary);
  body::BodyPose out = blocks.Parameters().ToPose();
  if (!out.root_translation_m.allFinite()) return absl::InternalError("skeleton fit diverged");
  return out;
}

absl::Status BodyFitter::FitShape(const std::vector<FitInput>& frames,
                                  std::vector<body::BodyPose>* poses) {
  if (poses->size() != frames.size() || frames.empty()) {
    return absl::InvalidArgumentError("FitShape needs one initial pose per frame");
  }
  const int k_shape = model_.num_shape_components();
  Eigen::VectorXd beta = shape_;
  std::vector<PoseBlocks> blocks;
  for (const body::BodyPose& pose : *poses) blocks.emplace_back(PoseParameters::FromPose(pose));
  for (int round = 0; round < options_.shape_rounds; ++round) {
    ShapedRest round_rest;
    data_->Shaped(beta, &round_rest.vertices_m, &round_rest.joints_m);
    const Eigen::Matrix3Xd& rest = round_rest.vertices_m;
    const std::array<Eigen::Vector3d, kJoints>& rest_joints = round_rest.joints_m;
    ceres::Problem problem;
    for (size_t f = 0; f < frames.size(); ++f) {
      const auto pointers = blocks[f].AngleAxisPointers();
      Kinematics kin;
      ComputeKinematics(*data_, pointers.data(), blocks[f].translation.data(), nullptr,
                        &rest_joints, false, &kin);
      Eigen::Matrix3Xd posed, normals;
      PoseAllVertices(*data_, kin, rest, &posed);
      VertexNormals(posed, data_->triangles, &normals);
      // Eq. 4.6 against the frame's pose at the start of the round.
      AddFrameTerms(*data_, options_, *frames[f].cloud, posed, normals, round, frames[f].skeleton_m,
                    blocks[f].Parameters(), k_shape > 0 ? beta.data() : nullptr,
                    k_shape > 0 ? nullptr : rest_.get(), &blocks[f], &problem);
    }
    if (k_shape > 0 && problem.HasParameterBlock(beta.data())) {
      problem.AddResidualBlock(NewShapePrior(k_shape, options_.shape_prior_weight), nullptr,
                               beta.data());
    }
    ceres::Solver::Summary summary;
    ceres::Solve(SolverOptions(options_.iterations_per_round, true), &problem, &summary);
  }
  if (!beta.allFinite()) return absl::InternalError("the shape fit diverged");
  shape_ = beta;
  data_->Shaped(shape_, &rest_->vertices_m, &rest_->joints_m);
  for (size_t f = 0; f < frames.size(); ++f) (*poses)[f] = blocks[f].Parameters().ToPose();
  return absl::OkStatus();
}

absl::Status BodyFitter::FitShapeFromSkeletons(const std::vector<FitInput>& frames) {
  std::vector<body::BodyPose> poses;
  for (const FitInput& input : frames) {
    ASSIGN_OR_RETURN(body::BodyPose pose, PoseFromSkeleton(input.skeleton_m));
    poses.push_back(pose);
  }
  return FitShape(frames, &poses);
}

absl::StatusOr<std::optional<body::BodyPose>> BodyFitter::InitialPose(
    const body::BodyPose* previous, const SkeletonJoints& skeleton_m) const {
  if (!HasTorso(skeleton_m)) {
    if (previous == nullptr) return std::nullopt;
    return *previous;
  }
  if (previous != nullptr) return FollowSkeleton(*previous, skeleton_m);
  return PoseFromSkeleton(skeleton_m);
}

absl::StatusOr<std::optional<BodyFitter::SequenceFit>> BodyFitter::FitNext(
    const FitInput& input, const body::BodyPose* previous) {
  if (input.cloud == nullptr) return absl::InvalidArgumentError("no point cloud");
  if (options_.hypotheses && previous != nullptr && HasTorso(input.skeleton_m)) {
    ASSIGN_OR_RETURN(SequenceFit fit, FitHypotheses(input, *previous));
    return fit;
  }
  ASSIGN_OR_RETURN(const std::optional<body::BodyPose> initial,
                   InitialPose(previous, input.skeleton_m));
  if (!initial.has_value()) return std::nullopt;
  SequenceFit out;
  out.hypothesis = previous == nullptr          ? Hypothesis::kSkeleton
                   : HasTorso(input.skeleton_m) ? Hypothesis::kFollowSkeleton
                                                : Hypothesis::kPrevious;
  ASSIGN_OR_RETURN(out.fit, FitFrame(input, *initial, previous));
  if (previous == nullptr || !HasTorso(input.skeleton_m)) return out;
  if (!(out.fit.point_rms_mm > options_.lost_rms_mm)) return out;
  ASSIGN_OR_RETURN(const body::BodyPose from_skeleton, PoseFromSkeleton(input.skeleton_m));
  ASSIGN_OR_RETURN(FrameFit again, FitFrame(input, from_skeleton, nullptr));
  const bool better = again.point_rms_mm < out.fit.point_rms_mm;
  if (better) {
    out.fit = std::move(again);
    out.restarted = true;
    out.hypothesis = Hypothesis::kSkeleton;
  }
  return out;
}

absl::StatusOr<BodyFitter::SequenceFit> BodyFitter::FitHypotheses(const FitInput& input,
                                                                  const body::BodyPose& previous) {
  // A fit explaining this share of its points is not bettered by a second.
  constexpr double kExplainedEnough = 0.98;
  struct Candidate {
    Hypothesis hypothesis;
    body::BodyPose initial;
    SkeletonJoints skeleton_m;
    double cost = 0.0;
  };
  std::vector<Candidate> candidates;
  const auto add = [&](Hypothesis hypothesis, const SkeletonJoints& skeleton_m,
                       const absl::StatusOr<body::BodyPose>& initial) {
    // A start that cannot be made (a degenerate torso) is no candidate.
    if (!initial.ok()) return;
    candidates.push_back({hypothesis, *initial, skeleton_m, 0.0});
  };
  const SkeletonJoints& skeleton = input.skeleton_m;
  add(Hypothesis::kFollowSkeleton, skeleton, FollowSkeleton(previous, skeleton));
  add(Hypothesis::kPrevious, skeleton, previous);
  // Swapped starts only for limbs whose sides the skeleton may have
  // swapped since the previous fit (each costs a FollowSkeleton solve and a
  // screening).
  std::array<Eigen::Vector3d, kJoints> before;
  {
    const PoseBlocks blocks(PoseParameters::FromPose(previous));
    const auto pointers = blocks.AngleAxisPointers();
    Kinematics kin;
    ComputeKinematics(*data_, pointers.data(), blocks.translation.data(), nullptr, &rest_->joints_m,
                      false, &kin);
    before = kin.position_m;
  }
  if (MayHaveSwapped(skeleton, before,
                     {{KinectV2Joint::kElbowLeft, KinectV2Joint::kElbowRight},
                      {KinectV2Joint::kWristLeft, KinectV2Joint::kWristRight},
                      {KinectV2Joint::kHandLeft, KinectV2Joint::kHandRight}})) {
    const SkeletonJoints arms = SwapArms(skeleton);
    add(Hypothesis::kArmsSwapped, arms, FollowSkeleton(previous, arms));
  }
  if (MayHaveSwapped(skeleton, before,
                     {{KinectV2Joint::kKneeLeft, KinectV2Joint::kKneeRight},
                      {KinectV2Joint::kAnkleLeft, KinectV2Joint::kAnkleRight},
                      {KinectV2Joint::kFootLeft, KinectV2Joint::kFootRight}})) {
    const SkeletonJoints legs = SwapLegs(skeleton);
    add(Hypothesis::kLegsSwapped, legs, FollowSkeleton(previous, legs));
  }
  add(Hypothesis::kSkeleton, skeleton, PoseFromSkeleton(skeleton));
  if (candidates.empty()) return absl::InternalError("no starting pose could be made");
  // Screened by how much of the cloud each start explains; the best is
  // fitted, and the second best too unless that fit explains nearly every
  // point (the first-listed wins ties, so an unswapped start is kept when
  // nothing tells them apart).
  for (Candidate& candidate : candidates) {
    candidate.cost = ExplainPose(candidate.initial, *input.cloud, options_.max_points).cost;
  }
  std::stable_sort(candidates.begin(), candidates.end(),
                   [](const Candidate& a, const Candidate& b) { return a.cost < b.cost; });
  std::optional<SequenceFit> best;
  const size_t fitted = std::min<size_t>(2, candidates.size());
  for (size_t k = 0; k < fitted; ++k) {
    if (best.has_value() && best->fit.explained_fraction >= kExplainedEnough) break;
    const Candidate& candidate = candidates[k];
    FitInput with_skeleton = input;
    with_skeleton.skeleton_m = candidate.skeleton_m;
    const bool restart = candidate.hypothesis == Hypothesis::kSkeleton;
    ASSIGN_OR_RETURN(FrameFit fit,
                     FitFrame(with_skeleton, candidate.initial, restart ? nullptr : &previous));
    if (best.has_value() && !(fit.explanation_cost < best->fit.explanation_cost)) continue;
    best.emplace();
    best->fit = std::move(fit);
    best->hypothesis = candidate.hypothesis;
    best->restarted = restart;
  }
  return *std::move(best);
}

void BodyFitter::PoseMesh(const body::BodyPose& pose, Eigen::Matrix3Xd* posed,
                          Eigen::Matrix3Xd* normals) const {
  const PoseBlocks blocks(PoseParameters::FromPose(pose));
  const auto pointers = blocks.AngleAxisPointers();
  Kinematics kin;
  ComputeKinematics(*data_, pointers.data(), blocks.translation.data(), nullptr, &rest_->joints_m,
                    false, &kin);
  PoseAllVertices(*data_, kin, rest_->vertices_m, posed);
  VertexNormals(*posed, data_->triangles, normals);
}

Explanation BodyFitter::ExplainPose(const body::BodyPose& pose, const PointCloud& cloud,
                                    int sample) const {
  Eigen::Matrix3Xd posed, normals;
  PoseMesh(pose, &posed, &normals);
  return Explain(posed, normals, cloud, options_, sample, 0);
}

std::vector<SensorDiagnosis> BodyFitter::DiagnoseFit(const FrameFit& fit, const PointCloud& cloud,
                                                     const std::vector<SensorView>& sensors) const {
  std::vector<SensorDiagnosis> out;
  if (fit.vertices_m.cols() == 0) return out;
  Eigen::Matrix3Xd posed = fit.vertices_m;
  if (fit.offsets_m.cols() == posed.cols()) posed += fit.offsets_m;
  Eigen::Matrix3Xd normals;
  VertexNormals(posed, data_->triangles, &normals);
  Eigen::VectorXd area = Eigen::VectorXd::Zero(posed.cols());
  for (const Eigen::Vector3i& t : data_->triangles) {
    const double third =
        (posed.col(t[1]) - posed.col(t[0])).cross(posed.col(t[2]) - posed.col(t[0])).norm() / 6.0;
    for (int c = 0; c < 3; ++c) area[t[c]] += third;
  }
  const double reach = options_.explained_m;
  const VertexGrid grid(posed, normals, reach);
  // A vertex faces a sensor when its normal is within about 70 degrees of
  // the line of sight: grazing surface is seen at random.
  constexpr double kFacingCos = 0.35;
  for (const PointCloud::SensorRange& range : cloud.sensor_ranges) {
    if (range.sensor < 0 || static_cast<size_t>(range.sensor) >= sensors.size() ||
        range.begin > range.end || range.end > cloud.size()) {
      continue;
    }
    SensorDiagnosis d;
    d.sensor = range.sensor;
    double sum2 = 0.0;
    for (size_t i = range.begin; i < range.end; ++i) {
      const Eigen::Vector3d z = cloud.points_m[i].cast<double>();
      ++d.points;
      const int v = grid.Nearest(z, cloud.normals[i].cast<double>(), options_.normal_epsilon, reach,
                                 options_.min_normal_dot);
      if (v < 0) continue;
      ++d.explained;
      const double plane = normals.col(v).dot(z - posed.col(v));
      sum2 += plane * plane;
    }
    d.rms_mm = d.explained > 0 ? 1000.0 * std::sqrt(sum2 / d.explained) : 0.0;
    const SensorView& view = sensors[range.sensor];
    const Eigen::Vector3d& centre = view.centre_m;
    const SightGrid sight(centre, cloud, range.begin, range.end);
    if (sight.usable()) {
      for (Eigen::Index v = 0; v < posed.cols(); ++v) {
        const Eigen::Vector3d to_sensor = centre - posed.col(v);
        if (normals.col(v).dot(to_sensor) < kFacingCos * to_sensor.norm()) continue;
        if (view.sees && !view.sees(posed.col(v))) continue;
        const int meet = sight.Meet(posed.col(v), reach);
        if (meet < 0) continue;
        ++d.facing_vertices;
        d.facing_area_m2 += area[v];
        if (meet > 0) {
          ++d.seen_vertices;
          d.seen_area_m2 += area[v];
        }
      }
    }
    out.push_back(d);
  }
  return out;
}

absl::StatusOr<FrameFit> BodyFitter::FitFrame(const FitInput& input, const body::BodyPose& initial,
                                              const body::BodyPose* previous) {
  if (input.cloud == nullptr) return absl::InvalidArgumentError("no point cloud");
  const Eigen::Matrix3Xd& rest = rest_->vertices_m;
  const std::array<Eigen::Vector3d, kJoints>& rest_joints = rest_->joints_m;
  PoseBlocks blocks(PoseParameters::FromPose(initial));
  const PoseParameters smooth_to = PoseParameters::FromPose(previous ? *previous : initial);
  const PointCloud& cloud = *input.cloud;
  Eigen::Matrix3Xd posed, normals;
  const auto pose_now = [&]() {
    const auto pointers = blocks.AngleAxisPointers();
    Kinematics kin;
    ComputeKinematics(*data_, pointers.data(), blocks.translation.data(), nullptr, &rest_joints,
                      false, &kin);
    PoseAllVertices(*data_, kin, rest, &posed);
    VertexNormals(posed, data_->triangles, &normals);
    return kin;
  };
  for (int round = 0; round < options_.rounds; ++round) {
    pose_now();
    ceres::Problem problem;
    AddFrameTerms(*data_, options_, cloud, posed, normals, round, input.skeleton_m, smooth_to,
                  nullptr, rest_.get(), &blocks, &problem);
    if (problem.NumResidualBlocks() == 0) break;
    ceres::Solver::Summary summary;
    ceres::Solve(SolverOptions(options_.iterations_per_round, false), &problem, &summary);
  }
  const Kinematics kin = pose_now();
  FrameFit fit;
  fit.pose = blocks.Parameters().ToPose();
  if (!fit.pose.root_translation_m.allFinite()) return absl::InternalError("the fit diverged");
  for (int j = 0; j < kJoints; ++j) fit.joints_m[j] = kin.position_m[j];

  // The RMS figure over a subset of the cloud, as the rounds used it.
  const int v_count = data_->num_vertices();
  double sum2 = 0.0;
  int used = 0;
  {
    const VertexGrid grid(posed, normals, 0.5 * options_.max_distance_m);
    for (int i : SamplePoints(cloud.size(), options_.max_points, options_.rounds)) {
      const Eigen::Vector3d z = cloud.points_m[i].cast<double>();
      const int v = grid.Nearest(z, cloud.normals[i].cast<double>(), options_.normal_epsilon,
                                 options_.max_distance_m, options_.min_normal_dot);
      if (v < 0) continue;
      const double plane = normals.col(v).dot(z - posed.col(v));
      sum2 += plane * plane;
      ++used;
    }
  }
  // Step 2's correspondences: every point within refine_max_distance_m.
  Eigen::Matrix3Xd pull = Eigen::Matrix3Xd::Zero(3, v_count);
  Eigen::VectorXd count = Eigen::VectorXd::Zero(v_count);
  if (options_.refine_vertices) {
    const VertexGrid grid(posed, normals, options_.refine_max_distance_m);
    for (size_t i = 0; i < cloud.size(); ++i) {
      const Eigen::Vector3d z = cloud.points_m[i].cast<double>();
      const int v = grid.Nearest(z, cloud.normals[i].cast<double>(), options_.normal_epsilon,
                                 options_.refine_max_distance_m, options_.min_normal_dot);
      if (v < 0) continue;
      pull.col(v) += z - posed.col(v);
      count[v] += 1.0;
    }
  }
  fit.correspondences = used;
  fit.point_rms_mm = used > 0 ? 1000.0 * std::sqrt(sum2 / used) : 0.0;
  const Explanation explained = Explain(posed, normals, cloud, options_, options_.max_points, 0);
  fit.explained_fraction = explained.fraction();
  fit.explanation_cost = explained.cost;
  fit.vertices_m = posed;

  if (options_.refine_vertices && count.sum() > 0) {
    // Step 2 (Eq. 4.4 + w_z Eq. 4.5 in D = Y_f - M): per triangle the edges
    // 1-0 and 2-0 keep the prediction's, each point pulls its vertex:
    //   (E^T E + w_z C) D = w_z sum_n (z_n - m_v(n)).
    if (!refine_solver_ready_) {
      std::vector<Eigen::Triplet<double>> triplets;
      for (const Eigen::Vector3i& t : data_->triangles) {
        for (int e = 1; e <= 2; ++e) {
          const int a = t[0], b = t[e];
          triplets.emplace_back(a, a, 1.0);
          triplets.emplace_back(b, b, 1.0);
          triplets.emplace_back(a, b, -1.0);
          triplets.emplace_back(b, a, -1.0);
        }
      }
      laplacian_.resize(v_count, v_count);
      laplacian_.setFromTriplets(triplets.begin(), triplets.end());
      laplacian_.makeCompressed();
      refine_solver_.analyzePattern(laplacian_);
      refine_solver_ready_ = true;
    }
    Eigen::SparseMatrix<double> system = laplacian_;
    for (int v = 0; v < v_count; ++v) {
      system.coeffRef(v, v) += options_.point_weight * count[v];
    }
    refine_solver_.factorize(system);
    if (refine_solver_.info() == Eigen::Success) {
      const Eigen::MatrixXd rhs = options_.point_weight * pull.transpose();
      const Eigen::MatrixXd d = refine_solver_.solve(rhs);
      if (refine_solver_.info() == Eigen::Success && d.allFinite()) {
        fit.offsets_m = d.transpose();
      }
    }
  }
  return fit;
}

}  // namespace reenact::bodyfit
