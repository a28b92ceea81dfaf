#include "common/render/offscreen_renderer.h"

#include <cmath>
#include <cstdlib>
#include <numbers>

#include <gtest/gtest.h>

namespace reenact::render {
namespace {

constexpr double kMm = 1e-3;

RenderCamera TestCamera() {
  RenderCamera camera;
  camera.width = 640;
  camera.height = 480;
  camera.fx = 500.0;
  camera.fy = 520.0;
  camera.cx = 317.3;
  camera.cy = 243.6;
  return camera;
}

std::unique_ptr<OffscreenRenderer> MakeRenderer(int msaa_samples = 0) {
  RendererOptions options;
  options.max_width = 640;
  options.max_height = 480;
  options.msaa_samples = msaa_samples;
  auto renderer = OffscreenRenderer::Create(options);
  EXPECT_TRUE(renderer.ok()) << renderer.status();
  return renderer.ok() ? std::move(renderer).value() : nullptr;
}

// A rectangle in the plane z = z_m of its model frame spanning [x0, x1] x
// [y0, y1], facing -z (toward a camera at the origin), with uvs (0,0) at
// (x0, y1), the bottom left as the camera sees it.
MeshData MakeRectangle(double x0, double y0, double x1, double y1, double z_m) {
  MeshData mesh;
  mesh.positions_m.resize(3, 4);
  mesh.positions_m << x0, x0, x1, x1,  // Top left, bottom left, bottom right, top right.
      y0, y1, y1, y0,                  //
      z_m, z_m, z_m, z_m;
  mesh.uvs.resize(2, 4);
  mesh.uvs << 0, 0, 1, 1,  //
      1, 0, 0, 1;
  mesh.triangles = {{0, 1, 2}, {0, 2, 3}};
  return mesh;
}

// Continuous image position of a camera-frame point.
Eigen::Vector2d Project(const RenderCamera& camera, const Eigen::Vector3d& point_in_camera) {
  return {camera.fx * point_in_camera.x() / point_in_camera.z() + camera.cx,
          camera.fy * point_in_camera.y() / point_in_camera.z() + camera.cy};
}

// Unit ray through the centre of pixel (u, v), camera frame, scaled to z = 1.
Eigen::Vector3d PixelRay(const RenderCamera& camera, int u, int v) {
  return {(u + 0.5 - camera.cx) / camera.fx, (v + 0.5 - camera.cy) / camera.fy, 1.0};
}

TEST(OffscreenRendererDepth, TiltedPlaneMatchesAnalyticDepth) {
  auto renderer = MakeRenderer();
  ASSERT_NE(renderer, nullptr);
  // A plane through (0, 0, 2.5) with normal n: points X with n.X = n.(0,0,2.5).
  const Eigen::Vector3d normal = Eigen::Vector3d(0.4, -0.3, -1.0).normalized();
  Eigen::Isometry3d world_from_model = Eigen::Isometry3d::Identity();
  world_from_model.linear() =
      Eigen::Quaterniond::FromTwoVectors(Eigen::Vector3d(0, 0, -1), normal).toRotationMatrix();
  world_from_model.translation() = Eigen::Vector3d(0, 0, 2.5);
  auto mesh = renderer->UploadMesh(MakeRectangle(-3, -3, 3, 3, 0));
  ASSERT_TRUE(mesh.ok()) << mesh.status();
  DrawItem item;
  item.mesh = *mesh;
  item.world_from_model = world_from_model;
  const RenderCamera camera = TestCamera();
  RenderOutputs out;
  ASSERT_TRUE(renderer->Render(camera, {item}, &out).ok());
  ASSERT_EQ(out.depth_m.width, 640);
  ASSERT_EQ(out.depth_m.height, 480);
  const double plane_offset = normal.dot(Eigen::Vector3d(0, 0, 2.5));
  double max_error_m = 0.0;
  for (int v = 0; v < camera.height; ++v) {
    for (int u = 0; u < camera.width; ++u) {
      const double expected_m = plane_offset / normal.dot(PixelRay(camera, u, v));
      max_error_m = std::max(max_error_m, std::abs(out.depth_m.at(u, v) - expected_m));
    }
  }
  EXPECT_LT(max_error_m, 1 * kMm);
}

TEST(OffscreenRendererDepth, EmptyPixelsAreZeroAndBehindFarAreClipped) {
  auto renderer = MakeRenderer();
  ASSERT_NE(renderer, nullptr);
  auto near_mesh = renderer->UploadMesh(MakeRectangle(-0.2, -0.2, 0.2, 0.2, 2.0));
  auto far_mesh = renderer->UploadMesh(MakeRectangle(-9, -9, 9, 9, 30.0));
  ASSERT_TRUE(near_mesh.ok() && far_mesh.ok());
  DrawItem near_item, far_item;
  near_item.mesh = *near_mesh;
  far_item.mesh = *far_mesh;
  RenderOutputs out;
  ASSERT_TRUE(renderer->Render(TestCamera(), {near_item, far_item}, &out).ok());
  EXPECT_NEAR(out.depth_m.at(317, 243), 2.0, 1 * kMm);
  EXPECT_EQ(out.depth_m.at(5, 5), 0.0f);  // Only the plane at 30 m (beyond far_m) is there.
  EXPECT_EQ(out.label.at(5, 5), 0);
}

TEST(OffscreenRendererSilhouette, SphereAreaMatchesProjectedCone) {
  auto renderer = MakeRenderer();
  ASSERT_NE(renderer, nullptr);
  auto sphere = renderer->UploadMesh(MakeUvSphere(0.3f, 128, 64));
  ASSERT_TRUE(sphere.ok());
  RenderCamera camera = TestCamera();
  camera.fy = camera.fx;  // Circular silhouette.
  DrawItem item;
  item.mesh = *sphere;
  const double distance_m = 2.0, radius_m = 0.3;
  item.world_from_model.translation() = Eigen::Vector3d(0, 0, distance_m);
  RenderOutputs out;
  out.requested = kRenderLabel;
  ASSERT_TRUE(renderer->Render(camera, {item}, &out).ok());
  EXPECT_TRUE(out.colour.empty());
  int area_px = 0;
  for (uint8_t label : out.label.data) area_px += label == 1;
  // The silhouette is the cone of half-angle asin(r / d) about the axis.
  const double tan_half_angle = radius_m / std::sqrt(distance_m * distance_m - radius_m * radius_m);
  const double expected_px = std::numbers::pi * std::pow(camera.fx * tan_half_angle, 2);
  EXPECT_NEAR(area_px, expected_px, 0.02 * expected_px);
}

TEST(OffscreenRendererCulling, BackFacesOfAClosedMeshAreSkippedWhenAsked) {
  auto renderer = MakeRenderer();
  ASSERT_NE(renderer, nullptr);
  auto sphere = renderer->UploadMesh(MakeUvSphere(0.3f, 64, 32));
  ASSERT_TRUE(sphere.ok());
  const RenderCamera camera = TestCamera();
  // Pixels drawn with the sphere `distance_m` ahead (0: the camera inside it).
  auto area_px = [&](double distance_m, bool cull) {
    DrawItem item;
    item.mesh = *sphere;
    item.cull_back_faces = cull;
    item.world_from_model.translation() = Eigen::Vector3d(0, 0, distance_m);
    RenderOutputs out;
    out.requested = kRenderLabel;
    EXPECT_TRUE(renderer->Render(camera, {item}, &out).ok());
    int area = 0;
    for (uint8_t label : out.label.data) area += label == 1;
    return area;
  };
  // Seen from outside, only hidden faces go: the same silhouette.
  const int outside = area_px(2.0, false);
  EXPECT_GT(outside, 1000);
  EXPECT_EQ(area_px(2.0, true), outside);
  // From inside every face points away: all of them are culled.
  EXPECT_EQ(area_px(0.0, false), camera.width * camera.height);
  EXPECT_EQ(area_px(0.0, true), 0);
}

// The rendered left/top edges of a rectangle whose corner projects to several
// sub-pixel positions: pixel (u, v) is drawn iff its centre (u + 0.5, v + 0.5)
// is inside, so the first drawn column c satisfies |u_corner - c| <= 0.5.
TEST(OffscreenRendererProjection, CornerLandsWithinHalfPixelOfAnalyticProjection) {
  auto renderer = MakeRenderer();
  ASSERT_NE(renderer, nullptr);
  const RenderCamera camera = TestCamera();
  for (int k = 0; k < 9; ++k) {
    const double z_m = 2.0;
    // Corner positions whose projections have fractions 0.05 .. 0.85.
    const double u_corner = 250.0 + 0.1 * k + 0.05 + 7 * k;
    const double v_corner = 200.0 + 0.1 * (8 - k) + 0.05 + 3 * k;
    const double x0 = (u_corner - camera.cx) / camera.fx * z_m;
    const double y0 = (v_corner - camera.cy) / camera.fy * z_m;
    const Eigen::Vector2d projected = Project(camera, {x0, y0, z_m});
    auto mesh = renderer->UploadMesh(MakeRectangle(x0, y0, x0 + 0.3, y0 + 0.3, z_m));
    ASSERT_TRUE(mesh.ok());
    DrawItem item;
    item.mesh = *mesh;
    RenderOutputs out;
    out.requested = kRenderLabel;
    ASSERT_TRUE(renderer->Render(camera, {item}, &out).ok());
    const int row = static_cast<int>(projected.y()) + 10,
              column = static_cast<int>(projected.x()) + 10;
    int first_column = -1, first_row = -1;
    for (int u = 0; u < camera.width && first_column < 0; ++u) {
      if (out.label.at(u, row) != 0) first_column = u;
    }
    for (int v = 0; v < camera.height && first_row < 0; ++v) {
      if (out.label.at(column, v) != 0) first_row = v;
    }
    EXPECT_LE(std::abs(projected.x() - first_column), 0.5) << "corner " << k;
    EXPECT_LE(std::abs(projected.y() - first_row), 0.5) << "corner " << k;
    ASSERT_TRUE(renderer->ReleaseMesh(*mesh).ok());
  }
}

TEST(OffscreenRendererTexture, CheckerboardShowsExpectedColours) {
  auto renderer = MakeRenderer();
  ASSERT_NE(renderer, nullptr);
  // 4 x 4 cells of 16 texels: red/blue checker, top-left cell green, so any
  // flip or rotation changes some cell.
  const Eigen::Vector3i red(200, 30, 30), blue(20, 40, 220), green(30, 210, 60);
  RgbImage texture(64, 64);
  auto cell_colour = [&](int i, int j) {
    if (i == 0 && j == 0) return green;
    return (i + j) % 2 == 0 ? red : blue;
  };
  for (int y = 0; y < 64; ++y) {
    for (int x = 0; x < 64; ++x) {
      for (int c = 0; c < 3; ++c) texture.at(x, y, c) = cell_colour(x / 16, y / 16)[c];
    }
  }
  auto texture_id = renderer->UploadTexture(texture);
  ASSERT_TRUE(texture_id.ok()) << texture_id.status();
  auto mesh = renderer->UploadMesh(MakeRectangle(-0.5, -0.5, 0.5, 0.5, 2.0));
  ASSERT_TRUE(mesh.ok());
  DrawItem item;
  item.mesh = *mesh;
  item.texture = *texture_id;
  item.lit = false;
  const RenderCamera camera = TestCamera();
  RenderOutputs out;
  ASSERT_TRUE(renderer->Render(camera, {item}, &out).ok());
  const Eigen::Vector2d top_left = Project(camera, {-0.5, -0.5, 2.0});
  const Eigen::Vector2d bottom_right = Project(camera, {0.5, 0.5, 2.0});
  for (int j = 0; j < 4; ++j) {
    for (int i = 0; i < 4; ++i) {
      const Eigen::Vector2d centre =
          top_left + (bottom_right - top_left).cwiseProduct(Eigen::Vector2d(i + 0.5, j + 0.5) / 4);
      const int u = static_cast<int>(centre.x()), v = static_cast<int>(centre.y());
      for (int c = 0; c < 3; ++c) {
        EXPECT_NEAR(out.colour.at(u, v, c), cell_colour(i, j)[c], 2)
            << "cell " << i << "," << j << " channel " << c;
      }
    }
  }
}

TEST(OffscreenRendererTexture, UpdateReplacesTexelsInPlaceAndRejectsAnotherSize) {
  auto renderer = MakeRenderer();
  ASSERT_NE(renderer, nullptr);
  RgbImage red(32, 32);
  RgbImage green(32, 32);
  for (int y = 0; y < 32; ++y) {
    for (int x = 0; x < 32; ++x) {
      red.at(x, y, 0) = 210;
      green.at(x, y, 1) = 190;
    }
  }
  auto texture = renderer->UploadTexture(red);
  auto mesh = renderer->UploadMesh(MakeRectangle(-0.5, -0.5, 0.5, 0.5, 2.0));
  ASSERT_TRUE(texture.ok() && mesh.ok());
  DrawItem item;
  item.mesh = *mesh;
  item.texture = *texture;
  item.lit = false;
  const RenderCamera camera = TestCamera();
  const int u = camera.width / 2, v = camera.height / 2;
  RenderOutputs out;
  ASSERT_TRUE(renderer->Render(camera, {item}, &out).ok());
  EXPECT_NEAR(out.colour.at(u, v, 0), 210, 2);
  ASSERT_TRUE(renderer->UpdateTexture(*texture, green).ok());
  ASSERT_TRUE(renderer->Render(camera, {item}, &out).ok());
  EXPECT_NEAR(out.colour.at(u, v, 0), 0, 2);
  EXPECT_NEAR(out.colour.at(u, v, 1), 190, 2);
  EXPECT_EQ(renderer->UpdateTexture(*texture, RgbImage(16, 32)).code(),
            absl::StatusCode::kInvalidArgument);
  auto with_alpha = renderer->UploadTexture(RgbaImage(32, 32, 100));
  ASSERT_TRUE(with_alpha.ok());
  EXPECT_EQ(renderer->UpdateTexture(*with_alpha, green).code(), absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(renderer->UpdateTexture(TextureId{99}, green).code(), absl::StatusCode::kNotFound);
}

TEST(OffscreenRendererBlend, BlendedItemMixesItsColourOverTheOpaqueOneAtTheSameDepth) {
  auto renderer = MakeRenderer();
  ASSERT_NE(renderer, nullptr);
  auto mesh = renderer->UploadMesh(MakeRectangle(-0.5, -0.5, 0.5, 0.5, 2.0));
  auto behind = renderer->UploadMesh(MakeRectangle(-0.5, -0.5, 0.5, 0.5, 2.5));
  ASSERT_TRUE(mesh.ok() && behind.ok());
  DrawItem red;
  red.mesh = *mesh;
  red.lit = false;
  red.label = 7;
  red.colour_srgb = Eigen::Vector3f(0.8f, 0.0f, 0.0f);
  DrawItem green = red;
  green.colour_srgb = Eigen::Vector3f(0.0f, 0.8f, 0.0f);
  green.label = 9;
  green.blend_weight = 0.25f;
  const RenderCamera camera = TestCamera();
  const int u = camera.width / 2, v = camera.height / 2;
  RenderOutputs out;
  out.requested = kRenderColour | kRenderLabel | kRenderDepth;
  // Listed first, drawn after the opaque one.
  ASSERT_TRUE(renderer->Render(camera, {green, red}, &out).ok());
  // Blended in linear light: 0.75 x 0.8 and 0.25 x 0.8 (sRGB) per channel.
  const auto srgb = [](double linear) {
    return 255.0 *
           (linear <= 0.0031308 ? 12.92 * linear : 1.055 * std::pow(linear, 1 / 2.4) - 0.055);
  };
  const double red_linear = std::pow((0.8 + 0.055) / 1.055, 2.4);
  EXPECT_NEAR(out.colour.at(u, v, 0), srgb(0.75 * red_linear), 3);
  EXPECT_NEAR(out.colour.at(u, v, 1), srgb(0.25 * red_linear), 3);
  EXPECT_EQ(out.label.at(u, v), 7) << "a blended item writes colour only";
  EXPECT_NEAR(out.depth_m.at(u, v), 2.0, 1e-3);
  // Behind the opaque surface, or over the background, it does not show.
  green.mesh = *behind;
  ASSERT_TRUE(renderer->Render(camera, {red, green}, &out).ok());
  EXPECT_NEAR(out.colour.at(u, v, 0), 204, 2);
  EXPECT_NEAR(out.colour.at(u, v, 1), 0, 2);
  green.mesh = *mesh;
  ASSERT_TRUE(renderer->Render(camera, {green}, &out).ok());
  EXPECT_NEAR(out.colour.at(u, v, 1), 0, 2);
  EXPECT_EQ(out.label.at(u, v), 0);
  // A weight outside (0, 1] is refused.
  green.blend_weight = 0.0f;
  EXPECT_EQ(renderer->Render(camera, {red, green}, &out).code(),
            absl::StatusCode::kInvalidArgument);
}

// Left half transparent (alpha 0), right half opaque red (220, 0, 0).
RgbaImage HalfTransparentRed() {
  RgbaImage texture(64, 64);
  for (int y = 0; y < 64; ++y) {
    for (int x = 0; x < 64; ++x) {
      texture.at(x, y, 0) = 220;
      texture.at(x, y, 3) = x < 32 ? 0 : 255;
    }
  }
  return texture;
}

TEST(OffscreenRendererTexture, AlphaBelowHalfIsDiscardedAndShowsWhatIsBehind) {
  auto renderer = MakeRenderer();
  ASSERT_NE(renderer, nullptr);
  auto texture_id = renderer->UploadTexture(HalfTransparentRed());
  ASSERT_TRUE(texture_id.ok()) << texture_id.status();
  auto front = renderer->UploadMesh(MakeRectangle(-0.5, -0.5, 0.5, 0.5, 2.0));
  auto back = renderer->UploadMesh(MakeRectangle(-1.0, -1.0, 1.0, 1.0, 3.0));
  ASSERT_TRUE(front.ok() && back.ok());
  DrawItem front_item;
  front_item.mesh = *front;
  front_item.texture = *texture_id;
  front_item.lit = false;
  front_item.label = 1;
  DrawItem back_item;
  back_item.mesh = *back;
  back_item.colour_srgb = Eigen::Vector3f(0.0f, 0.0f, 1.0f);
  back_item.lit = false;
  back_item.label = 2;
  const RenderCamera camera = TestCamera();
  RenderOutputs out;
  ASSERT_TRUE(renderer->Render(camera, {front_item, back_item}, &out).ok());
  const Eigen::Vector2d left = Project(camera, {-0.25, 0.0, 2.0});
  const Eigen::Vector2d right = Project(camera, {0.25, 0.0, 2.0});
  const int v = static_cast<int>(left.y());
  // Discarded: the back rectangle shows through, with its label and depth.
  EXPECT_EQ(out.label.at(static_cast<int>(left.x()), v), 2);
  EXPECT_NEAR(out.depth_m.at(static_cast<int>(left.x()), v), 3.0, 1e-3);
  EXPECT_NEAR(out.colour.at(static_cast<int>(left.x()), v, 2), 255, 1);
  EXPECT_EQ(out.label.at(static_cast<int>(right.x()), v), 1);
  EXPECT_NEAR(out.colour.at(static_cast<int>(right.x()), v, 0), 220, 2);
  EXPECT_NEAR(out.depth_m.at(static_cast<int>(right.x()), v), 2.0, 1e-3);
}

TEST(OffscreenRendererTexture, UnderlayShowsOnlyWhereACoincidentItemDiscards) {
  auto renderer = MakeRenderer();
  ASSERT_NE(renderer, nullptr);
  // The half-transparent texture on the same rectangle as a blue underlay,
  // drawn first and last: the order must not matter.
  auto texture_id = renderer->UploadTexture(HalfTransparentRed());
  ASSERT_TRUE(texture_id.ok()) << texture_id.status();
  auto mesh = renderer->UploadMesh(MakeRectangle(-0.5, -0.5, 0.5, 0.5, 2.0));
  ASSERT_TRUE(mesh.ok());
  DrawItem top;
  top.mesh = *mesh;
  top.texture = *texture_id;
  top.lit = false;
  top.label = 1;
  DrawItem under = top;
  under.texture = TextureId();
  under.colour_srgb = Eigen::Vector3f(0.0f, 0.0f, 1.0f);
  under.label = 2;
  under.underlay = true;
  const RenderCamera camera = TestCamera();
  const Eigen::Vector2d left = Project(camera, {-0.25, 0.0, 2.0});
  const Eigen::Vector2d right = Project(camera, {0.25, 0.0, 2.0});
  const int v = static_cast<int>(left.y());
  for (const std::vector<DrawItem>& items :
       {std::vector<DrawItem>{under, top}, std::vector<DrawItem>{top, under}}) {
    RenderOutputs out;
    ASSERT_TRUE(renderer->Render(camera, items, &out).ok());
    // Discarded texels: the underlay (blue, label 2) at the same depth.
    EXPECT_EQ(out.label.at(static_cast<int>(left.x()), v), 2);
    EXPECT_NEAR(out.colour.at(static_cast<int>(left.x()), v, 2), 255, 1);
    EXPECT_NEAR(out.depth_m.at(static_cast<int>(left.x()), v), 2.0, 2e-3);
    // Elsewhere the coincident item wins although both lie at 2 m.
    EXPECT_EQ(out.label.at(static_cast<int>(right.x()), v), 1);
    EXPECT_NEAR(out.colour.at(static_cast<int>(right.x()), v, 0), 220, 2);
  }
}

TEST(OffscreenRendererIds, ReleasedSlotsAreReused) {
  auto renderer = MakeRenderer();
  ASSERT_NE(renderer, nullptr);
  auto first = renderer->UploadMesh(MakeRectangle(-0.1, -0.1, 0.1, 0.1, 2.0));
  auto second = renderer->UploadMesh(MakeRectangle(-0.1, -0.1, 0.1, 0.1, 2.0));
  ASSERT_TRUE(first.ok() && second.ok());
  ASSERT_TRUE(renderer->ReleaseMesh(*first).ok());
  EXPECT_EQ(renderer->ReleaseMesh(*first).code(), absl::StatusCode::kNotFound);
  auto third = renderer->UploadMesh(MakeRectangle(-0.1, -0.1, 0.1, 0.1, 2.0));
  ASSERT_TRUE(third.ok());
  EXPECT_EQ(third->value, first->value);
  auto texture = renderer->UploadTexture(RgbImage(4, 4, 100));
  ASSERT_TRUE(texture.ok());
  ASSERT_TRUE(renderer->ReleaseTexture(*texture).ok());
  auto again = renderer->UploadTexture(RgbaImage(4, 4, 100));
  ASSERT_TRUE(again.ok());
  EXPECT_EQ(again->value, texture->value);
}

TEST(OffscreenRendererColour, FlatAndHeadlitColoursAndBackground) {
  auto renderer = MakeRenderer();
  ASSERT_NE(renderer, nullptr);
  ShadingOptions shading;
  shading.background_srgb = Eigen::Vector3f(0.2f, 0.4f, 0.6f);
  ASSERT_TRUE(renderer->SetShading(shading).ok());
  auto mesh = renderer->UploadMesh(MakeRectangle(-0.1, -0.1, 0.1, 0.1, 2.0));
  ASSERT_TRUE(mesh.ok());
  DrawItem item;
  item.mesh = *mesh;
  item.colour_srgb = Eigen::Vector3f(0.9f, 0.5f, 0.1f);
  item.lit = true;  // Head-on headlight: ambient + diffuse = 1, the albedo.
  RenderOutputs out;
  ASSERT_TRUE(renderer->Render(TestCamera(), {item}, &out).ok());
  EXPECT_NEAR(out.colour.at(317, 243, 0), 0.9 * 255, 1.5);
  EXPECT_NEAR(out.colour.at(317, 243, 1), 0.5 * 255, 1.5);
  EXPECT_NEAR(out.colour.at(317, 243, 2), 0.1 * 255, 1.5);
  EXPECT_NEAR(out.colour.at(3, 3, 0), 0.2 * 255, 1.5);
  EXPECT_NEAR(out.colour.at(3, 3, 1), 0.4 * 255, 1.5);
  EXPECT_NEAR(out.colour.at(3, 3, 2), 0.6 * 255, 1.5);
}

TEST(OffscreenRendererLabel, LabelInsideProjectedRectangleAndZeroOutside) {
  auto renderer = MakeRenderer();
  ASSERT_NE(renderer, nullptr);
  auto mesh = renderer->UploadMesh(MakeRectangle(-0.31, -0.22, 0.27, 0.18, 1.7));
  ASSERT_TRUE(mesh.ok());
  DrawItem item;
  item.mesh = *mesh;
  item.label = 7;
  const RenderCamera camera = TestCamera();
  RenderOutputs out;
  out.requested = kRenderLabel;
  ASSERT_TRUE(renderer->Render(camera, {item}, &out).ok());
  const Eigen::Vector2d top_left = Project(camera, {-0.31, -0.22, 1.7});
  const Eigen::Vector2d bottom_right = Project(camera, {0.27, 0.18, 1.7});
  int mismatches = 0, inside = 0;
  for (int v = 0; v < camera.height; ++v) {
    for (int u = 0; u < camera.width; ++u) {
      const Eigen::Vector2d centre(u + 0.5, v + 0.5);
      const bool in = (centre.array() > top_left.array()).all() &&
                      (centre.array() < bottom_right.array()).all();
      inside += in;
      mismatches += out.label.at(u, v) != (in ? 7 : 0);
    }
  }
  EXPECT_GT(inside, 10000);
  EXPECT_EQ(mismatches, 0);
}

TEST(OffscreenRendererOcclusion, NearerItemWinsWhateverTheDrawOrder) {
  auto renderer = MakeRenderer();
  ASSERT_NE(renderer, nullptr);
  auto near_mesh = renderer->UploadMesh(MakeRectangle(-0.1, -0.1, 0.1, 0.1, 1.5));
  auto far_mesh = renderer->UploadMesh(MakeRectangle(-1, -1, 1, 1, 3.0));
  ASSERT_TRUE(near_mesh.ok() && far_mesh.ok());
  DrawItem near_item, far_item;
  near_item.mesh = *near_mesh;
  near_item.label = 2;
  far_item.mesh = *far_mesh;
  far_item.label = 1;
  for (const auto& items :
       {std::vector<DrawItem>{near_item, far_item}, std::vector<DrawItem>{far_item, near_item}}) {
    RenderOutputs out;
    ASSERT_TRUE(renderer->Render(TestCamera(), items, &out).ok());
    EXPECT_EQ(out.label.at(317, 243), 2);
    EXPECT_NEAR(out.depth_m.at(317, 243), 1.5, 1 * kMm);
    EXPECT_EQ(out.label.at(200, 200), 1);
    EXPECT_NEAR(out.depth_m.at(200, 200), 3.0, 1 * kMm);
  }
}

TEST(OffscreenRendererNormals, PlaneNormalsPointTowardCamera) {
  auto renderer = MakeRenderer();
  ASSERT_NE(renderer, nullptr);
  MeshData with_normals = MakeRectangle(-0.1, -0.1, 0.1, 0.1, 2.0);
  with_normals.normals = ComputeVertexNormals(with_normals.positions_m, with_normals.triangles);
  auto smooth = renderer->UploadMesh(with_normals);
  auto faceted = renderer->UploadMesh(MakeRectangle(-0.1, -0.1, 0.1, 0.1, 2.0));
  ASSERT_TRUE(smooth.ok() && faceted.ok());
  Eigen::Isometry3d world_from_camera = Eigen::Isometry3d::Identity();
  world_from_camera.linear() =
      Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitY()).toRotationMatrix();  // Any pose.
  for (MeshId id : {*smooth, *faceted}) {
    DrawItem item;
    item.mesh = id;
    item.world_from_model = world_from_camera;  // Rectangle fixed in the camera.
    RenderCamera camera = TestCamera();
    camera.world_from_camera = world_from_camera;
    RenderOutputs out;
    out.requested = kRenderNormals | kRenderDepth;
    ASSERT_TRUE(renderer->Render(camera, {item}, &out).ok());
    const Eigen::Vector3d expected = world_from_camera.linear() * Eigen::Vector3d(0, 0, -1);
    for (int c = 0; c < 3; ++c) {
      EXPECT_NEAR(out.normals_in_world.at(317, 243, c), expected[c], 1e-4) << id.value;
      EXPECT_EQ(out.normals_in_world.at(3, 3, c), 0.0f);
    }
    EXPECT_NEAR(out.depth_m.at(317, 243), 2.0, 1 * kMm);
  }
}

TEST(UpdateMeshPositions, MovesPlainAndSeamSplitMeshes) {
  auto renderer = MakeRenderer();
  ASSERT_NE(renderer, nullptr);
  const MeshData rectangle = MakeRectangle(-0.2, -0.2, 0.2, 0.2, 2.0);
  // The same rectangle with a uv seam along its diagonal: 4 positions, 6 uvs.
  const std::vector<Eigen::Vector2f> uvs = {{0, 1}, {0, 0}, {1, 0}, {0.5, 1}, {0.5, 0}, {1, 1}};
  auto split =
      MeshFromCornerUvs(rectangle.positions_m, rectangle.triangles, uvs, {{0, 1, 2}, {3, 4, 5}});
  ASSERT_TRUE(split.ok()) << split.status();
  ASSERT_EQ(split->num_vertices(), 6);
  for (const MeshData& mesh : {rectangle, *split}) {
    auto id = renderer->UploadMesh(mesh);
    ASSERT_TRUE(id.ok());
    DrawItem item;
    item.mesh = *id;
    RenderOutputs before, after;
    ASSERT_TRUE(renderer->Render(TestCamera(), {item}, &before).ok());
    Eigen::Matrix3Xf moved = rectangle.positions_m;  // Original (4-vertex) indexing.
    moved.row(2).setConstant(2.6f);
    moved.row(0).array() += 0.1f;
    ASSERT_TRUE(renderer->UpdateMeshPositions(*id, moved).ok());
    ASSERT_TRUE(renderer->Render(TestCamera(), {item}, &after).ok());
    EXPECT_NEAR(before.depth_m.at(317, 243), 2.0, 1 * kMm);
    EXPECT_NEAR(after.depth_m.at(317, 243), 2.6, 1 * kMm);
    // Left edge: x = -0.1 m at 2.6 m projects to u = 317.3 - 500 * 0.1 / 2.6.
    EXPECT_EQ(after.label.at(297, 243), 0);
    EXPECT_EQ(after.label.at(299, 243), 1);
    EXPECT_FALSE(renderer->UpdateMeshPositions(*id, Eigen::Matrix3Xf(3, 5)).ok());
  }
}

TEST(OffscreenRendererMsaa, InteriorMatchesAndEdgesBlend) {
  auto renderer = MakeRenderer(4);
  ASSERT_NE(renderer, nullptr);
  auto mesh = renderer->UploadMesh(MakeRectangle(-0.3, -0.2, 0.25, 0.2, 2.0));
  ASSERT_TRUE(mesh.ok());
  Eigen::Isometry3d world_from_model = Eigen::Isometry3d::Identity();
  world_from_model.linear() = Eigen::AngleAxisd(0.2, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  DrawItem item;
  item.mesh = *mesh;
  item.world_from_model = world_from_model;
  item.colour_srgb = Eigen::Vector3f(1, 1, 1);
  item.lit = false;
  RenderOutputs out;
  ASSERT_TRUE(renderer->Render(TestCamera(), {item}, &out).ok());
  EXPECT_EQ(out.colour.at(317, 243, 0), 255);
  EXPECT_EQ(out.label.at(317, 243), 1);
  EXPECT_NEAR(out.depth_m.at(317, 243), 2.0, 1 * kMm);
  int partial = 0;
  for (size_t i = 0; i < out.colour.data.size(); i += 3) {
    partial += out.colour.data[i] > 0 && out.colour.data[i] < 255;
  }
  EXPECT_GT(partial, 100);  // Antialiased slanted edges.
}

TEST(OffscreenRendererErrors, BadInputsAreInvalidArgument) {
  RendererOptions options;
  options.msaa_samples = 3;
  EXPECT_EQ(OffscreenRenderer::Create(options).status().code(), absl::StatusCode::kInvalidArgument);
  auto renderer = MakeRenderer();
  ASSERT_NE(renderer, nullptr);
  RenderOutputs out;
  DrawItem unknown;
  unknown.mesh = MeshId{42};
  EXPECT_EQ(renderer->Render(TestCamera(), {unknown}, &out).code(),
            absl::StatusCode::kInvalidArgument);
  RenderCamera too_big = TestCamera();
  too_big.width = 641;
  EXPECT_EQ(renderer->Render(too_big, {}, &out).code(), absl::StatusCode::kInvalidArgument);
  MeshData no_uvs = MakeRectangle(-1, -1, 1, 1, 2);
  no_uvs.uvs.resize(2, 0);
  auto mesh = renderer->UploadMesh(no_uvs);
  auto texture = renderer->UploadTexture(RgbImage(4, 4));
  ASSERT_TRUE(mesh.ok() && texture.ok());
  DrawItem textured;
  textured.mesh = *mesh;
  textured.texture = *texture;
  EXPECT_EQ(renderer->Render(TestCamera(), {textured}, &out).code(),
            absl::StatusCode::kInvalidArgument);
  MeshData bad = no_uvs;
  bad.triangles.push_back({0, 1, 9});
  EXPECT_EQ(renderer->UploadMesh(bad).status().code(), absl::StatusCode::kInvalidArgument);
}

// With no EGL vendor library (glvnd finds no driver), Create reports
// Unavailable instead of crashing. Runs in a fresh child process so that the
// environment is read before EGL starts.
TEST(OffscreenRendererCreate, UnavailableWithoutEglDriver) {
  GTEST_FLAG_SET(death_test_style, "threadsafe");
  EXPECT_EXIT(
      {
        setenv("__EGL_VENDOR_LIBRARY_FILENAMES", "/nonexistent/egl_vendor.json", 1);
        auto renderer = OffscreenRenderer::Create(RendererOptions());
        std::fprintf(stderr, "%s\n", renderer.status().ToString().c_str());
        std::exit(renderer.status().code() == absl::StatusCode::kUnavailable ? 0 : 1);
      },
      testing::ExitedWithCode(0), "UNAVAILABLE.*EGL");
}

}  // namespace
}  // namespace reenact::render
