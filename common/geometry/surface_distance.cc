#include "common/geometry/surface_distance.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "absl/strings/str_cat.h"

namespace reenact {

double PointTriangleDistance(const Eigen::Vector3d& p, const Eigen::Vector3d& a,
                             const Eigen::Vector3d& b, const Eigen::Vector3d& c) {
  // Ericson 5.1.5: find the Voronoi region of the triangle that holds p.
  const Eigen::Vector3d ab = b - a, ac = c - a, ap = p - a;
  const double d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0 && d2 <= 0) return ap.norm();  // Vertex a.
  const Eigen::Vector3d bp = p - b;
  const double d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0 && d4 <= d3) return bp.norm();  // Vertex b.
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) {  // Edge ab.
    const double v = d1 / (d1 - d3);
    return (p - (a + v * ab)).norm();
  }
  const Eigen::Vector3d cp = p - c;
  const double d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0 && d5 <= d6) return cp.norm();  // Vertex c.
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) {  // Edge ac.
    const double w = d2 / (d2 - d6);
    return (p - (a + w * ac)).norm();
  }
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) {  // Edge bc.
    const double w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
    return (p - (b + w * (c - b))).norm();
  }
  const double denom = va + vb + vc;
  if (!(std::abs(denom) > 0)) {  // Degenerate triangle: nearest of its corners.
    return std::min({ap.norm(), bp.norm(), cp.norm()});
  }
  const double v = vb / denom, w = vc / denom;  // Inside the face.
  return (p - (a + ab * v + ac * w)).norm();
}

absl::StatusOr<TriangleSurfaceIndex> TriangleSurfaceIndex::Build(
    const Eigen::Matrix3Xd& vertices_m, const std::vector<Eigen::Vector3i>& triangles,
    double cell_m) {
  if (triangles.empty() || vertices_m.cols() == 0) {
    return absl::InvalidArgumentError("surface index: no triangles");
  }
  if (!(cell_m > 0) || !std::isfinite(cell_m)) {
    return absl::InvalidArgumentError("surface index: the cell size must be positive");
  }
  if (!vertices_m.allFinite()) {
    return absl::InvalidArgumentError("surface index: a vertex is not finite");
  }
  for (const Eigen::Vector3i& t : triangles) {
    if ((t.array() < 0).any() || (t.array() >= vertices_m.cols()).any()) {
      return absl::InvalidArgumentError(absl::StrCat("surface index: triangle index out of range (",
                                                     vertices_m.cols(), " vertices)"));
    }
  }
  TriangleSurfaceIndex index;
  index.vertices_ = vertices_m;
  index.triangles_ = triangles;
  index.cell_ = cell_m;
  index.origin_ = vertices_m.rowwise().minCoeff();
  index.centres_.resize(3, static_cast<Eigen::Index>(triangles.size()));
  index.radii_.resize(triangles.size());
  for (size_t t = 0; t < triangles.size(); ++t) {
    const Eigen::Vector3d centre =
        (vertices_m.col(triangles[t][0]) + vertices_m.col(triangles[t][1]) +
         vertices_m.col(triangles[t][2])) /
        3.0;
    index.centres_.col(static_cast<Eigen::Index>(t)) = centre;
    index.radii_[t] = std::max({(vertices_m.col(triangles[t][0]) - centre).norm(),
                                (vertices_m.col(triangles[t][1]) - centre).norm(),
                                (vertices_m.col(triangles[t][2]) - centre).norm()});
  }
  const Eigen::Vector3d extent = vertices_m.rowwise().maxCoeff() - index.origin_;
  for (int a = 0; a < 3; ++a) index.dims_[a] = static_cast<int>(std::floor(extent[a] / cell_m)) + 1;
  const double num_cells = static_cast<double>(index.dims_[0]) * index.dims_[1] * index.dims_[2];
  if (num_cells > 16e6) {
    return absl::ResourceExhaustedError(
        absl::StrCat("surface index: ", num_cells, " cells; use a larger cell"));
  }
  // Two passes (count, fill) into compressed rows.
  auto cell_range = [&](const Eigen::Vector3i& t, Eigen::Vector3i* lo, Eigen::Vector3i* hi) {
    Eigen::Vector3d min = vertices_m.col(t[0]), max = min;
    for (int k = 1; k < 3; ++k) {
      min = min.cwiseMin(vertices_m.col(t[k]));
      max = max.cwiseMax(vertices_m.col(t[k]));
    }
    for (int a = 0; a < 3; ++a) {
      (*lo)[a] = std::clamp(static_cast<int>(std::floor((min[a] - index.origin_[a]) / cell_m)), 0,
                            index.dims_[a] - 1);
      (*hi)[a] = std::clamp(static_cast<int>(std::floor((max[a] - index.origin_[a]) / cell_m)), 0,
                            index.dims_[a] - 1);
    }
  };
  auto cell_id = [&](int x, int y, int z) {
    return (static_cast<size_t>(z) * index.dims_[1] + y) * index.dims_[0] + x;
  };
  index.cell_start_.assign(static_cast<size_t>(num_cells) + 1, 0);
  for (int pass = 0; pass < 2; ++pass) {
    std::vector<int> fill;
    if (pass == 1) {
      for (size_t i = 1; i < index.cell_start_.size(); ++i) {
        index.cell_start_[i] += index.cell_start_[i - 1];
      }
      index.cell_items_.resize(index.cell_start_.back());
      fill.assign(index.cell_start_.begin(), index.cell_start_.end() - 1);
    }
    for (size_t t = 0; t < triangles.size(); ++t) {
      Eigen::Vector3i lo, hi;
      cell_range(triangles[t], &lo, &hi);
      for (int z = lo.z(); z <= hi.z(); ++z) {
        for (int y = lo.y(); y <= hi.y(); ++y) {
          for (int x = lo.x(); x <= hi.x(); ++x) {
            if (pass == 0) {
              ++index.cell_start_[cell_id(x, y, z) + 1];
            } else {
              index.cell_items_[fill[cell_id(x, y, z)]++] = static_cast<int>(t);
            }
          }
        }
      }
    }
  }
  return index;
}

