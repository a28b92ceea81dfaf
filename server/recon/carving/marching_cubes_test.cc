#include "server/recon/carving/marching_cubes.h"

#include <cmath>
#include <map>
#include <random>
#include <set>
#include <utility>

#include <gtest/gtest.h>

namespace reenact::recon::carving {
namespace {

constexpr double kPi = 3.14159265358979323846;

// A sphere's signed distance (positive outside) sampled on a grid.
SdfGrid SphereGrid(int n, double voxel_m, const Eigen::Vector3d& centre_m, double radius_m) {
  SdfGrid grid;
  grid.nx = grid.ny = grid.nz = n;
  grid.voxel_m = voxel_m;
  grid.origin_m =
      Eigen::Vector3d(-0.5 * (n - 1) * voxel_m, -0.5 * (n - 1) * voxel_m, -0.5 * (n - 1) * voxel_m);
  grid.sdf.resize(static_cast<size_t>(n) * n * n);
  for (int z = 0; z < n; ++z) {
    for (int y = 0; y < n; ++y) {
      for (int x = 0; x < n; ++x) {
        const Eigen::Vector3d p = grid.origin_m + voxel_m * Eigen::Vector3d(x, y, z);
        grid.sdf[grid.Index(x, y, z)] = static_cast<float>((p - centre_m).norm() - radius_m);
      }
    }
  }
  return grid;
}

struct EdgeCheck {
  int edges = 0;
  int boundary_or_nonmanifold = 0;  // Undirected edges not in exactly two triangles.
  int inconsistent = 0;             // Directed edges used twice in one direction.
};

// Every undirected edge must be in exactly two triangles, once in each
// direction (watertight and consistently oriented).
EdgeCheck CheckEdges(const TriangleMesh& mesh) {
  std::map<std::pair<uint32_t, uint32_t>, int> directed;
  for (size_t t = 0; t + 2 < mesh.triangles.size(); t += 3) {
    for (int k = 0; k < 3; ++k) {
      ++directed[{mesh.triangles[t + k], mesh.triangles[t + (k + 1) % 3]}];
    }
  }
  EdgeCheck check;
  for (const auto& [edge, count] : directed) {
    if (count != 1) ++check.inconsistent;
    const auto reverse = directed.find({edge.second, edge.first});
    const int reverse_count = reverse == directed.end() ? 0 : reverse->second;
    if (edge.first < edge.second) {
      ++check.edges;
      if (count + reverse_count != 2) ++check.boundary_or_nonmanifold;
    } else if (reverse_count == 0) {
      ++check.edges;
      ++check.boundary_or_nonmanifold;
    }
  }
  return check;
}

TEST(MarchingCubes, SphereIsWatertightAccurateAndOutwardFacing) {
  const double voxel_m = 0.008;
  const Eigen::Vector3d centre(0.0031, -0.0017, 0.0023);
  const double radius_m = 0.0987;  // ~12 voxels.
  const SdfGrid grid = SphereGrid(32, voxel_m, centre, radius_m);
  absl::StatusOr<TriangleMesh> mesh = MarchingCubes(grid);
  ASSERT_TRUE(mesh.ok()) << mesh.status();
  ASSERT_GT(mesh->num_triangles(), 1000);

  const EdgeCheck edges = CheckEdges(*mesh);
  EXPECT_EQ(edges.boundary_or_nonmanifold, 0) << "of " << edges.edges << " edges";
  EXPECT_EQ(edges.inconsistent, 0);

  double worst_m = 0.0;
  double worst_normal_deg = 0.0;
  for (size_t v = 0; v < mesh->positions_m.size(); ++v) {
    const Eigen::Vector3d p = mesh->positions_m[v].cast<double>();
    worst_m = std::max(worst_m, std::abs((p - centre).norm() - radius_m));
    const Eigen::Vector3d radial = (p - centre).normalized();
    const double cosine = std::clamp(radial.dot(mesh->normals[v].cast<double>()), -1.0, 1.0);
    worst_normal_deg = std::max(worst_normal_deg, std::acos(cosine) * 180.0 / kPi);
  }
  EXPECT_LT(worst_m, 0.5 * voxel_m) << "worst vertex distance to the sphere, m";
  EXPECT_LT(worst_normal_deg, 5.0);

  const double volume = EnclosedVolume(*mesh);
  const double true_volume = 4.0 / 3.0 * kPi * radius_m * radius_m * radius_m;
  EXPECT_NEAR(volume / true_volume, 1.0, 0.02) << "volume " << volume << " m^3";
}

// Each of the 256 sign patterns of one cell, inside a grid whose border is
// positive, gives a closed, consistently oriented surface of positive volume.
TEST(MarchingCubes, EveryCaseIsClosed) {
  for (int mask = 1; mask < 256; ++mask) {
    SdfGrid grid;
    grid.nx = grid.ny = grid.nz = 4;
    grid.voxel_m = 0.01;
    grid.sdf.assign(64, 1.0f);
    for (int c = 0; c < 8; ++c) {
      // Values differ per corner so that interpolated vertices do not coincide.
      if ((mask >> c) & 1)
        grid.sdf[grid.Index(1 + (c & 1), 1 + ((c >> 1) & 1), 1 + (c >> 2))] = -0.5f - 0.05f * c;
    }
    absl::StatusOr<TriangleMesh> mesh = MarchingCubes(grid);
    ASSERT_TRUE(mesh.ok()) << mesh.status();
    const EdgeCheck edges = CheckEdges(*mesh);
    EXPECT_EQ(edges.boundary_or_nonmanifold, 0) << "case " << mask;
    EXPECT_EQ(edges.inconsistent, 0) << "case " << mask;
    EXPECT_GT(EnclosedVolume(*mesh), 0.0) << "case " << mask;
  }
}

// A random field, positive on the grid's border so the level set is closed:
// exercises every corner case, ambiguous faces included.
TEST(MarchingCubes, RandomFieldIsWatertightAndOriented) {
  std::mt19937 random(7);
  std::uniform_real_distribution<float> value(-1.0f, 1.0f);
  SdfGrid grid;
  grid.nx = grid.ny = grid.nz = 14;
  grid.voxel_m = 0.01;
  grid.sdf.resize(14 * 14 * 14);
  std::set<int> cases;
  for (int z = 0; z < 14; ++z) {
    for (int y = 0; y < 14; ++y) {
      for (int x = 0; x < 14; ++x) {
        const bool border = x == 0 || y == 0 || z == 0 || x == 13 || y == 13 || z == 13;
        grid.sdf[grid.Index(x, y, z)] = border ? 1.0f : value(random);
      }
    }
  }
  for (int z = 0; z < 13; ++z) {
    for (int y = 0; y < 13; ++y) {
      for (int x = 0; x < 13; ++x) {
        int mask = 0;
        for (int c = 0; c < 8; ++c) {
          if (grid.sdf[grid.Index(x + (c & 1), y + ((c >> 1) & 1), z + ((c >> 2) & 1))] < 0) {
            mask |= 1 << c;
          }
        }
        cases.insert(mask);
      }
    }
  }
  EXPECT_GT(cases.size(), 200u) << "cases exercised";
  absl::StatusOr<TriangleMesh> mesh = MarchingCubes(grid);
  ASSERT_TRUE(mesh.ok()) << mesh.status();
  const EdgeCheck edges = CheckEdges(*mesh);
  EXPECT_GT(edges.edges, 1000);
  EXPECT_EQ(edges.boundary_or_nonmanifold, 0);
  EXPECT_EQ(edges.inconsistent, 0);
  // Outward orientation: the enclosed volume (negative region) is positive
  // and no larger than the interior.
  const double volume = EnclosedVolume(*mesh);
  EXPECT_GT(volume, 0.0);
  EXPECT_LT(volume, std::pow(12 * grid.voxel_m, 3));
}

// The thesis' truncation leaves the deep inside unobserved (N* = 0): cells
// touching it are skipped, yet the band around the zero level stays closed.
TEST(MarchingCubes, UnobservedInteriorStillGivesAClosedSurface) {
  const double voxel_m = 0.008;
  const Eigen::Vector3d centre(0.001, 0.002, -0.003);
  const double radius_m = 0.09;
  SdfGrid grid = SphereGrid(30, voxel_m, centre, radius_m);
  const float mu = 0.02f;
  grid.observed.assign(grid.sdf.size(), 1);
  for (size_t i = 0; i < grid.sdf.size(); ++i) {
    if (grid.sdf[i] < -mu) grid.observed[i] = 0;
    grid.sdf[i] = std::min(grid.sdf[i], mu);
  }
  absl::StatusOr<TriangleMesh> mesh = MarchingCubes(grid);
  ASSERT_TRUE(mesh.ok()) << mesh.status();
  const EdgeCheck edges = CheckEdges(*mesh);
  EXPECT_EQ(edges.boundary_or_nonmanifold, 0);
  EXPECT_EQ(edges.inconsistent, 0);
  const double true_volume = 4.0 / 3.0 * kPi * radius_m * radius_m * radius_m;
  EXPECT_NEAR(EnclosedVolume(*mesh) / true_volume, 1.0, 0.02);
}

TEST(MarchingCubes, CellsWithAnUnobservedCornerMakeNoTriangles) {
  SdfGrid grid = SphereGrid(24, 0.01, Eigen::Vector3d::Zero(), 0.07);
  grid.observed.assign(grid.sdf.size(), 1);
  // Hide the half x > 0 (samples x >= 12): the mesh is the half sphere x < 0.
  for (int z = 0; z < 24; ++z) {
    for (int y = 0; y < 24; ++y) {
      for (int x = 12; x < 24; ++x) grid.observed[grid.Index(x, y, z)] = 0;
    }
  }
  absl::StatusOr<TriangleMesh> mesh = MarchingCubes(grid);
  ASSERT_TRUE(mesh.ok()) << mesh.status();
  ASSERT_GT(mesh->num_triangles(), 100);
  const double last_x = grid.origin_m.x() + 11 * grid.voxel_m;
  for (const Eigen::Vector3f& p : mesh->positions_m) EXPECT_LE(p.x(), last_x + 1e-6);
  EXPECT_GT(CheckEdges(*mesh).boundary_or_nonmanifold, 0);  // Open where it was cut.
}

TEST(MarchingCubes, KeepLargeComponentsDropsFloaters) {
  SdfGrid grid = SphereGrid(40, 0.01, Eigen::Vector3d(-0.05, 0, 0), 0.1);
  // A small second sphere far from the first.
  for (int z = 0; z < 40; ++z) {
    for (int y = 0; y < 40; ++y) {
      for (int x = 0; x < 40; ++x) {
        const Eigen::Vector3d p = grid.origin_m + grid.voxel_m * Eigen::Vector3d(x, y, z);
        const float small = static_cast<float>((p - Eigen::Vector3d(0.15, 0.1, 0.1)).norm() - 0.03);
        float& value = grid.sdf[grid.Index(x, y, z)];
        value = std::min(value, small);
      }
    }
  }
  absl::StatusOr<TriangleMesh> mesh = MarchingCubes(grid);
  ASSERT_TRUE(mesh.ok()) << mesh.status();
  const TriangleMesh kept = KeepLargeComponents(*mesh, 0.5);
  EXPECT_LT(kept.num_triangles(), mesh->num_triangles());
  for (const Eigen::Vector3f& p : kept.positions_m) EXPECT_LT(p.x(), 0.08);
  EXPECT_EQ(CheckEdges(kept).boundary_or_nonmanifold, 0);
}

TEST(MarchingCubes, RejectsMalformedGrids) {
  SdfGrid grid;
  EXPECT_EQ(MarchingCubes(grid).status().code(), absl::StatusCode::kInvalidArgument);
  grid = SphereGrid(4, 0.01, Eigen::Vector3d::Zero(), 0.01);
  grid.sdf.pop_back();
  EXPECT_EQ(MarchingCubes(grid).status().code(), absl::StatusCode::kInvalidArgument);
  grid = SphereGrid(4, 0.01, Eigen::Vector3d::Zero(), 0.01);
  grid.observed.assign(3, 1);
  EXPECT_EQ(MarchingCubes(grid).status().code(), absl::StatusCode::kInvalidArgument);
  grid = SphereGrid(4, 0.01, Eigen::Vector3d::Zero(), 0.01);
  grid.voxel_m = -1.0;
  EXPECT_EQ(MarchingCubes(grid).status().code(), absl::StatusCode::kInvalidArgument);
}

}  // namespace
}  // namespace reenact::recon::carving
