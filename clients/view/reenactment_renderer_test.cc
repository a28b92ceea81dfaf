#include "clients/view/reenactment_renderer.h"

#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <iterator>
#include <string>

#include <gtest/gtest.h>

#include "clients/view/testing/vdtm_scenes.h"
#include "common/io/jpeg.h"
#include "common/io/reenactment_convert.h"
#include "common/io/testing/small_reenactment.h"
#include "common/io/video_writer.h"

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
Reenactment ThreeSensorScene() {
  Reenactment data =
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

// The thesis' selection (Eq. 3.13): one keyframe per triangle.
ReenactmentRendererOptions SingleKeyframe() {
  ReenactmentRendererOptions options;
  options.blend_keyframes = false;
  return options;
}

TEST(ReenactmentRenderer, VdtmDrawsTheRotationClosestKeyframe) {
  auto renderer = MakeRenderer();
  ASSERT_NE(renderer, nullptr);
  const Reenactment data = ThreeSensorScene();
  auto view = ReenactmentRenderer::Create(data, renderer.get(), SingleKeyframe());
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

// Blending (the default): the two nearest keyframes by the angle of Eq.
// 3.13, weighted w2 = a1 / (a1 + a2), mixed in linear light. At a keyframe's
// own direction it shows alone; halfway between two they mix equally.
TEST(ReenactmentRenderer, VdtmBlendsTheTwoNearestKeyframesByTheirAngles) {
  auto renderer = MakeRenderer();
  ASSERT_NE(renderer, nullptr);
  const Reenactment data = ThreeSensorScene();
  auto view = ReenactmentRenderer::Create(data, renderer.get());
  ASSERT_TRUE(view.ok()) << view.status();
  const auto linear = [](double srgb) {
    const double x = srgb / 255.0;
    return x <= 0.04045 ? x / 12.92 : std::pow((x + 0.055) / 1.055, 2.4);
  };
  const auto srgb = [](double v) {
    return 255.0 * (v <= 0.0031308 ? 12.92 * v : 1.055 * std::pow(v, 1 / 2.4) - 0.055);
  };
  for (auto [yaw, w2, first, second] :
       {std::tuple{40.0, 0.0, kBlue, kGreen}, std::tuple{20.0, 0.5, kBlue, kGreen},
        std::tuple{30.0, 0.25, kBlue, kGreen}, std::tuple{-10.0, 0.25, kGreen, kRed}}) {
    const render::RenderCamera camera = ViewerCamera(yaw);
    render::RenderOutputs out;
    FrameStats stats;
    ASSERT_TRUE((*view)->Render(0, camera, &out, &stats).ok());
    EXPECT_EQ(stats.triangles_blended, w2 > 0.0 ? 128 : 0) << "yaw " << yaw;
    const Eigen::Vector2i centre = PixelOf(camera, {0.0, 0.0, 0.0});
    for (int c = 0; c < 3; ++c) {
      const double expected = srgb((1.0 - w2) * linear(first[c]) + w2 * linear(second[c]));
      // The weights come in 1/32 steps; JPEG keeps flat colours within a few levels.
      EXPECT_NEAR(out.colour.at(centre.x(), centre.y(), c), expected, 8)
          << "yaw " << yaw << " channel " << c;
    }
  }
}

TEST(ReenactmentRenderer, OccludedTrianglesShowTheNextBestKeyframe) {
  auto renderer = MakeRenderer();
  ASSERT_NE(renderer, nullptr);
  Reenactment data = ThreeSensorScene();
  testing::HideVertices(&data.keyframes[2], -1e-6);  // Left half hidden in s2.
  auto view = ReenactmentRenderer::Create(data, renderer.get(), SingleKeyframe());
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
  Reenactment data = ThreeSensorScene();
  // s2's mask: the left half of its image is background.
  MaskImage mask(testing::kImageWidth, testing::kImageHeight, 1);
  for (int y = 0; y < mask.height; ++y) {
    for (int x = 0; x < mask.width / 2; ++x) mask.at(x, y) = 0;
  }
  data.keyframes[2].mask_rle = EncodeMaskRle(mask);
  auto view = ReenactmentRenderer::Create(data, renderer.get(), SingleKeyframe());
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
  Reenactment data = ThreeSensorScene();
  RgbImage yellow(8, 8);
  for (size_t i = 0; i < yellow.data.size(); i += 3) {
    yellow.data[i] = 240;
    yellow.data[i + 1] = 220;
    yellow.data[i + 2] = 10;
  }
  data.parts[0].baked_texture_jpeg = EncodeJpeg(yellow, 95).value();
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
  const Reenactment data = ThreeSensorScene();
  ReenactmentRendererOptions options = SingleKeyframe();
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
  const Reenactment data = ThreeSensorScene();
  auto view = ReenactmentRenderer::Create(data, renderer.get());
  ASSERT_TRUE(view.ok());
  render::RenderOutputs out;
  EXPECT_EQ((*view)->Render(7, ViewerCamera(0.0), &out).code(), absl::StatusCode::kNotFound);
  render::RenderCamera bad = ViewerCamera(0.0);
  bad.fx = 0;
  EXPECT_EQ((*view)->Render(0, bad, &out).code(), absl::StatusCode::kInvalidArgument);
  Reenactment corrupt = ThreeSensorScene();
  corrupt.keyframes[2].color_jpeg = "not a jpeg";
  auto broken = ReenactmentRenderer::Create(corrupt, renderer.get());
  ASSERT_TRUE(broken.ok());
  EXPECT_EQ((*broken)->Render(0, ViewerCamera(30.0), &out).code(), absl::StatusCode::kDataLoss);
}

// A camera 3 m in front of the test body (which faces +Z), looking at it.
render::RenderCamera BodyCamera() {
  render::RenderCamera camera;
  camera.width = 240;
  camera.height = 320;
  camera.fx = camera.fy = 300.0;
  camera.cx = camera.width / 2.0;
  camera.cy = camera.height / 2.0;
  camera.world_from_camera = testing::WorldFromCamera(0.0, 3.0);
  camera.world_from_camera.translation().y() = 0.9;
  return camera;
}

std::unique_ptr<render::OffscreenRenderer> MakeBodyRenderer() {
  render::RendererOptions options;
  options.max_width = 240;
  options.max_height = 320;
  auto renderer = render::OffscreenRenderer::Create(options);
  EXPECT_TRUE(renderer.ok()) << renderer.status();
  return renderer.ok() ? std::move(renderer).value() : nullptr;
}

// `point` in the camera frame and its continuous pixel position.
Eigen::Vector3d InCamera(const render::RenderCamera& camera, const Eigen::Vector3d& point) {
  return camera.world_from_camera.inverse() * point;
}
Eigen::Vector2d Project(const render::RenderCamera& camera, const Eigen::Vector3d& c) {
  return {camera.fx * c.x() / c.z() + camera.cx, camera.fy * c.y() / c.z() + camera.cy};
}

// The silhouette of `triangles` over `vertices` (world) seen by `camera`:
// pixels whose centre lies in a projected triangle.
MaskImage ProjectedSilhouette(const render::RenderCamera& camera, const Eigen::Matrix3Xd& vertices,
                              const std::vector<Eigen::Vector3i>& triangles) {
  MaskImage mask(camera.width, camera.height, 0);
  std::vector<Eigen::Vector2d> pixels(vertices.cols());
  for (Eigen::Index v = 0; v < vertices.cols(); ++v) {
    pixels[v] = Project(camera, InCamera(camera, vertices.col(v)));
  }
  for (const Eigen::Vector3i& t : triangles) {
    const Eigen::Vector2d &a = pixels[t[0]], &b = pixels[t[1]], &c = pixels[t[2]];
    const double area = (b - a).x() * (c - a).y() - (b - a).y() * (c - a).x();
    if (std::abs(area) < 1e-12) continue;
    const int x0 = std::max(0, static_cast<int>(std::floor(std::min({a.x(), b.x(), c.x()}))));
    const int x1 = std::min(camera.width - 1, static_cast<int>(std::max({a.x(), b.x(), c.x()})));
    const int y0 = std::max(0, static_cast<int>(std::floor(std::min({a.y(), b.y(), c.y()}))));
    const int y1 = std::min(camera.height - 1, static_cast<int>(std::max({a.y(), b.y(), c.y()})));
    for (int y = y0; y <= y1; ++y) {
      for (int x = x0; x <= x1; ++x) {
        const Eigen::Vector2d p(x + 0.5, y + 0.5);
        auto edge = [&](const Eigen::Vector2d& u, const Eigen::Vector2d& w) {
          return ((w - u).x() * (p - u).y() - (w - u).y() * (p - u).x()) / area;
        };
        if (edge(a, b) >= 0 && edge(b, c) >= 0 && edge(c, a) >= 0) mask.at(x, y) = 1;
      }
    }
  }
  return mask;
}

double Iou(const MaskImage& a, const MaskImage& b) {
  int64_t both = 0, either = 0;
  for (size_t i = 0; i < a.data.size(); ++i) {
    both += a.data[i] > 0 && b.data[i] > 0;
    either += a.data[i] > 0 || b.data[i] > 0;
  }
  return either > 0 ? static_cast<double>(both) / either : 0.0;
}

// The body is drawn where its posed triangles project, with the atlas
// colour of what it shows: for every model vertex the camera sees (rendered
// depth within 5 mm of its own), the pixel's colour is the atlas at the
// vertex's uv (the test atlas is a smooth gradient, so the sample is stable).
TEST(ReenactmentRenderer, DrawsABodyReenactmentWithItsAtlas) {
  auto renderer = MakeBodyRenderer();
  ASSERT_NE(renderer, nullptr);
  const Reenactment data =
      ReenactmentFromProto(reenact::testing::MakeTestBodyReenactment(5)).value();
  const BodyMesh* decoded = &*data.body;
  auto atlas = DecodeJpeg(decoded->atlas_jpeg);
  ASSERT_TRUE(atlas.ok());
  std::vector<int> uv_of_vertex(decoded->num_vertices(), -1);
  for (size_t i = 0; i < decoded->texture_vertex_source.size(); ++i) {
    uv_of_vertex[decoded->texture_vertex_source[i]] = static_cast<int>(i);
  }
  const render::RenderCamera camera = BodyCamera();
  for (TextureMode mode : {TextureMode::kVdtm, TextureMode::kBaked}) {
    ReenactmentRendererOptions options;
    options.mode = mode;
    auto view = ReenactmentRenderer::Create(data, renderer.get(), options);
    ASSERT_TRUE(view.ok()) << view.status();
    for (int frame : {0, 1, 4}) {  // Frame 1 carries vertex offsets.
      render::RenderOutputs out;
      FrameStats stats;
      const auto start = std::chrono::steady_clock::now();
      ASSERT_TRUE((*view)->Render(frame, camera, &out, &stats).ok());
      const double ms =
          std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start)
              .count();
      EXPECT_EQ(stats.parts_drawn, 1);
      EXPECT_EQ(stats.draw_items, 1);
      EXPECT_EQ(stats.triangles, static_cast<int>(decoded->triangles.size()));
      EXPECT_EQ(stats.textures_uploaded, frame == 0 ? 1 : 0) << "atlas decoded more than once";
      auto posed = PoseBodyMesh(*decoded, *data.frames[frame].body);
      ASSERT_TRUE(posed.ok()) << posed.status();
      const double iou =
          Iou(out.label, ProjectedSilhouette(camera, posed->vertices_m, decoded->triangles));
      EXPECT_GT(iou, 0.98) << "frame " << frame;
      double colour_error = 0.0;
      int seen = 0;
      for (int v = 0; v < decoded->num_vertices(); ++v) {
        const Eigen::Vector3d c = InCamera(camera, posed->vertices_m.col(v));
        const Eigen::Vector2d p = Project(camera, c);
        const int x = static_cast<int>(p.x()), y = static_cast<int>(p.y());
        if (x < 0 || y < 0 || x >= camera.width || y >= camera.height) continue;
        if (std::abs(out.depth_m.at(x, y) - c.z()) > 0.005) continue;  // Hidden.
        const Eigen::Vector2f uv = decoded->texture_uvs[uv_of_vertex[v]];
        const int ax = std::clamp(static_cast<int>(uv.x() * atlas->width), 0, atlas->width - 1);
        const int ay =
            std::clamp(static_cast<int>((1.0f - uv.y()) * atlas->height), 0, atlas->height - 1);
        for (int k = 0; k < 3; ++k) {
          colour_error += std::abs(out.colour.at(x, y, k) - atlas->at(ax, ay, k)) / 3.0;
        }
        ++seen;
      }
      ASSERT_GT(seen, 200) << "frame " << frame;
      // Neighbouring texels of the gradient differ by 4 levels; a pixel also
      // covers up to a few texels and the vertex's uv sits on seams.
      EXPECT_LT(colour_error / seen, 12.0) << "frame " << frame;
      std::printf(
          "body frame %d (%s): IoU %.4f against the projected mesh, %d vertices seen, "
          "mean colour error %.2f levels, %.2f ms\n",
          frame, mode == TextureMode::kVdtm ? "vdtm" : "baked", iou, seen, colour_error / seen, ms);
    }
  }
}

TEST(ReenactmentRenderer, BodyReenactmentHidesInvalidPosesAndReportsABadAtlas) {
  auto renderer = MakeBodyRenderer();
  ASSERT_NE(renderer, nullptr);
  Reenactment data = ReenactmentFromProto(reenact::testing::MakeTestBodyReenactment(3)).value();
  data.frames[2].body->valid = false;
  auto view = ReenactmentRenderer::Create(data, renderer.get());
  ASSERT_TRUE(view.ok()) << view.status();
  render::RenderOutputs out;
  FrameStats stats;
  ASSERT_TRUE((*view)->Render(2, BodyCamera(), &out, &stats).ok());
  EXPECT_EQ(stats.parts_drawn, 0);
  EXPECT_EQ(std::count(out.label.data.begin(), out.label.data.end(), 0),
            static_cast<long>(out.label.data.size()));
  EXPECT_EQ((*view)->Render(3, BodyCamera(), &out).code(), absl::StatusCode::kNotFound);

  data.body->atlas_jpeg = "not a jpeg";
  auto broken = ReenactmentRenderer::Create(data, renderer.get());
  ASSERT_TRUE(broken.ok());
  EXPECT_EQ((*broken)->Render(0, BodyCamera(), &out).code(), absl::StatusCode::kDataLoss);
  // Then drawn untextured (lit grey).
  ASSERT_TRUE((*broken)->Render(0, BodyCamera(), &out, &stats).ok());
  EXPECT_EQ(stats.parts_drawn, 1);

  data.body->skin_joints.pop_back();
  EXPECT_EQ(ReenactmentRenderer::Create(data, renderer.get()).status().code(),
            absl::StatusCode::kInvalidArgument);
}

// An appearance video of `frames` solid-colour atlases (64 x 64), frame k
// in kAppearanceColours[k % 5], as the body method stores it.
const std::array<Eigen::Vector3i, 5> kAppearanceColours = {
    Eigen::Vector3i(220, 40, 40), Eigen::Vector3i(40, 200, 60), Eigen::Vector3i(40, 60, 220),
    Eigen::Vector3i(220, 210, 40), Eigen::Vector3i(40, 200, 210)};

std::string SolidAppearanceVideo(int frames) {
  const std::string path = ::testing::TempDir() + "/appearance.mp4";
  VideoWriterOptions options;
  options.keyframe_interval = 2;
  auto writer = VideoWriter::Open(path, 64, 64, 15.0, options);
  EXPECT_TRUE(writer.ok()) << writer.status();
  if (!writer.ok()) return "";
  for (int k = 0; k < frames; ++k) {
    RgbImage atlas(64, 64);
    for (int i = 0; i < 64 * 64; ++i) {
      for (int c = 0; c < 3; ++c) {
        atlas.data[3 * i + c] = static_cast<uint8_t>(kAppearanceColours[k % 5][c]);
      }
    }
    EXPECT_TRUE((*writer)->Append(atlas).ok());
  }
  EXPECT_TRUE((*writer)->Close().ok());
  std::ifstream in(path, std::ios::binary);
  return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

// The mean colour of the body's pixels (label 1).
Eigen::Vector3d MeanBodyColour(const render::RenderOutputs& out) {
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  int n = 0;
  for (int y = 0; y < out.label.height; ++y) {
    for (int x = 0; x < out.label.width; ++x) {
      if (out.label.at(x, y) != 1) continue;
      for (int c = 0; c < 3; ++c) sum[c] += out.colour.at(x, y, c);
      ++n;
    }
  }
  return n > 0 ? Eigen::Vector3d(sum / n) : Eigen::Vector3d::Constant(-1.0);
}

// A body with an appearance video is drawn with each instant's atlas,
// whatever order the frames are asked in (on, back, again); a video of
// another length, one that does not decode and one cut short leave the
// static atlas drawn and say why; nothing fails.
TEST(ReenactmentRenderer, BodyAppearanceVideoGivesEachInstantItsAtlas) {
  auto renderer = MakeBodyRenderer();
  ASSERT_NE(renderer, nullptr);
  Reenactment data = ReenactmentFromProto(reenact::testing::MakeTestBodyReenactment(5)).value();
  BodyMesh& mesh = *data.body;
  mesh.appearance_mp4 = SolidAppearanceVideo(5);
  ASSERT_FALSE(mesh.appearance_mp4.empty());
  mesh.appearance_size_px = 64;
  mesh.appearance_frame_count = 5;
  const render::RenderCamera camera = BodyCamera();
  {
    auto view = ReenactmentRenderer::Create(data, renderer.get());
    ASSERT_TRUE(view.ok()) << view.status();
    double worst = 0.0;
    for (int frame : {0, 1, 2, 4, 1, 3, 0}) {
      render::RenderOutputs out;
      FrameStats stats;
      ASSERT_TRUE((*view)->Render(frame, camera, &out, &stats).ok()) << frame;
      EXPECT_TRUE(stats.per_frame_appearance);
      const Eigen::Vector3d mean = MeanBodyColour(out);
      const double error = (mean - kAppearanceColours[frame].cast<double>()).cwiseAbs().maxCoeff();
      worst = std::max(worst, error);
      EXPECT_LT(error, 8.0) << "frame " << frame << ": " << mean.transpose();
    }
    EXPECT_TRUE((*view)->appearance_note().empty());
    std::printf("appearance video: worst mean body colour off by %.2f levels\n", worst);
  }
  // The static atlas (a gradient) is what the fallbacks draw.
  ReenactmentRendererOptions no_video;
  no_video.appearance = false;
  render::RenderOutputs reference;
  {
    auto view = ReenactmentRenderer::Create(data, renderer.get(), no_video);
    ASSERT_TRUE(view.ok());
    FrameStats stats;
    ASSERT_TRUE((*view)->Render(2, camera, &reference, &stats).ok());
    EXPECT_FALSE(stats.per_frame_appearance);
  }
  const Eigen::Vector3d static_mean = MeanBodyColour(reference);
  const auto expect_static = [&](const Reenactment& broken, const std::string& what) {
    auto view = ReenactmentRenderer::Create(broken, renderer.get());
    ASSERT_TRUE(view.ok()) << what;
    for (int frame = 0; frame < 5; ++frame) {
      render::RenderOutputs out;
      FrameStats stats;
      ASSERT_TRUE((*view)->Render(frame, camera, &out, &stats).ok()) << what << " " << frame;
      if (stats.per_frame_appearance) continue;  // Frames before the cut.
      if (frame == 2) {
        EXPECT_LT((MeanBodyColour(out) - static_mean).cwiseAbs().maxCoeff(), 1.0) << what;
      }
    }
    EXPECT_NE((*view)->appearance_note().find("static atlas"), std::string::npos) << what;
    std::printf("%s: %s\n", what.c_str(), (*view)->appearance_note().c_str());
  };
  Reenactment longer = data;
  longer.body->appearance_frame_count = 6;
  expect_static(longer, "frame count that differs");
  Reenactment garbage = data;
  garbage.body->appearance_mp4 = std::string(2048, '\x5a');
  expect_static(garbage, "bytes that are no video");
  Reenactment cut = data;
  cut.body->appearance_mp4.resize(cut.body->appearance_mp4.size() / 2);
  expect_static(cut, "video cut in half");
}

TEST(OrbitCamera, TurnsAboutTheVerticalThroughThePivot) {
  const render::RenderCamera camera = ViewerCamera(0.0);
  const render::RenderCamera turned = OrbitCamera(camera, testing::kCentre, 90.0);
  const render::RenderCamera expected = ViewerCamera(90.0);
  EXPECT_TRUE(turned.world_from_camera.isApprox(expected.world_from_camera, 1e-12));
}

}  // namespace
}  // namespace reenact::view
