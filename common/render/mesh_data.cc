#include "common/render/mesh_data.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <numbers>
#include <unordered_map>

#include <Eigen/Geometry>

#include "absl/strings/str_cat.h"

namespace reenact::render {
namespace {

absl::Status CheckColumns(const char* name, Eigen::Index cols, int num_vertices) {
  if (cols != 0 && cols != num_vertices) {
    return absl::InvalidArgumentError(
        absl::StrCat("MeshData: ", name, " has ", cols, " columns, expected 0 or ", num_vertices));
  }
  return absl::OkStatus();
}

absl::Status CheckTriangles(const char* name, const std::vector<Eigen::Vector3i>& triangles,
                            int num_vertices) {
  for (size_t t = 0; t < triangles.size(); ++t) {
    for (int k = 0; k < 3; ++k) {
      if (triangles[t][k] < 0 || triangles[t][k] >= num_vertices) {
        return absl::InvalidArgumentError(absl::StrCat(name, " ", t, " has index ", triangles[t][k],
                                                       ", outside [0, ", num_vertices, ")"));
      }
    }
  }
  return absl::OkStatus();
}

}  // namespace

absl::Status ValidateMeshData(const MeshData& mesh) {
  const int n = mesh.num_vertices();
  if (n == 0 || mesh.triangles.empty()) {
    return absl::InvalidArgumentError("MeshData: no vertices or no triangles");
  }
  if (!mesh.positions_m.allFinite()) {
    return absl::InvalidArgumentError("MeshData: positions_m has non-finite values");
  }
  if (auto s = CheckColumns("normals", mesh.normals.cols(), n); !s.ok()) return s;
  if (auto s = CheckColumns("uvs", mesh.uvs.cols(), n); !s.ok()) return s;
  if (auto s = CheckColumns("colours_srgb", mesh.colours_srgb.cols(), n); !s.ok()) return s;
  if (auto s = CheckTriangles("MeshData: triangle", mesh.triangles, n); !s.ok()) return s;
  if (mesh.source_vertex.empty()) return absl::OkStatus();
  if (static_cast<int>(mesh.source_vertex.size()) != n) {
    return absl::InvalidArgumentError(absl::StrCat(
        "MeshData: source_vertex has ", mesh.source_vertex.size(), " entries, expected ", n));
  }
  for (int s : mesh.source_vertex) {
    if (s < 0 || s >= mesh.num_source_vertices) {
      return absl::InvalidArgumentError(absl::StrCat(
          "MeshData: source_vertex entry ", s, " outside [0, ", mesh.num_source_vertices, ")"));
    }
  }
  return absl::OkStatus();
}

Eigen::Matrix3Xf ComputeVertexNormals(const Eigen::Matrix3Xf& positions_m,
                                      const std::vector<Eigen::Vector3i>& triangles) {
  Eigen::Matrix3Xf normals = Eigen::Matrix3Xf::Zero(3, positions_m.cols());
  for (const Eigen::Vector3i& t : triangles) {
    const Eigen::Vector3f a = positions_m.col(t[0]);
    // The cross product's length is twice the area: area weighting for free.
    const Eigen::Vector3f n = (positions_m.col(t[1]) - a).cross(positions_m.col(t[2]) - a);
    for (int k = 0; k < 3; ++k) normals.col(t[k]) += n;
  }
  for (Eigen::Index i = 0; i < normals.cols(); ++i) {
    const float length = normals.col(i).norm();
    if (length > 0.0f) normals.col(i) /= length;
  }
  return normals;
}

absl::StatusOr<MeshData> MeshFromCornerUvs(const Eigen::Matrix3Xf& positions_m,
                                           const std::vector<Eigen::Vector3i>& triangles,
                                           const std::vector<Eigen::Vector2f>& uvs,
                                           const std::vector<Eigen::Vector3i>& uv_triangles,
                                           const Eigen::Matrix3Xf& normals) {
  const int num_positions = static_cast<int>(positions_m.cols());
  if (uv_triangles.size() != triangles.size()) {
    return absl::InvalidArgumentError(absl::StrCat("MeshFromCornerUvs: ", triangles.size(),
                                                   " triangles but ", uv_triangles.size(),
                                                   " uv triangles"));
  }
  if (normals.cols() != 0 && normals.cols() != num_positions) {
    return absl::InvalidArgumentError("MeshFromCornerUvs: normals must be empty or 3 x V");
  }
  if (auto s = CheckTriangles("MeshFromCornerUvs: triangle", triangles, num_positions); !s.ok()) {
    return s;
  }
  if (auto s = CheckTriangles("MeshFromCornerUvs: uv triangle", uv_triangles,
                              static_cast<int>(uvs.size()));
      !s.ok()) {
    return s;
  }
  const Eigen::Matrix3Xf source_normals =
      normals.cols() != 0 ? normals : ComputeVertexNormals(positions_m, triangles);

  MeshData mesh;
  mesh.num_source_vertices = num_positions;
  mesh.triangles.resize(triangles.size());
  std::unordered_map<int64_t, int> vertex_of_pair;
  vertex_of_pair.reserve(triangles.size() * 2);
  for (size_t t = 0; t < triangles.size(); ++t) {
    for (int k = 0; k < 3; ++k) {
      const int64_t key = static_cast<int64_t>(triangles[t][k]) * static_cast<int64_t>(uvs.size()) +
                          uv_triangles[t][k];
      auto [it, inserted] =
          vertex_of_pair.emplace(key, static_cast<int>(mesh.source_vertex.size()));
      if (inserted) mesh.source_vertex.push_back(triangles[t][k]);
      mesh.triangles[t][k] = it->second;
    }
  }
  const int n = static_cast<int>(mesh.source_vertex.size());
  mesh.positions_m.resize(3, n);
  mesh.normals.resize(3, n);
  mesh.uvs.resize(2, n);
  for (size_t t = 0; t < triangles.size(); ++t) {
    for (int k = 0; k < 3; ++k) mesh.uvs.col(mesh.triangles[t][k]) = uvs[uv_triangles[t][k]];
  }
  for (int i = 0; i < n; ++i) {
    mesh.positions_m.col(i) = positions_m.col(mesh.source_vertex[i]);
    mesh.normals.col(i) = source_normals.col(mesh.source_vertex[i]);
  }
  return mesh;
}

MeshData MakeUvSphere(float radius_m, int num_segments, int num_rings) {
  num_segments = std::max(num_segments, 3);
  num_rings = std::max(num_rings, 2);
  const int columns = num_segments + 1;  // The seam column is duplicated.
  MeshData mesh;
  mesh.positions_m.resize(3, columns * (num_rings + 1));
  mesh.normals.resize(3, mesh.positions_m.cols());
  mesh.uvs.resize(2, mesh.positions_m.cols());
  for (int r = 0; r <= num_rings; ++r) {
    const double polar = std::numbers::pi * r / num_rings;  // 0 at the top (+Y).
    for (int s = 0; s < columns; ++s) {
      const double azimuth = 2.0 * std::numbers::pi * s / num_segments;
      const Eigen::Vector3f n(static_cast<float>(std::sin(polar) * std::sin(azimuth)),
                              static_cast<float>(std::cos(polar)),
                              static_cast<float>(std::sin(polar) * std::cos(azimuth)));
      const int i = r * columns + s;
      mesh.normals.col(i) = n;
      mesh.positions_m.col(i) = radius_m * n;
      mesh.uvs.col(i) = Eigen::Vector2f(static_cast<float>(s) / num_segments,
                                        1.0f - static_cast<float>(r) / num_rings);
    }
  }
  for (int r = 0; r < num_rings; ++r) {
    for (int s = 0; s < num_segments; ++s) {
      const int a = r * columns + s, b = a + 1, c = a + columns, d = c + 1;
      // Counter-clockwise seen from outside; the pole rows have one triangle.
      if (r != 0) mesh.triangles.emplace_back(a, c, b);
      if (r != num_rings - 1) mesh.triangles.emplace_back(b, c, d);
    }
  }
  return mesh;
}

MeshData MakeFloorQuad(double width_m, double depth_m) {
  const float hw = static_cast<float>(0.5 * width_m);
  const float hd = static_cast<float>(0.5 * depth_m);
  MeshData mesh;
  mesh.positions_m.resize(3, 4);
  mesh.positions_m << -hw, -hw, hw, hw,  // Corners: -X-Z, -X+Z, +X+Z, +X-Z.
      0, 0, 0, 0,                        //
      -hd, hd, hd, -hd;
  mesh.uvs.resize(2, 4);
  mesh.uvs << 0, 0, 1, 1,  //
      1, 0, 0, 1;
  mesh.normals = Eigen::Matrix3Xf::Zero(3, 4);
  mesh.normals.row(1).setOnes();
  mesh.triangles = {{0, 1, 2}, {0, 2, 3}};  // Counter-clockwise seen from +Y.
  return mesh;
}

}  // namespace reenact::render
