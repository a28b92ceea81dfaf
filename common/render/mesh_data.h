// Triangle meshes as the renderer takes them: one GPU vertex per (position,
// uv) pair, plus the helpers that build that layout from meshes whose uv
// seams are stored per triangle corner (common/body/body_model.h).
#pragma once

#include <vector>

#include <Eigen/Core>

#include "absl/status/status.h"
#include "absl/status/statusor.h"

namespace reenact::render {

// A triangle mesh in its model frame. Per-vertex attributes are columns; the
// optional ones are either empty or have one column per vertex.
struct MeshData {
  // Vertex positions, metres, model frame. 3 x N.
  Eigen::Matrix3Xf positions_m;
  // Optional unit vertex normals, model frame, pointing out of the surface.
  // 3 x N or empty (lit draws then use the face normal).
  Eigen::Matrix3Xf normals;
  // Optional texture coordinates in [0,1]^2 with v up: (0,0) is the bottom
  // left of the texture image, (0,1) its top left. 2 x N or empty.
  Eigen::Matrix2Xf uvs;
  // Optional vertex colours, sRGB components in [0,1]. 3 x N or empty.
  Eigen::Matrix3Xf colours_srgb;
  // Triangles, counter-clockwise seen from outside, indices into the vertices.
  std::vector<Eigen::Vector3i> triangles;
  // Optional remap to an original mesh whose seams were split
  // (MeshFromCornerUvs): vertex i is a copy of original vertex
  // source_vertex[i]. Empty, or N entries in [0, num_source_vertices).
  std::vector<int> source_vertex;
  // Number of vertices of the original mesh; used only with source_vertex.
  int num_source_vertices = 0;

  int num_vertices() const { return static_cast<int>(positions_m.cols()); }
};

// Checks attribute sizes, index ranges, the remap and finiteness of the
// positions; InvalidArgument naming the first problem.
absl::Status ValidateMeshData(const MeshData& mesh);

// Area-weighted vertex normals (unit, pointing to the side from which the
// triangles are counter-clockwise) of a 3 x V mesh; vertices that belong to no
// triangle, or only to degenerate ones, get (0, 0, 0). Indices must be valid.
Eigen::Matrix3Xf ComputeVertexNormals(const Eigen::Matrix3Xf& positions_m,
                                      const std::vector<Eigen::Vector3i>& triangles);

// Builds the GPU layout of a mesh whose uvs are indexed per triangle corner
// (BodyModel::uvs / uv_triangles): every distinct (position, uv) pair becomes
// one vertex, and MeshData::source_vertex records the original vertex of each
// so that OffscreenRenderer::UpdateMeshPositions takes the original 3 x V
// positions. `normals` (3 x V, or empty to compute them with
// ComputeVertexNormals across the seams, so shading shows no seam) are copied
// per vertex. InvalidArgument on mismatched sizes or out-of-range indices.
absl::StatusOr<MeshData> MeshFromCornerUvs(const Eigen::Matrix3Xf& positions_m,
                                           const std::vector<Eigen::Vector3i>& triangles,
                                           const std::vector<Eigen::Vector2f>& uvs,
                                           const std::vector<Eigen::Vector3i>& uv_triangles,
                                           const Eigen::Matrix3Xf& normals = Eigen::Matrix3Xf());

// A sphere of `radius_m` centred on the model origin, with `num_segments`
// (>= 3) around +Y and `num_rings` (>= 2) from pole to pole; has normals and
// equirectangular uvs (u along longitude, v up), and 2 * num_segments *
// (num_rings - 1) triangles. The seam column is duplicated so uvs stay
// continuous.
MeshData MakeUvSphere(float radius_m, int num_segments, int num_rings);

// A flat quad in the model's y = 0 plane spanning [-w/2, w/2] x [-d/2, d/2],
// facing +Y (normals +Y, counter-clockwise seen from above), with uvs that
// put a texture's top row at -Z and its left column at -X: a printed sheet or
// a floor lying face up.
MeshData MakeFloorQuad(double width_m, double depth_m);

}  // namespace reenact::render
