#include "common/geometry/surface_distance.h"

#include <cmath>
#include <limits>
#include <random>
#include <vector>

#include <gtest/gtest.h>

namespace reenact {
namespace {

constexpr double kNm = 1e-9;

// Distance to a triangle by dense sampling of its surface (for checking).
double SampledDistance(const Eigen::Vector3d& p, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                       const Eigen::Vector3d& c) {
  double best = std::numeric_limits<double>::infinity();
  constexpr int kSteps = 400;
  for (int i = 0; i <= kSteps; ++i) {
    for (int j = 0; i + j <= kSteps; ++j) {
      const double u = static_cast<double>(i) / kSteps, v = static_cast<double>(j) / kSteps;
      best = std::min(best, (p - (a + u * (b - a) + v * (c - a))).norm());
    }
  }
  return best;
}

TEST(PointTriangleDistance, MatchesDenseSamplingInEveryRegion) {
  const Eigen::Vector3d a(0, 0, 0), b(1, 0, 0), c(0.3, 0.8, 0.1);
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> coordinate(-1.0, 2.0);
  for (int n = 0; n < 60; ++n) {
    const Eigen::Vector3d p(coordinate(rng), coordinate(rng), coordinate(rng));
    // The samples are 1/400 of an edge apart: within 3 mm of a 1 m triangle.
    EXPECT_NEAR(PointTriangleDistance(p, a, b, c), SampledDistance(p, a, b, c), 3e-3)
        << p.transpose();
    EXPECT_LE(PointTriangleDistance(p, a, b, c), SampledDistance(p, a, b, c) + kNm);
  }
  // Inside the face: the height over the plane.
  EXPECT_NEAR(PointTriangleDistance({0.3, 0.2, 0.5}, {0, 0, 0}, {1, 0, 0}, {0, 1, 0}), 0.5, kNm);
  // Degenerate triangle: nearest corner.
  EXPECT_NEAR(PointTriangleDistance({2, 0, 0}, {0, 0, 0}, {1, 0, 0}, {1, 0, 0}), 1.0, kNm);
}

// A latitude-longitude sphere of `radius` about the origin: its vertices
// (3 x N) and triangles.
struct Sphere {
  Eigen::Matrix3Xd vertices;
  std::vector<Eigen::Vector3i> triangles;
};
Sphere UvSphere(double radius, int segments, int rings) {
  Sphere s;
  s.vertices.resize(3, (rings + 1) * (segments + 1));
  for (int r = 0; r <= rings; ++r) {
    const double theta = M_PI * r / rings;
    for (int g = 0; g <= segments; ++g) {
      const double phi = 2 * M_PI * g / segments;
      s.vertices.col(r * (segments + 1) + g) =
          radius * Eigen::Vector3d(std::sin(theta) * std::cos(phi), std::cos(theta),
                                   std::sin(theta) * std::sin(phi));
    }
  }
  for (int r = 0; r < rings; ++r) {
    for (int g = 0; g < segments; ++g) {
      const int a = r * (segments + 1) + g, b = a + segments + 1;
      s.triangles.emplace_back(a, b, a + 1);
      s.triangles.emplace_back(a + 1, b, b + 1);
    }
  }
  return s;
}

TEST(TriangleSurfaceIndex, AgreesWithBruteForceNearAndFar) {
  const Sphere sphere = UvSphere(0.3, 24, 12);
  const Eigen::Matrix3Xd& vertices = sphere.vertices;
  auto index = TriangleSurfaceIndex::Build(vertices, sphere.triangles, 0.05);
  ASSERT_TRUE(index.ok()) << index.status();
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> coordinate(-0.5, 0.5);
  for (int n = 0; n < 300; ++n) {
    Eigen::Vector3d p(coordinate(rng), coordinate(rng), coordinate(rng));
    if (n % 10 == 0) p *= 20.0;  // Far outside the grid.
    double brute = std::numeric_limits<double>::infinity();
    for (const Eigen::Vector3i& t : sphere.triangles) {
      brute = std::min(brute, PointTriangleDistance(p, vertices.col(t[0]), vertices.col(t[1]),
                                                    vertices.col(t[2])));
    }
    EXPECT_NEAR(index->Distance(p), brute, kNm) << p.transpose();
  }
}

TEST(TriangleSurfaceIndex, BadInputIsInvalidArgument) {
  const Sphere sphere = UvSphere(0.3, 8, 4);
  const Eigen::Matrix3Xd& vertices = sphere.vertices;
  EXPECT_EQ(TriangleSurfaceIndex::Build(vertices, {}, 0.05).status().code(),
            absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(TriangleSurfaceIndex::Build(vertices, {{0, 1, 100000}}, 0.05).status().code(),
            absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(TriangleSurfaceIndex::Build(vertices, sphere.triangles, 0.0).status().code(),
            absl::StatusCode::kInvalidArgument);
  Eigen::Matrix3Xd bad = vertices;
  bad(0, 0) = std::numeric_limits<double>::quiet_NaN();
  EXPECT_EQ(TriangleSurfaceIndex::Build(bad, sphere.triangles, 0.05).status().code(),
            absl::StatusCode::kInvalidArgument);
}

}  // namespace
}  // namespace reenact
