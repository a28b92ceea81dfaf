#include "common/render/image_window.h"

#include <GLFW/glfw3.h>

#include <algorithm>
#include <mutex>

#include "absl/strings/str_cat.h"

namespace reenact::render {
namespace {

std::mutex& GlfwMutex() {
  static std::mutex mutex;
  return mutex;
}
int glfw_users = 0;  // Guarded by GlfwMutex(): windows open, to terminate GLFW.
std::string last_glfw_error;

void OnGlfwError(int code, const char* description) {
  last_glfw_error = absl::StrCat(description, " (GLFW error ", code, ")");
}

int TranslateKey(int key) {
  switch (key) {
    case GLFW_KEY_ESCAPE:
      return kKeyEscape;
    case GLFW_KEY_LEFT:
      return kKeyLeft;
    case GLFW_KEY_RIGHT:
      return kKeyRight;
    case GLFW_KEY_UP:
      return kKeyUp;
    case GLFW_KEY_DOWN:
      return kKeyDown;
    case GLFW_KEY_HOME:
      return kKeyHome;
    case GLFW_KEY_END:
      return kKeyEnd;
    case GLFW_KEY_PAGE_UP:
      return kKeyPageUp;
    case GLFW_KEY_PAGE_DOWN:
      return kKeyPageDown;
    default:
      break;
  }
  if (key == GLFW_KEY_SPACE || (key >= GLFW_KEY_0 && key <= GLFW_KEY_9) ||
      (key >= GLFW_KEY_A && key <= GLFW_KEY_Z)) {
    return key;  // GLFW's codes are the ASCII codes here.
  }
  return -1;
}

}  // namespace

struct ImageWindow::Impl {
  GLFWwindow* window = nullptr;
  GLuint texture = 0;
  WindowInput input;
  // Where the last image went in the framebuffer: x0, y0 (top-left, pixels)
  // and framebuffer pixels per image pixel; and the window-to-framebuffer
  // scale (HiDPI).
  double x0 = 0, y0 = 0, scale = 1, fb_per_window = 1;
  bool has_image = false;
  double last_x = 0, last_y = 0;

