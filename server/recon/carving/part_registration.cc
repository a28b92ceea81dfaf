#include "server/recon/carving/part_registration.h"

#include <cmath>

#include <Eigen/Cholesky>
#include <Eigen/Geometry>

#include "absl/status/statusor.h"
#include "absl/strings/str_cat.h"

namespace reenact::recon::carving {
namespace {

constexpr double kPi = 3.14159265358979323846;

using Matrix6d = Eigen::Matrix<double, 6, 6>;
using Vector6d = Eigen::Matrix<double, 6, 1>;

// Accumulates the normal equations of Eq. 3.8 linearised with the small-angle
// dT of Eq. 3.9 about `centre`: a point x moves to x + omega x (x - centre) + t.
class NormalEquations {
 public:
  explicit NormalEquations(const Eigen::Vector3d& centre) : centre_(centre) {}

  // One scalar residual r = direction . (x - target) with weight w:
  // dr/domega = (x - centre) x direction, dr/dt = direction.
  void AddScalar(const Eigen::Vector3d& x, const Eigen::Vector3d& direction, double residual,
                 double weight) {
    Vector6d jacobian;
    jacobian.head<3>() = (x - centre_).cross(direction);
    jacobian.tail<3>() = direction;
    a_.noalias() += weight * jacobian * jacobian.transpose();
    b_.noalias() -= weight * residual * jacobian;
    ++rows_;
  }

  // A point-to-point residual x - target: three scalar rows along the axes.
  void AddPoint(const Eigen::Vector3d& x, const Eigen::Vector3d& target, double weight) {
    const Eigen::Vector3d difference = x - target;
    for (int axis = 0; axis < 3; ++axis) {
      AddScalar(x, Eigen::Vector3d::Unit(axis), difference[axis], weight);
    }
  }

  // The increment (omega, t), or false when the system is singular.
  bool Solve(Vector6d* update) const {
    if (rows_ < 6) return false;
    const double scale = a_.diagonal().cwiseAbs().maxCoeff();
    if (!(scale > 0.0)) return false;
    // A tiny damping keeps directions no term constrains (e.g. sliding along
    // a plane without anchors) at zero instead of failing the solve.
    const Matrix6d damped = a_ + 1e-9 * scale * Matrix6d::Identity();
    const Eigen::LDLT<Matrix6d> ldlt(damped);
    if (ldlt.info() != Eigen::Success) return false;
    *update = ldlt.solve(b_);
    return update->allFinite();
  }

