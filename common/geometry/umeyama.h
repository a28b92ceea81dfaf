// Closed-form least-squares similarity between two corresponding point sets.
//
// Solves thesis Eq. 3.1,
//   (R, t, s) = argmin sum_m || p_m - (s R q_m + t) ||^2,
// with the method of S. Umeyama, "Least-Squares Estimation of Transformation
// Parameters Between Two Point Patterns", IEEE TPAMI 13(4), 1991 (Eqs. 38-43):
// an SVD of the cross-covariance of the centred sets, with the sign correction
// that keeps R a proper rotation when the best orthogonal fit is a reflection.
#pragma once

#include <vector>

#include <Eigen/Core>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "common/geometry/transforms.h"

namespace reenact {

struct UmeyamaOptions {
  // Estimate s; when false, s = 1 and the fit is rigid.
  bool estimate_scale = true;
  // The fit is rejected as degenerate (points collinear or coincident) when the
  // second singular value of the cross-covariance is below this fraction of
  // the first. Must be in [0, 1).
  double min_singular_value_ratio = 1e-9;

  absl::Status Validate() const;
};

// Fits target_from_source = (s, R, t) so that points_in_target[m] is close to
// s R points_in_source[m] + t (thesis Eq. 3.1: p_m = target, q_m = source).
// Units are whatever the inputs use; the translation comes out in target
// units and s is target units per source unit.
//
// Errors: InvalidArgument when the sets differ in size, hold fewer than 3
// points, contain NaN/Inf, or the options are invalid; FailedPrecondition when
// the source or target points are coincident or collinear (no unique
// rotation).
absl::StatusOr<Sim3d> FitSimilarityUmeyama(const std::vector<Eigen::Vector3d>& points_in_source,
                                           const std::vector<Eigen::Vector3d>& points_in_target,
                                           const UmeyamaOptions& options = {});

}  // namespace reenact
