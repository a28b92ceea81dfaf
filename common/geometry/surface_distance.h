// Distance from points to a triangle surface, accelerated by a uniform grid
// of triangle buckets: the query visits cells in growing rings (Chebyshev
// shells) around its own and stops once the next ring cannot hold anything
// nearer; a bounding sphere per triangle skips the exact test of triangles
// that cannot beat the best so far. Exact point-to-triangle distance by the closest point's Voronoi
// region (C. Ericson, "Real-Time Collision Detection", 2005, sec. 5.1.5).
#pragma once

#include <vector>

#include <Eigen/Core>

#include "absl/status/statusor.h"

namespace reenact {

// Unsigned distance from `p` to the triangle (a, b, c), any unit.
double PointTriangleDistance(const Eigen::Vector3d& p, const Eigen::Vector3d& a,
                             const Eigen::Vector3d& b, const Eigen::Vector3d& c);

class TriangleSurfaceIndex {
 public:
  // Builds the grid over `vertices_m` (3 x N) and `triangles`, with cells of
  // `cell_m`. InvalidArgument for an empty surface, an index out of range, a
  // non-finite vertex or a cell that is not positive; ResourceExhausted when
  // the grid would exceed ~16 M cells.
  static absl::StatusOr<TriangleSurfaceIndex> Build(const Eigen::Matrix3Xd& vertices_m,
                                                    const std::vector<Eigen::Vector3i>& triangles,
                                                    double cell_m = 0.02);

  // Distance from `point_m` to the nearest triangle, metres.
  double Distance(const Eigen::Vector3d& point_m) const;

 private:
  Eigen::Matrix3Xd vertices_;
  std::vector<Eigen::Vector3i> triangles_;
  Eigen::Matrix3Xd centres_;  // Per triangle: centroid and bounding radius.
  std::vector<double> radii_;
  Eigen::Vector3d origin_;
  double cell_ = 0.02;
  Eigen::Vector3i dims_;
  std::vector<int>
      cell_start_;  // CSR: triangles of cell i are cell_items_[start[i] .. start[i+1]).
  std::vector<int> cell_items_;
};

}  // namespace reenact
