// A linear shape space learned by principal component analysis (PCA) from a
// population of meshes in correspondence (same vertex count and order), as
// in SMPL (Loper et al. 2015, Sec. 3.2: "shape blend shapes" are the leading
// principal components of registered training meshes).
#pragma once

#include <vector>

#include <Eigen/Core>

#include "absl/status/statusor.h"

namespace reenact::body {

struct ShapeSpace {
  // Population mean, metres, 3 x V.
  Eigen::Matrix3Xd mean_m;
  // Principal directions, 3 x V each, ordered by decreasing variance and
  // scaled by the square root of their eigenvalue: mean + 1.0 * direction is
  // one standard deviation along that component.
  std::vector<Eigen::Matrix3Xd> directions_m;
  // Per component, its variance divided by the total population variance.
  std::vector<double> explained_variance_ratio;
};

// PCA of `population` (each 3 x V, all the same V, metres). Uses the N x N
// Gram matrix of the centred data (N = population size), so the cost grows
// with N^2 V rather than V^2. Keeps `num_components` components; fewer exist
// when N - 1 < num_components, which is InvalidArgument, as are an empty
// population, mismatched sizes or non-finite coordinates.
absl::StatusOr<ShapeSpace> LearnShapeSpace(const std::vector<Eigen::Matrix3Xd>& population,
                                           int num_components);

// Coefficients (in standard deviations) of the least-squares fit of
// `vertices_m` (3 x V) by mean + sum_k beta_k direction_k. InvalidArgument on
// a size mismatch or an empty space.
absl::StatusOr<Eigen::VectorXd> ProjectOntoShapeSpace(const ShapeSpace& space,
                                                      const Eigen::Matrix3Xd& vertices_m);

// mean + sum_k beta_k direction_k; `beta` may be shorter than the number of
// components (missing ones are 0); longer is InvalidArgument.
absl::StatusOr<Eigen::Matrix3Xd> ShapeFromCoefficients(const ShapeSpace& space,
                                                       const Eigen::VectorXd& beta);

}  // namespace reenact::body
