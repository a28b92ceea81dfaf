#include "clients/view/reenactment_renderer.h"

#include <cmath>

#include <gtest/gtest.h>

#include "clients/view/test_scene.h"
#include "common/io/jpeg.h"

namespace reenact::view {
namespace {

using testing::MakeFrame;
using testing::MakeSquareReenactment;
using testing::SolidKeyframe;
using testing::ViewerCamera;

const Eigen::Vector3i kRed(230, 20, 20), kGreen(20, 200, 40), kBlue(30, 40, 220);

std::unique_ptr<render::OffscreenRenderer> MakeRenderer() {
  render::RendererOptions options;
  options.max_width = testing::kImageWidth;
  options.max_height = testing::kImageHeight;
  auto renderer = render::OffscreenRenderer::Create(options);
  EXPECT_TRUE(renderer.ok()) << renderer.status();
  return renderer.ok() ? std::move(renderer).value() : nullptr;
}

// Sensors at -40, 0 and +40 degrees with red, green and blue keyframes.
ReenactmentData ThreeSensorScene() {
  ReenactmentData data =
      MakeSquareReenactment({MakeFrame(0, 0.0), MakeFrame(1, 0.0, 2.0)}, {-40.0, 0.0, 40.0});
  data.keyframes = {SolidKeyframe(0, "s0", kRed), SolidKeyframe(0, "s1", kGreen),
                    SolidKeyframe(0, "s2", kBlue)};
  return data;
}

// The pixel where a point of the square (part frame at frame 0) lands.
Eigen::Vector2i PixelOf(const render::RenderCamera& camera, const Eigen::Vector3d& point_in_part) {
  const Eigen::Vector3d c = camera.world_from_camera.inverse() * (testing::kCentre + point_in_part);
  return {static_cast<int>(camera.fx * c.x() / c.z() + camera.cx),
          static_cast<int>(camera.fy * c.y() / c.z() + camera.cy)};
}

void ExpectColour(const render::RenderOutputs& out, const Eigen::Vector2i& pixel,
                  const Eigen::Vector3i& rgb, const std::string& what) {
  for (int c = 0; c < 3; ++c) {
    // JPEG of a flat colour round-trips within a few levels.
    EXPECT_NEAR(out.colour.at(pixel.x(), pixel.y(), c), rgb[c], 6) << what << " channel " << c;
  }
}

TEST(ReenactmentRenderer, VdtmDrawsTheRotationClosestKeyframe) {
  auto renderer = MakeRenderer();
  ASSERT_NE(renderer, nullptr);
  const ReenactmentData data = ThreeSensorScene();
  auto view = ReenactmentRenderer::Create(data, renderer.get());
  ASSERT_TRUE(view.ok()) << view.status();
  for (auto [yaw, expected, colour] :
       {std::tuple{30.0, 2, kBlue}, std::tuple{-25.0, 0, kRed}, std::tuple{5.0, 1, kGreen}}) {
    const render::RenderCamera camera = ViewerCamera(yaw);
    render::RenderOutputs out;
    FrameStats stats;
    ASSERT_TRUE((*view)->Render(0, camera, &out, &stats).ok());
    EXPECT_EQ(stats.best_keyframe[0], expected) << "yaw " << yaw;
    EXPECT_EQ(stats.triangles, 128);
    EXPECT_EQ(stats.triangles_next_best, 0);
    ExpectColour(out, PixelOf(camera, {0.0, 0.0, 0.0}), colour, "centre");
    EXPECT_EQ(out.label.at(PixelOf(camera, {0.0, 0.0, 0.0}).x(), PixelOf(camera, {0, 0, 0}).y()),
              1);
  }
}

TEST(ReenactmentRenderer, OccludedTrianglesShowTheNextBestKeyframe) {
  auto renderer = MakeRenderer();
  ASSERT_NE(renderer, nullptr);
  ReenactmentData data = ThreeSensorScene();
  testing::HideVertices(&data.keyframes[2], -1e-6);  // Left half hidden in s2.
  auto view = ReenactmentRenderer::Create(data, renderer.get());
  ASSERT_TRUE(view.ok()) << view.status();
  const render::RenderCamera camera = ViewerCamera(30.0);
  render::RenderOutputs out;
  FrameStats stats;
  ASSERT_TRUE((*view)->Render(0, camera, &out, &stats).ok());
  EXPECT_EQ(stats.triangles_next_best, 64);
  EXPECT_EQ(stats.draw_items, 2);
  ExpectColour(out, PixelOf(camera, {-0.12, 0.05, 0.0}), kGreen, "left (next best: s1)");
  ExpectColour(out, PixelOf(camera, {0.12, 0.05, 0.0}), kBlue, "right (best: s2)");
}

TEST(ReenactmentRenderer, LookupsOnMaskBackgroundAreDiscarded) {
  auto renderer = MakeRenderer();
  ASSERT_NE(renderer, nullptr);
  ReenactmentData data = ThreeSensorScene();
  // s2's mask: the left half of its image is background.
  MaskImage mask(testing::kImageWidth, testing::kImageHeight, 1);
  for (int y = 0; y < mask.height; ++y) {
    for (int x = 0; x < mask.width / 2; ++x) mask.at(x, y) = 0;
  }
  data.keyframes[2].set_mask_rle(EncodeMaskRle(mask));
  auto view = ReenactmentRenderer::Create(data, renderer.get());
  ASSERT_TRUE(view.ok()) << view.status();
  const render::RenderCamera camera = ViewerCamera(30.0);
  render::RenderOutputs out;
  ASSERT_TRUE((*view)->Render(0, camera, &out).ok());
  const Eigen::Vector2i left = PixelOf(camera, {-0.12, 0.05, 0.0});
  const Eigen::Vector2i right = PixelOf(camera, {0.12, 0.05, 0.0});
  EXPECT_EQ(out.label.at(left.x(), left.y()), 0) << "background lookup drawn";
  EXPECT_EQ(out.depth_m.at(left.x(), left.y()), 0.0f);
  EXPECT_EQ(out.label.at(right.x(), right.y()), 1);
  ExpectColour(out, right, kBlue, "right");
}

TEST(ReenactmentRenderer, BakedModeUsesTheBakedTextureAndScaleGrowsThePart) {
  auto renderer = MakeRenderer();
  ASSERT_NE(renderer, nullptr);
  ReenactmentData data = ThreeSensorScene();
  RgbImage yellow(8, 8);
  for (size_t i = 0; i < yellow.data.size(); i += 3) {
    yellow.data[i] = 240;
    yellow.data[i + 1] = 220;
    yellow.data[i + 2] = 10;
  }
  data.parts[0].set_baked_texture_jpeg(EncodeJpeg(yellow, 95).value());
  ReenactmentRendererOptions options;
  options.mode = TextureMode::kBaked;
  auto view = ReenactmentRenderer::Create(data, renderer.get(), options);
  ASSERT_TRUE(view.ok()) << view.status();
  const render::RenderCamera camera = ViewerCamera(0.0);
  auto silhouette_width = [&](int frame) {
    render::RenderOutputs out;
    EXPECT_TRUE((*view)->Render(frame, camera, &out).ok());
    ExpectColour(out, PixelOf(camera, {0, 0, 0}), {240, 220, 10}, "baked");
    int width = 0;
    for (int x = 0; x < out.label.width; ++x)
      width += out.label.at(x, testing::kImageHeight / 2) > 0;
    return width;
  };
  const int unit = silhouette_width(0);
  const int doubled = silhouette_width(1);  // PartPose.scale 2.
  // 0.4 m at 2 m with f = 150 px: 30 px; twice that at scale 2.
  EXPECT_NEAR(unit, 30, 1);
  EXPECT_NEAR(doubled, 60, 1);
}

TEST(ReenactmentRenderer, TextureCacheStaysWithinItsBudget) {
  auto renderer = MakeRenderer();
  ASSERT_NE(renderer, nullptr);
  const ReenactmentData data = ThreeSensorScene();
  ReenactmentRendererOptions options;
  auto view = ReenactmentRenderer::Create(data, renderer.get(), options);
  ASSERT_TRUE(view.ok());
  render::RenderOutputs out;
  FrameStats stats;
  ASSERT_TRUE((*view)->Render(0, ViewerCamera(30.0), &out, &stats).ok());
  EXPECT_EQ(stats.textures_uploaded, 1);
  ASSERT_TRUE((*view)->Render(0, ViewerCamera(30.0), &out, &stats).ok());
  EXPECT_EQ(stats.textures_uploaded, 0) << "decoded twice";
  ASSERT_TRUE((*view)->Render(0, ViewerCamera(-30.0), &out, &stats).ok());
  EXPECT_EQ(stats.textures_uploaded, 1);
  EXPECT_GT((*view)->cached_texture_bytes(), 0);

  options.texture_cache_bytes = 0;
  auto tight = ReenactmentRenderer::Create(data, renderer.get(), options);
  ASSERT_TRUE(tight.ok());
  for (int i = 0; i < 2; ++i) {
    ASSERT_TRUE((*tight)->Render(0, ViewerCamera(30.0), &out, &stats).ok());
    EXPECT_EQ(stats.textures_uploaded, 1);
    EXPECT_EQ((*tight)->cached_texture_bytes(), 0);
  }
}

TEST(ReenactmentRenderer, BadFrameAndCameraAreErrors) {
  auto renderer = MakeRenderer();
  ASSERT_NE(renderer, nullptr);
  const ReenactmentData data = ThreeSensorScene();
  auto view = ReenactmentRenderer::Create(data, renderer.get());
  ASSERT_TRUE(view.ok());
  render::RenderOutputs out;
  EXPECT_EQ((*view)->Render(7, ViewerCamera(0.0), &out).code(), absl::StatusCode::kNotFound);
  render::RenderCamera bad = ViewerCamera(0.0);
  bad.fx = 0;
  EXPECT_EQ((*view)->Render(0, bad, &out).code(), absl::StatusCode::kInvalidArgument);
  ReenactmentData corrupt = ThreeSensorScene();
  corrupt.keyframes[2].set_color_jpeg("not a jpeg");
  auto broken = ReenactmentRenderer::Create(corrupt, renderer.get());
  ASSERT_TRUE(broken.ok());
  EXPECT_EQ((*broken)->Render(0, ViewerCamera(30.0), &out).code(), absl::StatusCode::kDataLoss);
}

TEST(OrbitCamera, TurnsAboutTheVerticalThroughThePivot) {
  const render::RenderCamera camera = ViewerCamera(0.0);
  const render::RenderCamera turned = OrbitCamera(camera, testing::kCentre, 90.0);
  const render::RenderCamera expected = ViewerCamera(90.0);
  EXPECT_TRUE(turned.world_from_camera.isApprox(expected.world_from_camera, 1e-12));
}

}  // namespace
}  // namespace reenact::view