  void ToImage(double window_x, double window_y, double* x, double* y) const {
    *x = (window_x * fb_per_window - x0) / scale;
    *y = (window_y * fb_per_window - y0) / scale;
  }
};

namespace {

ImageWindow::Impl* ImplOf(GLFWwindow* window) {
  return static_cast<ImageWindow::Impl*>(glfwGetWindowUserPointer(window));
}

void OnKey(GLFWwindow* window, int key, int, int action, int) {
  if (action != GLFW_PRESS && action != GLFW_REPEAT) return;
  if (const int k = TranslateKey(key); k >= 0) ImplOf(window)->input.keys_pressed.push_back(k);
}

void OnButton(GLFWwindow* window, int button, int action, int) {
  if (button != GLFW_MOUSE_BUTTON_LEFT) return;
  ImageWindow::Impl* impl = ImplOf(window);
  impl->input.button_down = action == GLFW_PRESS;
  if (action == GLFW_PRESS) {
    double wx = 0, wy = 0;
    glfwGetCursorPos(window, &wx, &wy);
    impl->ToImage(wx, wy, &impl->input.press_x_px, &impl->input.press_y_px);
  }
}

void OnCursor(GLFWwindow* window, double wx, double wy) {
  ImageWindow::Impl* impl = ImplOf(window);
  double x = 0, y = 0;
  impl->ToImage(wx, wy, &x, &y);
  if (impl->input.button_down) {
    impl->input.drag_dx_px += x - impl->last_x;
    impl->input.drag_dy_px += y - impl->last_y;
  }
  impl->last_x = x;
  impl->last_y = y;
}

void OnScroll(GLFWwindow* window, double, double dy) { ImplOf(window)->input.scroll += dy; }

}  // namespace

absl::StatusOr<std::unique_ptr<ImageWindow>> ImageWindow::Open(const std::string& title, int width,
                                                               int height) {
  if (width < 16 || height < 16 || width > 8192 || height > 8192) {
    return absl::InvalidArgumentError("window size must be 16..8192 pixels");
  }
  std::lock_guard<std::mutex> lock(GlfwMutex());
  glfwSetErrorCallback(OnGlfwError);
  if (glfw_users == 0 && glfwInit() != GLFW_TRUE) {
    return absl::UnavailableError(absl::StrCat(
        "no display for a window: ", last_glfw_error,
        " (set DISPLAY, or run under `xvfb-run -a`, or render headless with --render-to)"));
  }
  glfwDefaultWindowHints();
  glfwWindowHint(GLFW_CONTEXT_VERSION_MAJOR, 2);
  glfwWindowHint(GLFW_CONTEXT_VERSION_MINOR, 1);
  GLFWwindow* window = glfwCreateWindow(width, height, title.c_str(), nullptr, nullptr);
  if (window == nullptr) {
    if (glfw_users == 0) glfwTerminate();
    return absl::UnavailableError(absl::StrCat("cannot open a window: ", last_glfw_error));
  }
  ++glfw_users;
  auto impl = std::make_unique<Impl>();
  impl->window = window;
  glfwSetWindowUserPointer(window, impl.get());
  glfwSetKeyCallback(window, OnKey);
  glfwSetMouseButtonCallback(window, OnButton);
  glfwSetCursorPosCallback(window, OnCursor);
  glfwSetScrollCallback(window, OnScroll);
  glfwMakeContextCurrent(window);
  glfwSwapInterval(0);  // The apps pace themselves.
  glGenTextures(1, &impl->texture);
  glfwMakeContextCurrent(nullptr);
  return std::unique_ptr<ImageWindow>(new ImageWindow(std::move(impl)));
}

ImageWindow::ImageWindow(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}

ImageWindow::~ImageWindow() {
  std::lock_guard<std::mutex> lock(GlfwMutex());
  glfwMakeContextCurrent(impl_->window);
  glDeleteTextures(1, &impl_->texture);
  glfwMakeContextCurrent(nullptr);
  glfwDestroyWindow(impl_->window);
  if (--glfw_users == 0) glfwTerminate();
}

absl::Status ImageWindow::Show(const RgbImage& image) {
  if (image.empty() || image.data.size() != image.num_pixels() * 3) {
    return absl::InvalidArgumentError("ImageWindow::Show: empty or malformed image");
  }
  Impl& impl = *impl_;
  glfwMakeContextCurrent(impl.window);
  int fb_w = 0, fb_h = 0, win_w = 0, win_h = 0;
  glfwGetFramebufferSize(impl.window, &fb_w, &fb_h);
  glfwGetWindowSize(impl.window, &win_w, &win_h);
  impl.fb_per_window = win_w > 0 ? static_cast<double>(fb_w) / win_w : 1.0;
  impl.scale =
      std::min(static_cast<double>(fb_w) / image.width, static_cast<double>(fb_h) / image.height);
  const double w = image.width * impl.scale, h = image.height * impl.scale;
  impl.x0 = 0.5 * (fb_w - w);
  impl.y0 = 0.5 * (fb_h - h);
  glViewport(0, 0, fb_w, fb_h);
  glClearColor(0, 0, 0, 1);
  glClear(GL_COLOR_BUFFER_BIT);
  glBindTexture(GL_TEXTURE_2D, impl.texture);
  glPixelStorei(GL_UNPACK_ALIGNMENT, 1);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_LINEAR);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);
  glTexImage2D(GL_TEXTURE_2D, 0, GL_RGB, image.width, image.height, 0, GL_RGB, GL_UNSIGNED_BYTE,
               image.data.data());
  glEnable(GL_TEXTURE_2D);
  // Normalised device coordinates of the image's corners; texture row 0 is
  // the image's top row.
  const double left = -1 + 2 * impl.x0 / fb_w, right = left + 2 * w / fb_w;
  const double top = 1 - 2 * impl.y0 / fb_h, bottom = top - 2 * h / fb_h;
  glBegin(GL_QUADS);
  glTexCoord2d(0, 0);
  glVertex2d(left, top);
  glTexCoord2d(1, 0);
  glVertex2d(right, top);
  glTexCoord2d(1, 1);
  glVertex2d(right, bottom);
  glTexCoord2d(0, 1);
  glVertex2d(left, bottom);
  glEnd();
  glDisable(GL_TEXTURE_2D);
  const GLenum error = glGetError();
  glfwSwapBuffers(impl.window);
  glfwMakeContextCurrent(nullptr);
  if (error != GL_NO_ERROR) {
    return absl::InternalError(absl::StrCat("OpenGL error ", error, " showing an image"));
  }
  impl.has_image = true;
  return absl::OkStatus();
}

WindowInput ImageWindow::Poll() {
  glfwPollEvents();
  Impl& impl = *impl_;
  WindowInput input = impl.input;
  input.pointer_x_px = impl.last_x;
  input.pointer_y_px = impl.last_y;
  input.close_requested = glfwWindowShouldClose(impl.window) == GLFW_TRUE;
  // Start the next interval: keep the button state, clear the rest.
  impl.input = WindowInput();
  impl.input.button_down = input.button_down;
  return input;
}

void ImageWindow::SetTitle(const std::string& title) {
  glfwSetWindowTitle(impl_->window, title.c_str());
}

}  // namespace reenact::render
