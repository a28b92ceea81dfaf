// A desktop window (GLFW) that shows images drawn elsewhere, e.g. by
// OffscreenRenderer, and reports the user's input. The window's own OpenGL
// context only puts the image on the screen (scaled to the window, keeping
// its aspect), so the apps draw the same way with or without a display.
//
// Threads: create, show and poll from the main thread (GLFW's rule). A
// thread that also uses an OffscreenRenderer must release that renderer's
// context before Show (OffscreenRenderer::ReleaseCurrent); Show leaves no
// context current.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "common/base/image.h"

namespace reenact::render {

// Keys the apps use; letters and digits are reported as their upper-case
// ASCII code ('A', '1').
enum WindowKey : int {
  kKeySpace = ' ',
  kKeyEscape = 256,
  kKeyLeft,
  kKeyRight,
  kKeyUp,
  kKeyDown,
  kKeyHome,
  kKeyEnd,
  kKeyPageUp,
  kKeyPageDown,
};

// Input since the previous Poll.
struct WindowInput {
  std::vector<int> keys_pressed;  // WindowKey or ASCII, in order.
  // Left-button drag: pointer motion while the button is held, image pixels.
  double drag_dx_px = 0.0;
  double drag_dy_px = 0.0;
  bool button_down = false;
  // Where the left button went down this time, image pixels (x, y); negative
  // when it did not.
  double press_x_px = -1.0;
  double press_y_px = -1.0;
  // Pointer position now, image pixels.
  double pointer_x_px = 0.0;
  double pointer_y_px = 0.0;
  // Scroll wheel steps (positive: away from the user).
  double scroll = 0.0;
  bool close_requested = false;  // Window closed by the user.
};

class ImageWindow {
 public:
  // Opens a window of width x height pixels. Unavailable when there is no
  // display (no X server or Wayland compositor: run under `xvfb-run -a` for
  // tests) or no OpenGL for it; InvalidArgument for a bad size.
  static absl::StatusOr<std::unique_ptr<ImageWindow>> Open(const std::string& title, int width,
                                                           int height);
  ~ImageWindow();
  ImageWindow(const ImageWindow&) = delete;
  ImageWindow& operator=(const ImageWindow&) = delete;

  // Puts `image` (sRGB, top row first) on the screen and swaps buffers.
  // Pointer positions of later input are in this image's pixels.
  absl::Status Show(const RgbImage& image);
  // Processes pending events and returns the input since the last call.
  WindowInput Poll();
  void SetTitle(const std::string& title);

  struct Impl;  // The GLFW window and input state (image_window.cc).

 private:
  explicit ImageWindow(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace reenact::render