 private:
  Eigen::Vector3d centre_;
  Matrix6d a_ = Matrix6d::Zero();
  Vector6d b_ = Vector6d::Zero();
  int rows_ = 0;
};

Eigen::Vector3d CentreOf(const std::vector<SourcePoint>& sources,
                         const std::vector<SkeletonAnchor>& anchors, const Rigid3d& delta) {
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  double count = 0.0;
  for (const SourcePoint& source : sources) {
    sum += source.point_in_world_m.cast<double>();
    count += 1.0;
  }
  if (count == 0.0) {
    for (const SkeletonAnchor& anchor : anchors) {
      sum += anchor.point_in_world_m;
      count += 1.0;
    }
  }
  return count > 0.0 ? Eigen::Vector3d(delta * Eigen::Vector3d(sum / count))
                     : Eigen::Vector3d::Zero();
}

struct TermSums {
  double plane_sq = 0.0;
  double flow_sq = 0.0;
  double skeleton_sq = 0.0;
  int plane_pairs = 0;
  int flow_pairs = 0;
};

// Adds the E_p and E_o pairs of one source point moved by `delta`.
void AddPointTerms(const SourcePoint& source, const RegistrationView& view, const Rigid3d& delta,
                   const Eigen::Matrix3d& delta_rotation, const PartRegistrationOptions& options,
                   double cos_max_normal_angle, NormalEquations* system, TermSums* sums) {
  const Eigen::Vector3d x = delta * source.point_in_world_m.cast<double>();
  // E_p: projective association in the same sensor's D_n.
  Eigen::Vector2f pixel;
  const Eigen::Vector3f x_in_camera = view.camera->ToCamera(x.cast<float>());
  if (view.camera->ProjectCameraPoint(x_in_camera, &pixel)) {
    if (std::optional<size_t> cell = view.surface->CellAt(pixel);
        cell && view.surface->HasNormal(*cell)) {
      const Eigen::Vector3d target = view.surface->points_in_world_m[*cell].cast<double>();
      const Eigen::Vector3d normal = view.surface->normals_in_world[*cell].cast<double>();
      const Eigen::Vector3d moved_normal = delta_rotation * source.normal_in_world.cast<double>();
      if ((x - target).norm() <= options.max_pair_distance_m &&
          moved_normal.dot(normal) >= cos_max_normal_angle) {
        const double residual = normal.dot(x - target);
        system->AddScalar(x, normal, residual, source.weight);
        sums->plane_sq += residual * residual;
        ++sums->plane_pairs;
      }
    }
  }
  // E_o: the optical-flow target.
  if (source.has_flow_target && options.w_o > 0.0) {
    const Eigen::Vector3d target = source.flow_target_in_world_m.cast<double>();
    const double distance = (x - target).norm();
    if (distance <= options.max_pair_distance_m) {
      system->AddPoint(x, target, options.w_o * source.weight);
      sums->flow_sq += distance * distance;
      ++sums->flow_pairs;
    }
  }
}

}  // namespace

absl::Status PartRegistrationOptions::Validate() const {
  if (!(w_o >= 0.0) || !std::isfinite(w_o)) {
    return absl::InvalidArgumentError(absl::StrCat("w_o must be >= 0, is ", w_o));
  }
  if (!(w_s >= 0.0) || !std::isfinite(w_s)) {
    return absl::InvalidArgumentError(absl::StrCat("w_s must be >= 0, is ", w_s));
  }
  if (!(max_pair_distance_m > 0.0) || !std::isfinite(max_pair_distance_m)) {
    return absl::InvalidArgumentError(
        absl::StrCat("max_pair_distance_m must be > 0, is ", max_pair_distance_m));
  }
  if (!(max_normal_angle_deg > 0.0 && max_normal_angle_deg <= 180.0)) {
    return absl::InvalidArgumentError(
        absl::StrCat("max_normal_angle_deg must be in (0, 180], is ", max_normal_angle_deg));
  }
  if (!(min_update_deg >= 0.0) || !(min_update_mm >= 0.0)) {
    return absl::InvalidArgumentError("min_update_deg and min_update_mm must be >= 0");
  }
  if (max_iterations < 1) {
    return absl::InvalidArgumentError(
        absl::StrCat("max_iterations must be >= 1, is ", max_iterations));
  }
  return absl::OkStatus();
}

absl::StatusOr<PartRegistrationSummary> RegisterPart(const std::vector<SourcePoint>& sources,
                                                     const std::vector<RegistrationView>& views,
                                                     const std::vector<SkeletonAnchor>& anchors,
                                                     const PartRegistrationOptions& options,
                                                     const Rigid3d& initial_delta) {
  if (absl::Status status = options.Validate(); !status.ok()) return status;
  const double cos_max_normal_angle = std::cos(options.max_normal_angle_deg * kPi / 180.0);
  PartRegistrationSummary summary;
  summary.delta = initial_delta;
  for (int iteration = 0; iteration < options.max_iterations; ++iteration) {
    const Eigen::Vector3d centre = CentreOf(sources, anchors, summary.delta);
    const Eigen::Matrix3d delta_rotation = summary.delta.rotation.toRotationMatrix();
    NormalEquations system(centre);
    TermSums sums;
    for (const SourcePoint& source : sources) {
      if (source.view < 0 || source.view >= static_cast<int>(views.size())) continue;
      AddPointTerms(source, views[source.view], summary.delta, delta_rotation, options,
                    cos_max_normal_angle, &system, &sums);
    }
    if (options.w_s > 0.0) {
      for (const SkeletonAnchor& anchor : anchors) {
        const Eigen::Vector3d x = summary.delta * anchor.point_in_world_m;
        system.AddPoint(x, anchor.target_in_world_m, options.w_s * anchor.weight);
        sums.skeleton_sq += (x - anchor.target_in_world_m).squaredNorm();
      }
    }
    summary.plane_pairs = sums.plane_pairs;
    summary.flow_pairs = sums.flow_pairs;
    summary.plane_rms_m = sums.plane_pairs ? std::sqrt(sums.plane_sq / sums.plane_pairs) : 0.0;
    summary.flow_rms_m = sums.flow_pairs ? std::sqrt(sums.flow_sq / sums.flow_pairs) : 0.0;
    summary.skeleton_rms_m = (!anchors.empty() && options.w_s > 0.0)
                                 ? std::sqrt(sums.skeleton_sq / anchors.size())
                                 : 0.0;
    Vector6d update;
    if (!system.Solve(&update)) {
      summary.solved = iteration > 0;
      break;
    }
    summary.iterations = iteration + 1;
    // Compose the increment (rotation about `centre`, then translation) onto
    // dT: T_{b,n} = dT T_{b,n-1} (Eq. 3.7), the rotation made exact.
    const Eigen::Vector3d omega = update.head<3>();
    const Eigen::Vector3d translation = update.tail<3>();
    const double angle = omega.norm();
    const Eigen::Quaterniond rotation =
        angle > 0.0 ? Eigen::Quaterniond(Eigen::AngleAxisd(angle, omega / angle))
                    : Eigen::Quaterniond::Identity();
    const Rigid3d increment(rotation, centre - (rotation * centre) + translation);
    summary.delta = increment * summary.delta;
    summary.delta.rotation.normalize();
    if (angle * 180.0 / kPi < options.min_update_deg &&
        translation.norm() * 1000.0 < options.min_update_mm) {
      summary.converged = true;
      break;
    }
  }
  return summary;
}

}  // namespace reenact::recon::carving
