#include <gtest/gtest.h>

#include <Eigen/Geometry>

#include "common/render/mesh_data.h"
#include "common/render/render_types.h"

namespace reenact::render {
namespace {

TEST(ClipFromCamera, PixelEdgesMapToNdcBoundsAndDepthRange) {
  RenderCamera camera;
  camera.width = 640;
  camera.height = 480;
  camera.fx = 500;
  camera.fy = 510;
  camera.cx = 321.7;
  camera.cy = 238.2;
  camera.near_m = 0.5;
  camera.far_m = 8.0;
  ASSERT_TRUE(camera.Validate().ok());
  const Eigen::Matrix4d clip_from_camera = ClipFromCamera(camera);
  // A point that projects to the continuous pixel position (u, v) at depth z.
  auto ndc = [&](double u, double v, double z) {
    const Eigen::Vector4d point((u - camera.cx) / camera.fx * z, (v - camera.cy) / camera.fy * z, z,
                                1.0);
    const Eigen::Vector4d clip = clip_from_camera * point;
    return Eigen::Vector3d(clip.head<3>() / clip.w());
  };
  // NDC -> window: x_window = (x_ndc + 1) / 2 * width; must equal u (pixels).
  const Eigen::Vector3d corner = ndc(0.0, 0.0, 0.5);
  const Eigen::Vector3d far_corner = ndc(640.0, 480.0, 8.0);
  const Eigen::Vector3d inner = ndc(123.25, 400.75, 3.0);
  EXPECT_NEAR(corner.x(), -1.0, 1e-12);
  EXPECT_NEAR(corner.y(), -1.0, 1e-12);
  EXPECT_NEAR(corner.z(), -1.0, 1e-12);
  EXPECT_NEAR(far_corner.x(), 1.0, 1e-12);
  EXPECT_NEAR(far_corner.y(), 1.0, 1e-12);
  EXPECT_NEAR(far_corner.z(), 1.0, 1e-12);
  EXPECT_NEAR((inner.x() + 1) / 2 * 640, 123.25, 1e-9);  // Pixels.
  EXPECT_NEAR((inner.y() + 1) / 2 * 480, 400.75, 1e-9);
}

TEST(RenderCameraValidate, RejectsBadIntrinsicsAndClipping) {
  RenderCamera camera;
  EXPECT_FALSE(camera.Validate().ok());  // Zero size.
  camera.width = 10;
  camera.height = 10;
  camera.fx = camera.fy = 10;
  EXPECT_TRUE(camera.Validate().ok());
  camera.near_m = 2.0;
  camera.far_m = 1.0;
  EXPECT_EQ(camera.Validate().code(), absl::StatusCode::kInvalidArgument);
}

TEST(MeshFromCornerUvs, SplitsSeamVerticesAndKeepsRemap) {
  // Two triangles sharing edge (1, 2); the second uses other uvs for it.
  Eigen::Matrix3Xf positions_m(3, 4);
  positions_m << 0, 1, 0, 1,  //
      0, 0, 1, 1,             //
      0, 0, 0, 0;
  const std::vector<Eigen::Vector3i> triangles = {{0, 1, 2}, {2, 1, 3}};
  const std::vector<Eigen::Vector2f> uvs = {{0, 0},     {1, 0},     {0, 1},
                                            {0.5, 0.5}, {0.6, 0.6}, {0.7, 0.7}};
  auto mesh = MeshFromCornerUvs(positions_m, triangles, uvs, {{0, 1, 2}, {3, 4, 5}});
  ASSERT_TRUE(mesh.ok()) << mesh.status();
  EXPECT_EQ(mesh->num_vertices(), 6);  // Vertices 1 and 2 are split.
  EXPECT_EQ(mesh->num_source_vertices, 4);
  ASSERT_TRUE(ValidateMeshData(*mesh).ok());
  for (int t = 0; t < 2; ++t) {
    for (int k = 0; k < 3; ++k) {
      const int vertex = mesh->triangles[t][k];
      EXPECT_EQ(mesh->source_vertex[vertex], triangles[t][k]);
      EXPECT_LT((mesh->positions_m.col(vertex) - positions_m.col(triangles[t][k])).norm(), 1e-7);
      // Normals are shared across the seam: the flat square's +z.
      EXPECT_NEAR(mesh->normals(2, vertex), 1.0f, 1e-6);
    }
  }
  EXPECT_FALSE(MeshFromCornerUvs(positions_m, triangles, uvs, {{0, 1, 2}}).ok());
  EXPECT_FALSE(MeshFromCornerUvs(positions_m, triangles, uvs, {{0, 1, 2}, {3, 4, 6}}).ok());
}

TEST(MakeUvSphere, VerticesOnSphereAndOutwardWinding) {
  const MeshData sphere = MakeUvSphere(0.25f, 16, 8);
  ASSERT_TRUE(ValidateMeshData(sphere).ok());
  EXPECT_EQ(sphere.triangles.size(), 2u * 16 * 7);
  for (int i = 0; i < sphere.num_vertices(); ++i) {
    EXPECT_NEAR(sphere.positions_m.col(i).norm(), 0.25f, 1e-6);  // Metres.
  }
  for (const Eigen::Vector3i& t : sphere.triangles) {
    const Eigen::Vector3f a = sphere.positions_m.col(t[0]), b = sphere.positions_m.col(t[1]),
                          c = sphere.positions_m.col(t[2]);
    EXPECT_GT((b - a).cross(c - a).dot(a + b + c), 0.0f);  // Counter-clockwise from outside.
  }
}

}  // namespace
}  // namespace reenact::render
