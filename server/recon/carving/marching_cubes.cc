#include "server/recon/carving/marching_cubes.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <numeric>
#include <unordered_map>

#include <Eigen/Geometry>

#include "absl/strings/str_cat.h"

namespace reenact::recon::carving {
namespace {

// Cube corner c sits at (c & 1, (c >> 1) & 1, (c >> 2) & 1) in cell units.
Eigen::Vector3d CornerOffset(int corner) {
  return Eigen::Vector3d(corner & 1, (corner >> 1) & 1, (corner >> 2) & 1);
}

struct CubeEdge {
  int a = 0;     // Corner with the axis bit clear.
  int b = 0;     // Corner with the axis bit set.
  int axis = 0;  // 0 x, 1 y, 2 z.
};

// The 12 edges: for each axis, the four corners with that axis bit clear.
const std::array<CubeEdge, 12>& CubeEdges() {
  static const std::array<CubeEdge, 12> edges = [] {
    std::array<CubeEdge, 12> result;
    int index = 0;
    for (int axis = 0; axis < 3; ++axis) {
      for (int corner = 0; corner < 8; ++corner) {
        if (corner & (1 << axis)) continue;
        result[index++] = {corner, corner | (1 << axis), axis};
      }
    }
    return result;
  }();
  return edges;
}

int EdgeBetween(int c0, int c1) {
  const auto& edges = CubeEdges();
  for (int e = 0; e < 12; ++e) {
    if ((edges[e].a == c0 && edges[e].b == c1) || (edges[e].a == c1 && edges[e].b == c0)) return e;
  }
  return -1;  // Not reached for corners that differ in one bit.
}

// Triangles of one case as edge indices, three per triangle.
using CaseTriangles = std::vector<int8_t>;

// True when two cube edges lie on a common face: a face across an axis
// neither edge runs along, on the same side for both.
bool ShareFace(int e0, int e1) {
  const auto& edges = CubeEdges();
  for (int axis = 0; axis < 3; ++axis) {
    if (axis == edges[e0].axis || axis == edges[e1].axis) continue;
    if (((edges[e0].a >> axis) & 1) == ((edges[e1].a >> axis) & 1)) return true;
  }
  return false;
}

// Fans `loop` into triangles. A fan diagonal that lay on a cube face could
// meet the same diagonal of the neighbouring cell (four triangles on one
// edge), so the fan root is one whose diagonals all cross the cell's
// inside; every one of the 256 cases has such a root (the test
// MarchingCubes.EveryCaseIsClosed checks each).
void FanLoop(const std::vector<int>& loop, CaseTriangles* out) {
  const int k = static_cast<int>(loop.size());
  int root = 0;
  for (int candidate = 0; candidate < k; ++candidate) {
    bool clean = true;
    for (int i = 2; i + 1 < k && clean; ++i) {
      if (ShareFace(loop[candidate], loop[(candidate + i) % k])) clean = false;
    }
    if (clean) {
      root = candidate;
      break;
    }
  }
  for (int i = 1; i + 1 < k; ++i) {
    out->push_back(static_cast<int8_t>(loop[root]));
    out->push_back(static_cast<int8_t>(loop[(root + i) % k]));
    out->push_back(static_cast<int8_t>(loop[(root + i + 1) % k]));
  }
}

// Builds the triangles of one case (bit c of `negative_mask` set: corner c is
// negative) by the face walk of the header comment.
CaseTriangles BuildCase(int negative_mask) {
  auto negative = [&](int corner) { return (negative_mask >> corner) & 1; };
  std::array<int, 12> next_edge;  // Directed segments: from edge -> to edge.
  next_edge.fill(-1);
  for (int axis = 0; axis < 3; ++axis) {
    const int u = (axis + 1) % 3;
    const int v = (axis + 2) % 3;
    for (int side = 0; side < 2; ++side) {
      // Face corners in cyclic order around the face.
      const int base = side << axis;
      const std::array<int, 4> ring = {base, base | (1 << u), base | (1 << u) | (1 << v),
                                       base | (1 << v)};
      Eigen::Vector3d face_normal = Eigen::Vector3d::Zero();
      face_normal[axis] = side ? 1.0 : -1.0;
      // Pair each positive->negative crossing with the next negative->positive
      // one going round the ring: each pair cuts off one run of negatives.
      for (int start = 0; start < 4; ++start) {
        if (negative(ring[start]) || !negative(ring[(start + 1) % 4])) continue;
        int end = (start + 1) % 4;
        std::vector<int> run;
        while (negative(ring[end])) {
          run.push_back(ring[end]);
          end = (end + 1) % 4;
        }
        const int in_corner = ring[(end + 3) % 4];  // Last negative of the run.
        const int e0 = EdgeBetween(ring[start], ring[(start + 1) % 4]);
        const int e1 = EdgeBetween(in_corner, ring[end]);
        // Orientation: (face normal x direction) points to the positive side.
        const auto& edges = CubeEdges();
        auto mid = [&](int e) -> Eigen::Vector3d {
          return 0.5 * (CornerOffset(edges[e].a) + CornerOffset(edges[e].b));
        };
        Eigen::Vector3d run_centre = Eigen::Vector3d::Zero();
        for (int corner : run) run_centre += CornerOffset(corner);
        run_centre /= static_cast<double>(run.size());
        const Eigen::Vector3d direction = mid(e1) - mid(e0);
        const Eigen::Vector3d segment_mid = 0.5 * (mid(e0) + mid(e1));
        const bool keep = face_normal.cross(direction).dot(run_centre - segment_mid) < 0.0;
        if (keep) {
          next_edge[e0] = e1;
        } else {
          next_edge[e1] = e0;
        }
      }
    }
  }
  // Close the segments into loops and fan each loop into triangles.
  CaseTriangles triangles;
  std::array<bool, 12> used{};
  for (int first = 0; first < 12; ++first) {
    if (next_edge[first] < 0 || used[first]) continue;
    std::vector<int> loop;
    for (int e = first; e >= 0 && !used[e]; e = next_edge[e]) {
      used[e] = true;
      loop.push_back(e);
    }
    FanLoop(loop, &triangles);
  }
  return triangles;
}

const std::array<CaseTriangles, 256>& TriangleTable() {
  static const std::array<CaseTriangles, 256> table = [] {
    std::array<CaseTriangles, 256> result;
    for (int mask = 0; mask < 256; ++mask) result[mask] = BuildCase(mask);
    return result;
  }();
  return table;
}

// Central-difference gradient of the field at a sample (one-sided next to
// the border or an unobserved neighbour; 0 along an axis with neither).
Eigen::Vector3f Gradient(const SdfGrid& grid, int x, int y, int z) {
  const std::array<int, 3> at = {x, y, z};
  const std::array<int, 3> size = {grid.nx, grid.ny, grid.nz};
  const float centre = grid.sdf[grid.Index(x, y, z)];
  Eigen::Vector3f gradient = Eigen::Vector3f::Zero();
  for (int axis = 0; axis < 3; ++axis) {
    std::array<int, 3> lo = at;
    std::array<int, 3> hi = at;
    --lo[axis];
    ++hi[axis];
    const bool has_lo = lo[axis] >= 0 && grid.IsObserved(grid.Index(lo[0], lo[1], lo[2]));
    const bool has_hi = hi[axis] < size[axis] && grid.IsObserved(grid.Index(hi[0], hi[1], hi[2]));
    const float lo_value = has_lo ? grid.sdf[grid.Index(lo[0], lo[1], lo[2])] : centre;
    const float hi_value = has_hi ? grid.sdf[grid.Index(hi[0], hi[1], hi[2])] : centre;
    const int steps = static_cast<int>(has_lo) + static_cast<int>(has_hi);
    if (steps > 0) gradient[axis] = (hi_value - lo_value) / static_cast<float>(steps);
  }
  return gradient;
}

// Builds the mesh; vertices are keyed by their grid edge (3 * sample + axis).
class Mesher {
 public:
  explicit Mesher(const SdfGrid& grid) : grid_(grid) {}

