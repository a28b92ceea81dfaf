// The interactive modes of reenact-viewer, in a window (render::ImageWindow)
// with the reenactment drawn by view::ReenactmentRenderer:
//
//  * Orbit: the teacher in an empty scene. Left drag orbits about the actor,
//    the wheel zooms; space plays or pauses, left/right step one instant,
//    up/down double or halve the speed, L toggles looping, R resets the
//    camera, Home/End jump to the ends, a click or drag on the timeline at
//    the bottom scrubs; Esc or Q quits.
#pragma once

#include <string>

#include "absl/status/statusor.h"
#include "clients/view/reenactment_renderer.h"
#include "common/model/reenactment.h"

namespace reenact::viewer {

struct WindowOptions {
  int width = 1280;  // Pixels of the drawn image (and the window).
  int height = 720;
  view::TextureMode mode = view::TextureMode::kVdtm;
  // Multisampling (0, 2, 4, 8). Off by default: on a software renderer 4x
  // costs about five times the frame.
  int msaa_samples = 0;
  double speed = 1.0;
  bool loop = true;
  // Quit after this many seconds (0: when the user quits), e.g. for a
  // measured run under `xvfb-run`.
  double run_seconds = 0.0;
  // Draw the timeline and the status line over the image.
  bool hud = true;
};

// What a window session did.
struct WindowSummary {
  int frames_shown = 0;
  double seconds = 0.0;
  // Shown frames per second over the session, and the part of each frame
  // spent drawing the reenactment (render + read back), milliseconds.
  double fps = 0.0;
  double render_ms_mean = 0.0;
};

// Runs orbit mode until the user quits (or options.run_seconds pass).
// Unavailable without a display or GL; InvalidArgument for bad options.
absl::StatusOr<WindowSummary> RunOrbitWindow(const Reenactment& data, const WindowOptions& options);

}  // namespace reenact::viewer
