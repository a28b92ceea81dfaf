#include "common/body/shape_space.h"

#include <algorithm>
#include <cmath>
#include <string>

#include <Eigen/Eigenvalues>

#include "absl/status/status.h"
#include "absl/strings/str_cat.h"

namespace reenact::body {
namespace {

// Views a 3 x V matrix as one 3V vector (column-major: x0 y0 z0 x1 ...).
Eigen::Map<const Eigen::VectorXd> Flat(const Eigen::Matrix3Xd& m) {
  return Eigen::Map<const Eigen::VectorXd>(m.data(), m.size());
}

absl::Status CheckPopulation(const std::vector<Eigen::Matrix3Xd>& population, int num_components) {
  if (population.empty()) return absl::InvalidArgumentError("empty population");
  const Eigen::Index num_vertices = population.front().cols();
  if (num_vertices == 0) return absl::InvalidArgumentError("member 0 has no vertices");
  for (size_t i = 0; i < population.size(); ++i) {
    if (population[i].cols() != num_vertices) {
      return absl::InvalidArgumentError(absl::StrCat("member ", i, " has ", population[i].cols(),
                                                     " vertices, member 0 has ", num_vertices));
    }
    if (!population[i].allFinite()) {
      return absl::InvalidArgumentError(absl::StrCat("member ", i, " is not finite"));
    }
  }
  const int max_components = static_cast<int>(population.size()) - 1;
  if (num_components < 1 || num_components > max_components) {
    return absl::InvalidArgumentError(absl::StrCat("num_components ", num_components,
                                                   " outside [1, ", max_components,
                                                   "] for a population of ", population.size()));
  }
  return absl::OkStatus();
}

}  // namespace

absl::StatusOr<ShapeSpace> LearnShapeSpace(const std::vector<Eigen::Matrix3Xd>& population,
                                           int num_components) {
  if (absl::Status status = CheckPopulation(population, num_components); !status.ok()) {
    return status;
  }
  const int n = static_cast<int>(population.size());
  const Eigen::Index dim = population.front().size();
  ShapeSpace space;
  space.mean_m = Eigen::Matrix3Xd::Zero(3, population.front().cols());
  for (const Eigen::Matrix3Xd& member : population) space.mean_m += member;
  space.mean_m /= n;

  // Centred data X (3V x N); its Gram matrix X^T X = V S^2 V^T shares the
  // non-zero eigenvalues of the covariance X X^T / (N - 1) up to that factor.
  Eigen::MatrixXd centred(dim, n);
  for (int i = 0; i < n; ++i) centred.col(i) = Flat(population[i]) - Flat(space.mean_m);
  Eigen::MatrixXd gram(n, n);
  gram.triangularView<Eigen::Lower>() = centred.transpose() * centred;
  gram.triangularView<Eigen::StrictlyUpper>() = gram.transpose();
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> solver(gram);
  if (solver.info() != Eigen::Success) {
    return absl::InternalError("eigen decomposition of the Gram matrix failed");
  }
  const Eigen::VectorXd& eigenvalues = solver.eigenvalues();  // Ascending.
  const double total = eigenvalues.cwiseMax(0.0).sum();
  if (!(total > 0.0)) return absl::InvalidArgumentError("population has no variance");

  for (int k = 0; k < num_components; ++k) {
    const int column = n - 1 - k;
    const double sigma_squared = std::max(eigenvalues(column), 0.0);
    // Principal direction u = X v / sigma; one standard deviation of the
    // covariance is sigma / sqrt(N - 1), so u * std = X v / sqrt(N - 1).
    Eigen::VectorXd scaled = centred * solver.eigenvectors().col(column) / std::sqrt(n - 1.0);
    // Fix the sign so results do not depend on the solver: the largest
    // coordinate is positive.
    Eigen::Index largest = 0;
    scaled.cwiseAbs().maxCoeff(&largest);
    if (scaled(largest) < 0) scaled = -scaled;
    space.directions_m.push_back(
        Eigen::Map<const Eigen::Matrix3Xd>(scaled.data(), 3, space.mean_m.cols()));
    space.explained_variance_ratio.push_back(sigma_squared / total);
  }
  return space;
}

absl::StatusOr<Eigen::VectorXd> ProjectOntoShapeSpace(const ShapeSpace& space,
                                                      const Eigen::Matrix3Xd& vertices_m) {
  if (space.directions_m.empty()) return absl::InvalidArgumentError("empty shape space");
  if (vertices_m.cols() != space.mean_m.cols()) {
    return absl::InvalidArgumentError(
        absl::StrCat("mesh has ", vertices_m.cols(), " vertices, the space ", space.mean_m.cols()));
  }
  const int k = static_cast<int>(space.directions_m.size());
  Eigen::MatrixXd basis(space.mean_m.size(), k);
  for (int i = 0; i < k; ++i) basis.col(i) = Flat(space.directions_m[i]);
  const Eigen::VectorXd residual = Flat(vertices_m) - Flat(space.mean_m);
  // Directions are orthogonal, so the normal equations are diagonal; solve
  // them in general form anyway to stay exact for any basis.
  const Eigen::MatrixXd normal = basis.transpose() * basis;
  return Eigen::VectorXd(normal.ldlt().solve(basis.transpose() * residual));
}

absl::StatusOr<Eigen::Matrix3Xd> ShapeFromCoefficients(const ShapeSpace& space,
                                                       const Eigen::VectorXd& beta) {
  if (beta.size() > static_cast<Eigen::Index>(space.directions_m.size())) {
    return absl::InvalidArgumentError(
        absl::StrCat(beta.size(), " coefficients for ", space.directions_m.size(), " components"));
  }
  Eigen::Matrix3Xd shape = space.mean_m;
  for (Eigen::Index k = 0; k < beta.size(); ++k) shape += beta(k) * space.directions_m[k];
  return shape;
}

}  // namespace reenact::body