  TriangleMesh Run() {
    const auto& table = TriangleTable();
    for (int z = 0; z + 1 < grid_.nz; ++z) {
      for (int y = 0; y + 1 < grid_.ny; ++y) {
        for (int x = 0; x + 1 < grid_.nx; ++x) MeshCell(table, x, y, z);
      }
    }
    FillMissingNormals();
    return std::move(mesh_);
  }

 private:
  void MeshCell(const std::array<CaseTriangles, 256>& table, int x, int y, int z) {
    int mask = 0;
    for (int corner = 0; corner < 8; ++corner) {
      const size_t index =
          grid_.Index(x + (corner & 1), y + ((corner >> 1) & 1), z + ((corner >> 2) & 1));
      if (!grid_.IsObserved(index)) return;  // N* = 0 at a corner: skipped.
      if (grid_.sdf[index] < 0.0f) mask |= 1 << corner;
    }
    for (int8_t edge : table[mask]) {
      mesh_.triangles.push_back(VertexOnEdge(x, y, z, CubeEdges()[edge]));
    }
  }

  uint32_t VertexOnEdge(int x, int y, int z, const CubeEdge& edge) {
    const int ax = x + (edge.a & 1);
    const int ay = y + ((edge.a >> 1) & 1);
    const int az = z + ((edge.a >> 2) & 1);
    const size_t key = 3 * grid_.Index(ax, ay, az) + edge.axis;
    auto [it, inserted] = vertex_of_edge_.try_emplace(key, 0);
    if (!inserted) return it->second;
    const int bx = ax + (edge.axis == 0);
    const int by = ay + (edge.axis == 1);
    const int bz = az + (edge.axis == 2);
    const float va = grid_.sdf[grid_.Index(ax, ay, az)];
    const float vb = grid_.sdf[grid_.Index(bx, by, bz)];
    const float t = std::clamp(va / (va - vb), 0.0f, 1.0f);
    const Eigen::Vector3d pa = grid_.origin_m + grid_.voxel_m * Eigen::Vector3d(ax, ay, az);
    Eigen::Vector3d position = pa;
    position[edge.axis] += t * grid_.voxel_m;
    const Eigen::Vector3f gradient =
        (1.0f - t) * Gradient(grid_, ax, ay, az) + t * Gradient(grid_, bx, by, bz);
    const float norm = gradient.norm();
    it->second = static_cast<uint32_t>(mesh_.positions_m.size());
    mesh_.positions_m.push_back(position.cast<float>());
    mesh_.normals.push_back(norm > 0.0f ? Eigen::Vector3f(gradient / norm)
                                        : Eigen::Vector3f::Zero());
    return it->second;
  }

