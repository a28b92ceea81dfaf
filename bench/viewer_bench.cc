// What the viewer draws per frame for a body-model reenactment (thesis ch. 4;
// the goal is >= 60 frames/s at 1280x720 on the machine's software OpenGL,
// Mesa llvmpipe): the default procedural body (the reenactments' model),
// posed by CMU 131_01 retargeted onto it, a 1024x1024 atlas, seen by a
// camera orbiting the actor's mean position 3.5 m away, 1.3 m high, with a
// 50 degree horizontal field of view: the whole body in view (about 9 % of
// the image), about as large as in the viewer's default sensor view. The
// body is drawn with its back faces culled (DrawItem::cull_back_faces). Each iteration is one frame
// as reenact-viewer makes it:
// the instant's skinning on the CPU, the upload of the positions, the draw
// and the colour read back (ReenactmentRenderer::Render). Variants with and
// without 4x multisampling (the window's default) and at 1920x1080.
//
// REENACT_BENCH_REENACTMENT=FILE.reen measures that reenactment instead (e.g.
// the demo's body reenactment under out/demo/server/reenactments/). The
// _SwitchContext variant also releases the renderer's context after every
// frame, as the window does to show the image with its own context.
//
//   build/bench/viewer_bench [--benchmark_filter=...]
#include <benchmark/benchmark.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <string>

#include "clients/view/reenactment_renderer.h"
#include "clients/viewer/viewer_camera.h"
#include "common/body/motion.h"
#include "common/body/procedural_body.h"
#include "common/body/retarget.h"
#include "common/io/body_reenactment.h"
#include "common/io/jpeg.h"
#include "common/io/reenactment_convert.h"
#include "common/render/offscreen_renderer.h"

namespace reenact {
namespace {

// A body reenactment of 120 instants of a CMU dance, or empty on failure.
const Reenactment* BodyReenactment() {
  static const Reenactment* data = []() -> const Reenactment* {
    if (const char* file = std::getenv("REENACT_BENCH_REENACTMENT"); file != nullptr) {
      auto read = ReadReenactment(file);
      if (!read.ok()) {
        std::fprintf(stderr, "%s\n", std::string(read.status().message()).c_str());
        return nullptr;
      }
      return new Reenactment(std::move(*read));
    }
    auto model = body::BuildProceduralBody();
    auto motion = body::ReadMotion(std::string(REENACT_TEST_DATA_DIR) + "/mocap/cmu/131_01.bvh");
    if (!model.ok() || !motion.ok()) return nullptr;
    const Eigen::VectorXd shape = Eigen::VectorXd::Zero(model->num_shape_components());
    auto poses = body::RetargetMotion(*motion, *model, shape);
    if (!poses.ok()) return nullptr;
    RgbImage atlas(1024, 1024);
    for (int y = 0; y < atlas.height; ++y) {
      for (int x = 0; x < atlas.width; ++x) {
        atlas.at(x, y, 0) = static_cast<uint8_t>(x / 4);
        atlas.at(x, y, 1) = static_cast<uint8_t>(y / 4);
        atlas.at(x, y, 2) = static_cast<uint8_t>(((x / 32 + y / 32) % 2) * 200);
      }
    }
    auto jpeg = EncodeJpeg(atlas, 90);
    auto message = jpeg.ok() ? MakeBodyMesh(*model, shape, *jpeg) : jpeg.status();
    auto mesh = message.ok() ? BodyMeshFromProto(*message) : message.status();
    if (!mesh.ok()) return nullptr;
    auto* d = new Reenactment;
    d->info.reenactment_id = "r-bench-body";
    d->info.method = "body";
    d->info.fps = 30.0;
    d->body = std::move(*mesh);
    const int frames = std::min<int>(120, static_cast<int>(poses->poses.size()));
    // The dance moves about the room: centred on the origin, where the
    // camera looks, so that every frame draws the whole body.
    Eigen::Vector3d mean_root = Eigen::Vector3d::Zero();
    for (int f = 0; f < frames; ++f) mean_root += poses->poses[f].root_translation_m;
    mean_root /= std::max(frames, 1);
    mean_root.y() = 0.0;
    for (int f = 0; f < frames; ++f) poses->poses[f].root_translation_m -= mean_root;
    d->info.frame_count = frames;
    for (int f = 0; f < frames; ++f) {
      ReenactmentFrame& frame = d->frames.emplace_back();
      frame.frame_index = f;
      frame.body.emplace().pose = poses->poses[f];
      frame.body->valid = true;
    }
    return d;
  }();
  return data;
}

void RenderBody(benchmark::State& state, int width, int height, int msaa,
                bool switch_context = false) {
  const Reenactment* data = BodyReenactment();
  if (data == nullptr) {
    state.SkipWithError("no body reenactment (test data missing?)");
    return;
  }
  render::RendererOptions options;
  options.max_width = width;
  options.max_height = height;
  options.msaa_samples = msaa;
  auto renderer = render::OffscreenRenderer::Create(options);
  if (!renderer.ok()) {
    state.SkipWithError(std::string(renderer.status().message()).c_str());
    return;
  }
  auto view = view::ReenactmentRenderer::Create(*data, renderer->get());
  if (!view.ok()) {
    state.SkipWithError(std::string(view.status().message()).c_str());
    return;
  }
  const int frames = static_cast<int>(data->frames.size());
  const absl::StatusOr<Eigen::Vector3d> actor = view::MeanActorPosition(*data);
  const Eigen::Vector3d target(actor.ok() ? actor->x() : 0.0, 0.9, actor.ok() ? actor->z() : 0.0);
  int64_t n = 0;
  for (auto _ : state) {
    const double yaw = 3.0 * static_cast<double>(n);
    const Eigen::Vector3d eye = target + Eigen::Vector3d(3.5 * std::sin(yaw * M_PI / 180), 0.4,
                                                         3.5 * std::cos(yaw * M_PI / 180));
    auto camera = viewer::LookAtCamera(eye, target, 50.0, width, height);
    render::RenderOutputs out;
    out.requested = render::kRenderColour;
    const int instant = data->frames[n % frames].frame_index;
    if (!camera.ok() || !(*view)->Render(instant, *camera, &out).ok()) {
      state.SkipWithError("render failed");
      return;
    }
    benchmark::DoNotOptimize(out.colour.data.data());
    if (switch_context && !(*renderer)->ReleaseCurrent().ok()) {
      state.SkipWithError("ReleaseCurrent failed");
      return;
    }
    ++n;
  }
  state.counters["fps"] = benchmark::Counter(static_cast<double>(n), benchmark::Counter::kIsRate);
  state.SetLabel((*renderer)->Description());
}

void BM_ViewerBody_1280x720_Msaa4(benchmark::State& state) { RenderBody(state, 1280, 720, 4); }
void BM_ViewerBody_1280x720_NoMsaa(benchmark::State& state) { RenderBody(state, 1280, 720, 0); }
void BM_ViewerBody_1280x720_NoMsaa_SwitchContext(benchmark::State& state) {
  RenderBody(state, 1280, 720, 0, true);
}
void BM_ViewerBody_1920x1080_Msaa4(benchmark::State& state) { RenderBody(state, 1920, 1080, 4); }
BENCHMARK(BM_ViewerBody_1280x720_Msaa4)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_ViewerBody_1280x720_NoMsaa)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_ViewerBody_1280x720_NoMsaa_SwitchContext)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();
BENCHMARK(BM_ViewerBody_1920x1080_Msaa4)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace
}  // namespace reenact

BENCHMARK_MAIN();
