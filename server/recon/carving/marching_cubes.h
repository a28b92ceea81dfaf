// Marching cubes (W. E. Lorensen, H. E. Cline, "Marching cubes: a high
// resolution 3D surface construction algorithm", SIGGRAPH 1987; thesis [55])
// on a sampled signed distance field: the zero level set of the volume of a
// body part (thesis 3.4.1, "Body part mesh reconstruction").
//
// Conventions: positive values are outside, negative inside; a sample of
// exactly 0 counts as outside. Triangles are counter-clockwise seen from
// outside (their normals point toward positive values). Vertices lie on
// grid edges (linear interpolation of the two samples) and are welded: two
// cells that share an edge share its vertex, so a closed level set gives a
// watertight mesh. Normals are the normalised, interpolated gradient of the
// field (central differences).
//
// Departure from the 1987 paper: its 256-case triangle table (typed in by
// hand in most implementations) is generated here, once, by walking each
// cube face: on a face, crossing edges are paired so that each pair cuts off
// one run of negative corners (on the ambiguous face with two diagonal
// negative corners, each negative corner is cut off on its own), and each
// segment is oriented with the positive side on its left when the face is
// seen from outside the cube; the segments close into loops, each fanned
// into triangles from a vertex whose diagonals run through the cell's inside
// (never along a face, where they could meet the neighbour's). The face rule
// depends only on the face's four signs, so two cells sharing a face always
// agree on it and the mesh has no cracks (the original table's known holes
// at ambiguous faces do not occur).
#pragma once

#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "absl/status/status.h"
#include "absl/status/statusor.h"

namespace reenact::recon::carving {

// A scalar field sampled at the points origin + voxel * (x, y, z) of an
// nx x ny x nz grid (any frame, metres).
struct SdfGrid {
  int nx = 0;
  int ny = 0;
  int nz = 0;
  Eigen::Vector3d origin_m = Eigen::Vector3d::Zero();  // Position of sample (0, 0, 0).
  double voxel_m = 0.0;                                // Sample spacing.
  // Signed distance per sample, index x + nx * (y + ny * z); positive outside.
  std::vector<float> sdf;
  // Per sample: 0 when the sample has no value (the thesis' N*(v) = 0);
  // cells with such a corner make no triangles. Empty: every sample counts.
  std::vector<uint8_t> observed;

  size_t Index(int x, int y, int z) const {
    return static_cast<size_t>(x) + static_cast<size_t>(nx) * (y + static_cast<size_t>(ny) * z);
  }
  bool IsObserved(size_t index) const { return observed.empty() || observed[index] != 0; }
  // InvalidArgument for non-positive sizes or spacing, or arrays of the wrong length.
  absl::Status Validate() const;
};

// An indexed triangle mesh.
struct TriangleMesh {
  std::vector<Eigen::Vector3f> positions_m;
  std::vector<Eigen::Vector3f> normals;  // Unit length, one per position.
  std::vector<uint32_t> triangles;       // Three indices per triangle, counter-clockwise outside.

  int num_triangles() const { return static_cast<int>(triangles.size() / 3); }
};

// The zero level set of `grid` (see the file comment), in the grid's frame.
// InvalidArgument when the grid does not validate.
absl::StatusOr<TriangleMesh> MarchingCubes(const SdfGrid& grid);

// Keeps the connected components (through shared vertices) with at least
// `min_fraction` of the largest one's triangles, dropping small floaters;
// unused vertices are removed. min_fraction 1 keeps only the largest.
TriangleMesh KeepLargeComponents(const TriangleMesh& mesh, double min_fraction);

// Volume enclosed by a closed, outward-oriented mesh (divergence theorem),
// cubic metres; negative when the triangles face inward.
double EnclosedVolume(const TriangleMesh& mesh);

}  // namespace reenact::recon::carving