  // A vertex whose gradient vanished takes the mean of its triangles' normals.
  void FillMissingNormals() {
    std::vector<Eigen::Vector3f> face_sum(mesh_.positions_m.size(), Eigen::Vector3f::Zero());
    for (size_t t = 0; t + 2 < mesh_.triangles.size(); t += 3) {
      const Eigen::Vector3f& p0 = mesh_.positions_m[mesh_.triangles[t]];
      const Eigen::Vector3f& p1 = mesh_.positions_m[mesh_.triangles[t + 1]];
      const Eigen::Vector3f& p2 = mesh_.positions_m[mesh_.triangles[t + 2]];
      const Eigen::Vector3f area_normal = (p1 - p0).cross(p2 - p0);
      for (int k = 0; k < 3; ++k) face_sum[mesh_.triangles[t + k]] += area_normal;
    }
    for (size_t v = 0; v < mesh_.normals.size(); ++v) {
      if (mesh_.normals[v].squaredNorm() > 0.0f) continue;
      const float norm = face_sum[v].norm();
      mesh_.normals[v] =
          norm > 0.0f ? Eigen::Vector3f(face_sum[v] / norm) : Eigen::Vector3f::UnitY();
    }
  }

  const SdfGrid& grid_;
  TriangleMesh mesh_;
  std::unordered_map<size_t, uint32_t> vertex_of_edge_;
};

// Union-find over vertices.
int FindRoot(std::vector<int>& parent, int v) {
  while (parent[v] != v) {
    parent[v] = parent[parent[v]];
    v = parent[v];
  }
  return v;
}

}  // namespace

absl::Status SdfGrid::Validate() const {
  if (nx <= 0 || ny <= 0 || nz <= 0) {
    return absl::InvalidArgumentError(absl::StrCat("SdfGrid: size ", nx, "x", ny, "x", nz));
  }
  if (!(voxel_m > 0.0) || !std::isfinite(voxel_m)) {
    return absl::InvalidArgumentError(absl::StrCat("SdfGrid: voxel_m ", voxel_m));
  }
  const size_t count = static_cast<size_t>(nx) * ny * nz;
  if (sdf.size() != count) {
    return absl::InvalidArgumentError(
        absl::StrCat("SdfGrid: ", sdf.size(), " values for ", count, " samples"));
  }
  if (!observed.empty() && observed.size() != count) {
    return absl::InvalidArgumentError(
        absl::StrCat("SdfGrid: ", observed.size(), " observed flags for ", count, " samples"));
  }
  return absl::OkStatus();
}

absl::StatusOr<TriangleMesh> MarchingCubes(const SdfGrid& grid) {
  if (absl::Status status = grid.Validate(); !status.ok()) return status;
  return Mesher(grid).Run();
}

TriangleMesh KeepLargeComponents(const TriangleMesh& mesh, double min_fraction) {
  const int num_vertices = static_cast<int>(mesh.positions_m.size());
  std::vector<int> parent(num_vertices);
  std::iota(parent.begin(), parent.end(), 0);
  for (size_t t = 0; t + 2 < mesh.triangles.size(); t += 3) {
    const int r0 = FindRoot(parent, static_cast<int>(mesh.triangles[t]));
    for (int k = 1; k < 3; ++k) {
      const int rk = FindRoot(parent, static_cast<int>(mesh.triangles[t + k]));
      if (rk != r0) parent[rk] = r0;
    }
  }
  std::unordered_map<int, int> triangles_of_root;
  for (size_t t = 0; t < mesh.triangles.size(); t += 3) {
    ++triangles_of_root[FindRoot(parent, static_cast<int>(mesh.triangles[t]))];
  }
  int largest = 0;
  for (const auto& [root, count] : triangles_of_root) largest = std::max(largest, count);
  TriangleMesh kept;
  std::vector<int> new_index(num_vertices, -1);
  for (size_t t = 0; t + 2 < mesh.triangles.size(); t += 3) {
    const int root = FindRoot(parent, static_cast<int>(mesh.triangles[t]));
    if (triangles_of_root[root] < min_fraction * largest) continue;
    for (int k = 0; k < 3; ++k) {
      const uint32_t v = mesh.triangles[t + k];
      if (new_index[v] < 0) {
        new_index[v] = static_cast<int>(kept.positions_m.size());
        kept.positions_m.push_back(mesh.positions_m[v]);
        kept.normals.push_back(mesh.normals[v]);
      }
      kept.triangles.push_back(static_cast<uint32_t>(new_index[v]));
    }
  }
  return kept;
}

double EnclosedVolume(const TriangleMesh& mesh) {
  double six_volume = 0.0;
  for (size_t t = 0; t + 2 < mesh.triangles.size(); t += 3) {
    const Eigen::Vector3d p0 = mesh.positions_m[mesh.triangles[t]].cast<double>();
    const Eigen::Vector3d p1 = mesh.positions_m[mesh.triangles[t + 1]].cast<double>();
    const Eigen::Vector3d p2 = mesh.positions_m[mesh.triangles[t + 2]].cast<double>();
    six_volume += p0.dot(p1.cross(p2));
  }
  return six_volume / 6.0;
}

}  // namespace reenact::recon::carving
