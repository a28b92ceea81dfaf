#include "common/geometry/umeyama.h"

#include <cmath>

#include <Eigen/SVD>

#include "absl/strings/str_cat.h"
#include "common/base/status_macros.h"

namespace reenact {
namespace {

absl::Status CheckInputs(const std::vector<Eigen::Vector3d>& points_in_source,
                         const std::vector<Eigen::Vector3d>& points_in_target) {
  if (points_in_source.size() != points_in_target.size()) {
    return absl::InvalidArgumentError(absl::StrCat("Umeyama: ", points_in_source.size(),
                                                   " source points but ", points_in_target.size(),
                                                   " target points"));
  }
  if (points_in_source.size() < 3) {
    return absl::InvalidArgumentError(
        absl::StrCat("Umeyama: need at least 3 point pairs, got ", points_in_source.size()));
  }
  for (size_t i = 0; i < points_in_source.size(); ++i) {
    if (!points_in_source[i].allFinite() || !points_in_target[i].allFinite()) {
      return absl::InvalidArgumentError(absl::StrCat("Umeyama: point pair ", i, " is not finite"));
    }
  }
  return absl::OkStatus();
}

Eigen::Vector3d Mean(const std::vector<Eigen::Vector3d>& points) {
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  for (const Eigen::Vector3d& point : points) sum += point;
  return sum / static_cast<double>(points.size());
}

}  // namespace

absl::Status UmeyamaOptions::Validate() const {
  if (!(min_singular_value_ratio >= 0.0 && min_singular_value_ratio < 1.0)) {
    return absl::InvalidArgumentError(
        absl::StrCat("UmeyamaOptions: min_singular_value_ratio must be in [0, 1), got ",
                     min_singular_value_ratio));
  }
  return absl::OkStatus();
}

absl::StatusOr<Sim3d> FitSimilarityUmeyama(const std::vector<Eigen::Vector3d>& points_in_source,
                                           const std::vector<Eigen::Vector3d>& points_in_target,
                                           const UmeyamaOptions& options) {
  RETURN_IF_ERROR(options.Validate());
  RETURN_IF_ERROR(CheckInputs(points_in_source, points_in_target));
  const double n = static_cast<double>(points_in_source.size());
  const Eigen::Vector3d mean_source = Mean(points_in_source);  // mu_x, Umeyama Eq. 34.
  const Eigen::Vector3d mean_target = Mean(points_in_target);  // mu_y, Eq. 35.

  // Source variance (Eq. 36) and cross-covariance Sigma_xy (Eq. 38).
  double variance_source = 0.0;
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();
  for (size_t i = 0; i < points_in_source.size(); ++i) {
    const Eigen::Vector3d q = points_in_source[i] - mean_source;
    const Eigen::Vector3d p = points_in_target[i] - mean_target;
    variance_source += q.squaredNorm();
    covariance += p * q.transpose();
  }
  variance_source /= n;
  covariance /= n;
  if (!(variance_source > 0.0)) {
    return absl::FailedPreconditionError("Umeyama: source points are all coincident");
  }

  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(covariance,
                                              Eigen::ComputeFullU | Eigen::ComputeFullV);
  const Eigen::Vector3d& singular_values = svd.singularValues();
  // Rank < 2 (Eq. 39 needs rank >= m - 1): collinear or coincident points.
  if (!(singular_values(1) > options.min_singular_value_ratio * singular_values(0))) {
    return absl::FailedPreconditionError(
        absl::StrCat("Umeyama: degenerate point sets (collinear or coincident); singular values ",
                     singular_values(0), ", ", singular_values(1), ", ", singular_values(2)));
  }

  // Reflection fix (Eq. 39/43): S = diag(1, 1, -1) when det(U) det(V) < 0.
  Eigen::Vector3d sign = Eigen::Vector3d::Ones();
  if (svd.matrixU().determinant() * svd.matrixV().determinant() < 0.0) sign(2) = -1.0;
  const Eigen::Matrix3d rotation =
      svd.matrixU() * sign.asDiagonal() * svd.matrixV().transpose();  // Eq. 40.
  const double scale = options.estimate_scale
                           ? singular_values.dot(sign) / variance_source  // Eq. 42.
                           : 1.0;
  const Eigen::Vector3d translation = mean_target - scale * rotation * mean_source;  // Eq. 41.
  if (!(scale > 0.0) || !translation.allFinite()) {
    return absl::FailedPreconditionError("Umeyama: fit produced a non-positive scale");
  }
  return Sim3d(scale, Eigen::Quaterniond(rotation), translation);
}

}  // namespace reenact