double TriangleSurfaceIndex::Distance(const Eigen::Vector3d& point_m) const {
  Eigen::Vector3i q;
  for (int a = 0; a < 3; ++a) {
    const double c = std::floor((point_m[a] - origin_[a]) / cell_);
    q[a] = static_cast<int>(std::clamp(c, -1e8, 1e8));
  }
  // Rings before the first that touches the grid are empty; past the last
  // one that does, nothing is left.
  int first_ring = 0, last_ring = 0;
  for (int a = 0; a < 3; ++a) {
    first_ring = std::max({first_ring, -q[a], q[a] - (dims_[a] - 1)});
    last_ring = std::max({last_ring, std::abs(q[a]), std::abs(q[a] - (dims_[a] - 1))});
  }
  double best = std::numeric_limits<double>::infinity();
  auto visit = [&](int x, int y, int z) {
    if (x < 0 || y < 0 || z < 0 || x >= dims_[0] || y >= dims_[1] || z >= dims_[2]) return;
    const size_t id = (static_cast<size_t>(z) * dims_[1] + y) * dims_[0] + x;
    for (int i = cell_start_[id]; i < cell_start_[id + 1]; ++i) {
      const int triangle = cell_items_[i];
      // The bounding sphere rules most triangles out cheaply.
      if ((point_m - centres_.col(triangle)).norm() - radii_[triangle] >= best) continue;
      const Eigen::Vector3i& t = triangles_[triangle];
      best = std::min(best, PointTriangleDistance(point_m, vertices_.col(t[0]), vertices_.col(t[1]),
                                                  vertices_.col(t[2])));
    }
  };
  // Distance from the point to the outside of the cells of rings 0..r: what
  // lies in ring r + 1 or beyond is at least this far.
  const Eigen::Vector3d in_cell = (point_m - origin_) / cell_ - q.cast<double>();
  double margin = 1.0;  // In cells, to the own cell's nearest face.
  for (int a = 0; a < 3; ++a) {
    margin = std::min({margin, std::max(0.0, in_cell[a]), std::max(0.0, 1.0 - in_cell[a])});
  }
  // Offsets of ring r along axis a, clipped to the grid.
  auto lo = [&](int a, int r) { return std::max(-r, -q[a]); };
  auto hi = [&](int a, int r) { return std::min(r, dims_[a] - 1 - q[a]); };
  for (int r = first_ring; r <= last_ring; ++r) {
    for (int dz = lo(2, r); dz <= hi(2, r); ++dz) {
      for (int dy = lo(1, r); dy <= hi(1, r); ++dy) {
        if (std::abs(dz) == r || std::abs(dy) == r) {  // A face of the shell: the whole row.
          for (int dx = lo(0, r); dx <= hi(0, r); ++dx) visit(q.x() + dx, q.y() + dy, q.z() + dz);
        } else {  // Inside the shell's faces: only its two ends.
          visit(q.x() - r, q.y() + dy, q.z() + dz);
          visit(q.x() + r, q.y() + dy, q.z() + dz);
        }
      }
    }
    if (best <= (r + margin) * cell_) break;
  }
  return best;
}

}  // namespace reenact
