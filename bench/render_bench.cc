// Speed of the offscreen renderer: a textured ~20k-triangle mesh drawn and
// read back at a Kinect v2 depth size (depth + label) and at 1080p (colour).
#include <memory>

#include <benchmark/benchmark.h>

#include "common/render/offscreen_renderer.h"

namespace reenact::render {
namespace {

struct Scene {
  std::unique_ptr<OffscreenRenderer> renderer;
  MeshData mesh_data;
  DrawItem item;
};

// A sphere of 20,000 triangles with a 1024 x 1024 checker texture, 2 m ahead.
Scene* GetScene(benchmark::State& state) {
  static Scene* scene = [] {
    auto* s = new Scene;
    auto renderer = OffscreenRenderer::Create(RendererOptions());
    if (!renderer.ok()) return s;
    s->renderer = std::move(renderer).value();
    s->mesh_data = MakeUvSphere(0.6f, 100, 101);
    RgbImage texture(1024, 1024);
    for (int y = 0; y < texture.height; ++y) {
      for (int x = 0; x < texture.width; ++x) {
        const bool odd = ((x / 64) + (y / 64)) % 2 != 0;
        texture.at(x, y, 0) = odd ? 220 : 30;
        texture.at(x, y, 1) = 90;
        texture.at(x, y, 2) = odd ? 40 : 200;
      }
    }
    s->item.mesh = s->renderer->UploadMesh(s->mesh_data).value();
    s->item.texture = s->renderer->UploadTexture(texture).value();
    s->item.world_from_model.translation() = Eigen::Vector3d(0, 0, 2.0);
    return s;
  }();
  if (scene->renderer == nullptr) state.SkipWithError("no EGL/OpenGL renderer");
  return scene;
}

RenderCamera Camera(int width, int height, double f_px) {
  RenderCamera camera;
  camera.width = width;
  camera.height = height;
  camera.fx = camera.fy = f_px;
  camera.cx = width / 2.0;
  camera.cy = height / 2.0;
  return camera;
}

void RenderLoop(benchmark::State& state, const RenderCamera& camera, uint32_t requested) {
  Scene* scene = GetScene(state);
  if (scene->renderer == nullptr) return;
  RenderOutputs out;
  out.requested = requested;
  for (auto _ : state) {
    if (!scene->renderer->Render(camera, {scene->item}, &out).ok()) {
      state.SkipWithError("Render failed");
      return;
    }
    benchmark::DoNotOptimize(out.depth_m.data.data());
  }
  state.counters["triangles"] = static_cast<double>(scene->mesh_data.triangles.size());
}

void BM_RenderDepthLabel_512x424(benchmark::State& state) {
  RenderLoop(state, Camera(512, 424, 365.0), kRenderDepth | kRenderLabel);
}
BENCHMARK(BM_RenderDepthLabel_512x424)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_RenderColour_1920x1080(benchmark::State& state) {
  RenderLoop(state, Camera(1920, 1080, 1060.0), kRenderColour);
}
BENCHMARK(BM_RenderColour_1920x1080)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_RenderAll_1920x1080(benchmark::State& state) {
  RenderLoop(state, Camera(1920, 1080, 1060.0),
             kRenderColour | kRenderDepth | kRenderLabel | kRenderNormals);
}
BENCHMARK(BM_RenderAll_1920x1080)->Unit(benchmark::kMillisecond)->UseRealTime();

// The per-frame upload of an animated mesh (positions + recomputed normals).
void BM_UpdateMeshPositions_20k(benchmark::State& state) {
  Scene* scene = GetScene(state);
  if (scene->renderer == nullptr) return;
  Eigen::Matrix3Xf positions_m = scene->mesh_data.positions_m;
  for (auto _ : state) {
    positions_m.row(0).array() += 1e-6f;
    if (!scene->renderer->UpdateMeshPositions(scene->item.mesh, positions_m).ok()) {
      state.SkipWithError("UpdateMeshPositions failed");
      return;
    }
  }
}
BENCHMARK(BM_UpdateMeshPositions_20k)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace
}  // namespace reenact::render

BENCHMARK_MAIN();
