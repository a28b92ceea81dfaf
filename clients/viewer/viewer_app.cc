#include "clients/viewer/viewer_app.h"

#include <chrono>

#include "absl/strings/str_format.h"
#include "clients/viewer/hud.h"
#include "clients/viewer/playback.h"
#include "clients/viewer/viewer_camera.h"
#include "common/base/status_macros.h"
#include "common/render/image_window.h"
#include "common/render/offscreen_renderer.h"

namespace reenact::viewer {
namespace {

using Clock = std::chrono::steady_clock;

double Seconds(Clock::duration d) { return std::chrono::duration<double>(d).count(); }

// Where the orbit starts: sensor 0's colour camera about the actor's mean
// position, else 3 m in front of the actor (or of the origin).
OrbitController StartingOrbit(const Reenactment& data, int width, int height) {
  const absl::StatusOr<Eigen::Vector3d> actor = view::MeanActorPosition(data);
  const Eigen::Vector3d target = actor.ok() ? *actor : Eigen::Vector3d(0, 1, 0);
  if (static_cast<int>(data.info.sensors.size()) > 0) {
    if (auto camera = view::SensorRenderCamera(data.info.sensors[0], width, height); camera.ok()) {
      return OrbitController::FromCamera(*camera, target);
    }
  }
  render::RenderCamera camera;
  camera.width = width;
  camera.fx = 0.5 * width / std::tan(25.0 * M_PI / 180.0);
  camera.world_from_camera.translation() = target + Eigen::Vector3d(0, 0.3, 3.0);
  return OrbitController::FromCamera(camera, target);
}

// Applies the input of one frame; false when the user asked to quit.
// `scrubbing` holds whether the left button went down on the timeline.
bool HandleInput(const render::WindowInput& input, int width, int height, OrbitController* orbit,
                 Playback* playback, bool* scrubbing) {
  if (input.close_requested) return false;
  for (int key : input.keys_pressed) {
    switch (key) {
      case render::kKeyEscape:
      case 'Q':
        return false;
      case render::kKeySpace:
        playback->TogglePlaying();
        break;
      case render::kKeyLeft:
        playback->Step(-1);
        break;
      case render::kKeyRight:
        playback->Step(1);
        break;
      case render::kKeyUp:
        playback->SetSpeed(playback->speed() * 2);
        break;
      case render::kKeyDown:
        playback->SetSpeed(playback->speed() / 2);
        break;
      case render::kKeyHome:
        playback->Scrub(0.0);
        break;
      case render::kKeyEnd:
        playback->Scrub(1.0);
        break;
      case 'L':
        playback->SetLoop(!playback->loop());
        break;
      case 'R':
        orbit->Reset();
        break;
      default:
        break;
    }
  }
  // A press on the timeline scrubs (and so does dragging along it); a drag
  // that started elsewhere orbits.
  if (input.press_x_px >= 0) {
    *scrubbing = TimelineFractionAt(input.press_x_px, input.press_y_px, width, height) >= 0;
  }
  if (*scrubbing) {
    playback->Scrub(std::clamp(input.pointer_x_px / (width - 1), 0.0, 1.0));
    if (!input.button_down) *scrubbing = false;
  } else if (input.drag_dx_px != 0 || input.drag_dy_px != 0) {
    orbit->Rotate(input.drag_dx_px, input.drag_dy_px);
  }
  if (input.scroll != 0) orbit->Zoom(input.scroll);
  return true;
}

}  // namespace

absl::StatusOr<WindowSummary> RunOrbitWindow(const Reenactment& data,
                                             const WindowOptions& options) {
  if (data.frames.empty()) return absl::InvalidArgumentError("the reenactment has no instant");
  if (!(options.run_seconds >= 0)) return absl::InvalidArgumentError("run_seconds must be >= 0");
  render::RendererOptions renderer_options;
  renderer_options.max_width = options.width;
  renderer_options.max_height = options.height;
  renderer_options.msaa_samples = options.msaa_samples;
  ASSIGN_OR_RETURN(auto renderer, render::OffscreenRenderer::Create(renderer_options));
  render::ShadingOptions shading;
  shading.background_srgb = Eigen::Vector3f(0.12f, 0.12f, 0.14f);
  RETURN_IF_ERROR(renderer->SetShading(shading));
  view::ReenactmentRendererOptions view_options;
  view_options.mode = options.mode;
  ASSIGN_OR_RETURN(auto view,
                   view::ReenactmentRenderer::Create(data, renderer.get(), view_options));
  RETURN_IF_ERROR(renderer->ReleaseCurrent());
  ASSIGN_OR_RETURN(auto window,
                   render::ImageWindow::Open("reenact-viewer " + data.info.reenactment_id,
                                             options.width, options.height));
  Playback playback(static_cast<int>(data.frames.size()), data.info.fps);
  playback.SetSpeed(options.speed);
  playback.SetLoop(options.loop);
  OrbitController orbit = StartingOrbit(data, options.width, options.height);

  WindowSummary summary;
  double render_seconds = 0.0;
  const Clock::time_point start = Clock::now();
  Clock::time_point last = start;
  double fps_shown = 0.0;
  bool scrubbing = false;
  while (true) {
    const Clock::time_point now = Clock::now();
    playback.Advance(Seconds(now - last));
    if (Seconds(now - last) > 0) fps_shown = 0.9 * fps_shown + 0.1 / Seconds(now - last);
    last = now;
    ASSIGN_OR_RETURN(render::RenderCamera camera, orbit.Camera(options.width, options.height));
    render::RenderOutputs out;
    out.requested = render::kRenderColour;
    const int frame = playback.frame();
    RETURN_IF_ERROR(view->Render(data.frames[frame].frame_index, camera, &out));
    RETURN_IF_ERROR(renderer->ReleaseCurrent());
    render_seconds += Seconds(Clock::now() - now);
    if (options.hud) {
      DrawTimeline(playback.fraction(), &out.colour);
      DrawStatusLine(
          absl::StrFormat("%s  instant %d/%d  %.2gx%s%s  %.0f fps%s", data.info.method, frame + 1,
                          playback.frame_count(), playback.speed(), playback.loop() ? "  loop" : "",
                          playback.playing() ? "" : "  paused", fps_shown,
                          view->appearance_note().empty() ? "" : "  static atlas (no video)"),
          0, &out.colour);
    }
    RETURN_IF_ERROR(window->Show(out.colour));
    ++summary.frames_shown;
    if (!HandleInput(window->Poll(), options.width, options.height, &orbit, &playback,
                     &scrubbing)) {
      break;
    }
    if (options.run_seconds > 0 && Seconds(Clock::now() - start) >= options.run_seconds) break;
  }
  summary.seconds = Seconds(Clock::now() - start);
  summary.fps = summary.seconds > 0 ? summary.frames_shown / summary.seconds : 0.0;
  summary.render_ms_mean =
      summary.frames_shown > 0 ? 1000.0 * render_seconds / summary.frames_shown : 0.0;
  return summary;
}

}  // namespace reenact::viewer
