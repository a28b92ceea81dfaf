#include "common/render/offscreen_renderer.h"

#include <EGL/egl.h>
#include <EGL/eglext.h>

#define GL_GLEXT_PROTOTYPES 1
#include <GL/glcorearb.h>

#include <array>
#include <cmath>
#include <cstring>
#include <map>
#include <mutex>
#include <utility>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "absl/strings/str_split.h"
#include "absl/strings/string_view.h"
#include "common/base/status_macros.h"
#include "common/render/gl_shaders.h"

namespace reenact::render {
namespace {

constexpr int kNumColourAttachments = 4;  // Colour, depth_m, label, normals.
constexpr std::array<uint32_t, kNumColourAttachments> kAttachmentOutput = {
    kRenderColour, kRenderDepth, kRenderLabel, kRenderNormals};

std::string EglErrorText() { return absl::StrFormat("EGL error 0x%04x", eglGetError()); }

bool HasExtension(const char* extensions, absl::string_view name) {
  if (extensions == nullptr) return false;
  for (absl::string_view e : absl::StrSplit(extensions, ' ')) {
    if (e == name) return true;
  }
  return false;
}

// EGL displays are per-process singletons and eglTerminate ends every context
// on one, so renderers count their users and the last one terminates.
std::mutex& DisplayMutex() {
  static std::mutex mutex;
  return mutex;
}
std::map<EGLDisplay, int>& DisplayUsers() {
  static std::map<EGLDisplay, int> users;
  return users;
}

bool InitializeDisplay(EGLDisplay display) {
  if (display == EGL_NO_DISPLAY) return false;
  std::lock_guard lock(DisplayMutex());
  EGLint major = 0, minor = 0;
  if (eglInitialize(display, &major, &minor) != EGL_TRUE) return false;
  ++DisplayUsers()[display];
  return true;
}

void ReleaseDisplay(EGLDisplay display) {
  std::lock_guard lock(DisplayMutex());
  if (--DisplayUsers()[display] == 0) {
    DisplayUsers().erase(display);
    eglTerminate(display);
  }
}

// Tries Mesa's surfaceless platform, then the first EGL device (headless
// NVIDIA), then the default display.
absl::StatusOr<EGLDisplay> OpenDisplay() {
  const char* client_extensions = eglQueryString(EGL_NO_DISPLAY, EGL_EXTENSIONS);
  auto get_platform_display = reinterpret_cast<PFNEGLGETPLATFORMDISPLAYEXTPROC>(
      eglGetProcAddress("eglGetPlatformDisplayEXT"));
  std::string tried;
  if (get_platform_display != nullptr &&
      HasExtension(client_extensions, "EGL_MESA_platform_surfaceless")) {
    EGLDisplay display =
        get_platform_display(EGL_PLATFORM_SURFACELESS_MESA, EGL_DEFAULT_DISPLAY, nullptr);
    if (InitializeDisplay(display)) return display;
    absl::StrAppend(&tried, " surfaceless: ", EglErrorText(), ";");
  }
  auto query_devices =
      reinterpret_cast<PFNEGLQUERYDEVICESEXTPROC>(eglGetProcAddress("eglQueryDevicesEXT"));
  if (get_platform_display != nullptr && query_devices != nullptr &&
      HasExtension(client_extensions, "EGL_EXT_platform_device")) {
    EGLDeviceEXT device = nullptr;
    EGLint num_devices = 0;
    if (query_devices(1, &device, &num_devices) == EGL_TRUE && num_devices > 0) {
      EGLDisplay display = get_platform_display(EGL_PLATFORM_DEVICE_EXT, device, nullptr);
      if (InitializeDisplay(display)) return display;
    }
    absl::StrAppend(&tried, " device: ", EglErrorText(), ";");
  }
  if (InitializeDisplay(eglGetDisplay(EGL_DEFAULT_DISPLAY)))
    return eglGetDisplay(EGL_DEFAULT_DISPLAY);
  absl::StrAppend(&tried, " default display: ", EglErrorText());
  return absl::UnavailableError(
      absl::StrCat("OffscreenRenderer: no EGL display could be initialised (", tried,
                   "); is an EGL driver (Mesa or a GPU vendor's) installed?"));
}

// An OpenGL 3.3 core context without a surface on `display`.
absl::StatusOr<EGLContext> CreateContext(EGLDisplay display) {
  if (!HasExtension(eglQueryString(display, EGL_EXTENSIONS), "EGL_KHR_surfaceless_context")) {
    return absl::UnavailableError("OffscreenRenderer: EGL lacks EGL_KHR_surfaceless_context");
  }
  if (eglBindAPI(EGL_OPENGL_API) != EGL_TRUE) {
    return absl::UnavailableError(
        absl::StrCat("OffscreenRenderer: EGL has no desktop OpenGL (", EglErrorText(), ")"));
  }
  const EGLint config_attributes[] = {EGL_RENDERABLE_TYPE, EGL_OPENGL_BIT, EGL_SURFACE_TYPE, 0,
                                      EGL_NONE};
  EGLConfig config = nullptr;
  EGLint num_configs = 0;
  if (eglChooseConfig(display, config_attributes, &config, 1, &num_configs) != EGL_TRUE ||
      num_configs == 0) {
    config = EGL_NO_CONFIG_KHR;  // Needs EGL_KHR_no_config_context; checked by the create.
  }
  const EGLint context_attributes[] = {EGL_CONTEXT_MAJOR_VERSION,
                                       3,
                                       EGL_CONTEXT_MINOR_VERSION,
                                       3,
                                       EGL_CONTEXT_OPENGL_PROFILE_MASK,
                                       EGL_CONTEXT_OPENGL_CORE_PROFILE_BIT,
                                       EGL_NONE};
  EGLContext context = eglCreateContext(display, config, EGL_NO_CONTEXT, context_attributes);
  if (context == EGL_NO_CONTEXT) {
    return absl::UnavailableError(absl::StrCat(
        "OffscreenRenderer: cannot create an OpenGL 3.3 core context (", EglErrorText(), ")"));
  }
  if (eglMakeCurrent(display, EGL_NO_SURFACE, EGL_NO_SURFACE, context) != EGL_TRUE) {
    const std::string error = EglErrorText();
    eglDestroyContext(display, context);
    return absl::UnavailableError(
        absl::StrCat("OffscreenRenderer: cannot make the context current (", error, ")"));
  }
  return context;
}

absl::Status CheckGl(absl::string_view what) {
  const GLenum error = glGetError();
  if (error == GL_NO_ERROR) return absl::OkStatus();
  while (glGetError() != GL_NO_ERROR) {
  }
  return absl::InternalError(
      absl::StrFormat("OffscreenRenderer: %s: GL error 0x%04x", what, error));
}

absl::StatusOr<GLuint> CompileShader(GLenum stage, const char* source) {
  GLuint shader = glCreateShader(stage);
  glShaderSource(shader, 1, &source, nullptr);
  glCompileShader(shader);
  GLint ok = GL_FALSE;
  glGetShaderiv(shader, GL_COMPILE_STATUS, &ok);
  if (ok == GL_TRUE) return shader;
  char log[2048] = {};
  glGetShaderInfoLog(shader, sizeof(log), nullptr, log);
  glDeleteShader(shader);
  return absl::InternalError(absl::StrCat("OffscreenRenderer: shader compile failed: ", log));
}

absl::StatusOr<GLuint> LinkProgram(const char* vertex_source, const char* fragment_source) {
  ASSIGN_OR_RETURN(GLuint vertex, CompileShader(GL_VERTEX_SHADER, vertex_source));
  auto fragment = CompileShader(GL_FRAGMENT_SHADER, fragment_source);
  if (!fragment.ok()) {
    glDeleteShader(vertex);
    return fragment.status();
  }
  GLuint program = glCreateProgram();
  glAttachShader(program, vertex);
  glAttachShader(program, *fragment);
  glLinkProgram(program);
  glDeleteShader(vertex);
  glDeleteShader(*fragment);
  GLint ok = GL_FALSE;
  glGetProgramiv(program, GL_LINK_STATUS, &ok);
  if (ok == GL_TRUE) return program;
  char log[2048] = {};
  glGetProgramInfoLog(program, sizeof(log), nullptr, log);
  glDeleteProgram(program);
  return absl::InternalError(absl::StrCat("OffscreenRenderer: shader link failed: ", log));
}

float SrgbToLinear(float c) {
  return c <= 0.04045f ? c / 12.92f : std::pow((c + 0.055f) / 1.055f, 2.4f);
}

// Column-major float copy of a double matrix, as glUniformMatrix4fv takes it.
std::array<float, 16> ToGl(const Eigen::Matrix4d& m) {
  std::array<float, 16> out;
  Eigen::Map<Eigen::Matrix4f>(out.data()) = m.cast<float>();
  return out;
}

// The framebuffer objects of one sample count.
struct Framebuffer {
  GLuint fbo = 0;
  std::array<GLuint, kNumColourAttachments> colour{};
  GLuint depth = 0;

  absl::Status Allocate(int width, int height, int samples) {
    constexpr std::array<GLenum, kNumColourAttachments> kFormats = {GL_SRGB8_ALPHA8, GL_R32F,
                                                                    GL_R8UI, GL_RGBA32F};
    glGenFramebuffers(1, &fbo);
    glBindFramebuffer(GL_FRAMEBUFFER, fbo);
    glGenRenderbuffers(kNumColourAttachments, colour.data());
    glGenRenderbuffers(1, &depth);
    for (int i = 0; i <= kNumColourAttachments; ++i) {
      const bool is_depth = i == kNumColourAttachments;
      glBindRenderbuffer(GL_RENDERBUFFER, is_depth ? depth : colour[i]);
      glRenderbufferStorageMultisample(
          GL_RENDERBUFFER, samples, is_depth ? GL_DEPTH_COMPONENT32F : kFormats[i], width, height);
      glFramebufferRenderbuffer(GL_FRAMEBUFFER,
                                is_depth ? GL_DEPTH_ATTACHMENT : GL_COLOR_ATTACHMENT0 + i,
                                GL_RENDERBUFFER, is_depth ? depth : colour[i]);
    }
    const GLenum status = glCheckFramebufferStatus(GL_FRAMEBUFFER);
    if (status != GL_FRAMEBUFFER_COMPLETE) {
      return absl::UnavailableError(
          absl::StrFormat("OffscreenRenderer: framebuffer of %dx%d, %d samples incomplete (0x%04x)",
                          width, height, samples, status));
    }
    return CheckGl("framebuffer allocation");
  }

  void Free() {
    glDeleteRenderbuffers(kNumColourAttachments, colour.data());
    glDeleteRenderbuffers(1, &depth);
    glDeleteFramebuffers(1, &fbo);
  }
};

// Uniform locations of the mesh program.
struct MeshProgram {
  GLuint program = 0;
  GLint clip_from_model, world_from_model, camera_z_from_model, mode, lit, has_normals, headlight,
      colour_linear, texture, camera_centre_world, direction_to_light_world, ambient, diffuse,
      label;

  void Locate() {
    auto at = [&](const char* name) { return glGetUniformLocation(program, name); };
    clip_from_model = at("u_clip_from_model");
    world_from_model = at("u_world_from_model");
    camera_z_from_model = at("u_camera_z_from_model");
    mode = at("u_mode");
    lit = at("u_lit");
    has_normals = at("u_has_normals");
    headlight = at("u_headlight");
    colour_linear = at("u_colour_linear");
    texture = at("u_texture");
    camera_centre_world = at("u_camera_centre_world");
    direction_to_light_world = at("u_direction_to_light_world");
    ambient = at("u_ambient");
    diffuse = at("u_diffuse");
    label = at("u_label");
  }
};

// Attribute locations of kMeshVertexShader.
enum Attribute : GLuint { kPosition = 0, kNormal = 1, kUv = 2, kColour = 3 };

struct MeshRecord {
  bool alive = false;
  GLuint vao = 0;
  std::array<GLuint, 4> vbo{};  // Indexed by Attribute; 0 when absent.
  GLuint index_buffer = 0;
  int num_vertices = 0;
  GLsizei num_indices = 0;
  // For UpdateMeshPositions: the remap to the original vertices (empty when
  // none) and the triangles in the original indexing.
  std::vector<int> source_vertex;
  int num_source_vertices = 0;
  std::vector<Eigen::Vector3i> source_triangles;
};

GLuint MakeBuffer(GLenum target, const void* data, size_t bytes, GLenum usage) {
  GLuint buffer = 0;
  glGenBuffers(1, &buffer);
  glBindBuffer(target, buffer);
  glBufferData(target, static_cast<GLsizeiptr>(bytes), data, usage);
  return buffer;
}

// Makes the buffer of a vertex attribute of kRows floats per vertex and binds
// it to `location` in the current vertex array; 0 when the mesh lacks it.
template <int kRows>
GLuint MakeAttribute(Attribute location, const Eigen::Matrix<float, kRows, Eigen::Dynamic>& values,
                     GLenum usage) {
  if (values.cols() == 0) {
    glDisableVertexAttribArray(location);  // The shader does not read it.
    return 0;
  }
  GLuint buffer = MakeBuffer(GL_ARRAY_BUFFER, values.data(), values.size() * sizeof(float), usage);
  glEnableVertexAttribArray(location);
  glVertexAttribPointer(location, kRows, GL_FLOAT, GL_FALSE, 0, nullptr);
  return buffer;
}

}  // namespace

struct OffscreenRenderer::Impl {
  RendererOptions options;
  EGLDisplay display = EGL_NO_DISPLAY;
  EGLContext context = EGL_NO_CONTEXT;
  std::string description;
  Framebuffer resolved;     // Single-sample; read back from.
  Framebuffer multisample;  // Drawn into when msaa_samples > 0.
  MeshProgram program;
  std::vector<MeshRecord> meshes;
  std::vector<GLuint> textures;  // 0 once released.
  ShadingOptions shading;

  ~Impl();
  absl::Status MakeCurrent();
  absl::Status InitGl();
  absl::StatusOr<MeshRecord*> FindMesh(MeshId id);
  absl::StatusOr<TextureId> UploadTexture(int width, int height, int channels,
                                          const std::vector<uint8_t>& data);
  absl::Status CheckItems(const std::vector<DrawItem>& items);
  void SetFrameUniforms(const RenderCamera& camera);
  void DrawItems(const RenderCamera& camera, const std::vector<DrawItem>& items);
  void DrawOne(const Eigen::Matrix4d& camera_from_world, const Eigen::Matrix4d& clip_from_world,
               const DrawItem& item);
  void Resolve(int width, int height, uint32_t requested);
  void ReadBack(int width, int height, RenderOutputs* out);
};

OffscreenRenderer::Impl::~Impl() {
  if (context == EGL_NO_CONTEXT) return;
  if (MakeCurrent().ok()) {
    for (MeshRecord& mesh : meshes) {
      if (!mesh.alive) continue;
      glDeleteBuffers(static_cast<GLsizei>(mesh.vbo.size()), mesh.vbo.data());
      glDeleteBuffers(1, &mesh.index_buffer);
      glDeleteVertexArrays(1, &mesh.vao);
    }
    glDeleteTextures(static_cast<GLsizei>(textures.size()), textures.data());
    glDeleteProgram(program.program);
    resolved.Free();
    if (options.msaa_samples > 0) multisample.Free();
  }
  eglMakeCurrent(display, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
  eglDestroyContext(display, context);
  ReleaseDisplay(display);
}

absl::Status OffscreenRenderer::Impl::MakeCurrent() {
  if (eglGetCurrentContext() == context) return absl::OkStatus();
  eglBindAPI(EGL_OPENGL_API);
  if (eglMakeCurrent(display, EGL_NO_SURFACE, EGL_NO_SURFACE, context) != EGL_TRUE) {
    return absl::FailedPreconditionError(
        absl::StrCat("OffscreenRenderer: cannot make the context current on this thread (",
                     EglErrorText(), "); call ReleaseCurrent() on the thread that used it"));
  }
  return absl::OkStatus();
}

absl::Status OffscreenRenderer::Impl::InitGl() {
  GLint major = 0, minor = 0;
  glGetIntegerv(GL_MAJOR_VERSION, &major);
  glGetIntegerv(GL_MINOR_VERSION, &minor);
  if (major * 10 + minor < 33) {
    return absl::UnavailableError(
        absl::StrCat("OffscreenRenderer: OpenGL ", major, ".", minor, " is older than 3.3"));
  }
  description = absl::StrCat(reinterpret_cast<const char*>(glGetString(GL_VERSION)), " | ",
                             reinterpret_cast<const char*>(glGetString(GL_RENDERER)));
  ASSIGN_OR_RETURN(program.program,
                   LinkProgram(internal::kMeshVertexShader, internal::kMeshFragmentShader));
  program.Locate();
  RETURN_IF_ERROR(resolved.Allocate(options.max_width, options.max_height, 0));
  if (options.msaa_samples > 0) {
    RETURN_IF_ERROR(
        multisample.Allocate(options.max_width, options.max_height, options.msaa_samples));
  }
  glPixelStorei(GL_PACK_ALIGNMENT, 1);
  glPixelStorei(GL_UNPACK_ALIGNMENT, 1);
  glEnable(GL_DEPTH_TEST);
  glDepthFunc(GL_LESS);
  glDisable(GL_CULL_FACE);
  glDisable(GL_BLEND);
  glEnable(GL_SCISSOR_TEST);
  glFrontFace(GL_CW);  // ClipFromCamera mirrors y: outside faces are clockwise.
  return CheckGl("initialisation");
}

absl::StatusOr<MeshRecord*> OffscreenRenderer::Impl::FindMesh(MeshId id) {
  if (id.value < 0 || id.value >= static_cast<int>(meshes.size()) || !meshes[id.value].alive) {
    return absl::NotFoundError(absl::StrCat("OffscreenRenderer: unknown mesh id ", id.value));
  }
  return &meshes[id.value];
}

absl::Status OffscreenRenderer::Impl::CheckItems(const std::vector<DrawItem>& items) {
  for (const DrawItem& item : items) {
    auto mesh = FindMesh(item.mesh);
    if (!mesh.ok()) return absl::InvalidArgumentError(mesh.status().message());
    if (item.texture.valid()) {
      if (item.texture.value >= static_cast<int>(textures.size()) ||
          textures[item.texture.value] == 0) {
        return absl::InvalidArgumentError(
            absl::StrCat("OffscreenRenderer: unknown texture id ", item.texture.value));
      }
      if ((*mesh)->vbo[kUv] == 0) {
        return absl::InvalidArgumentError(
            absl::StrCat("OffscreenRenderer: mesh ", item.mesh.value, " has a texture but no uvs"));
      }
    }
    if (item.label < 0 || item.label > 255) {
      return absl::InvalidArgumentError(
          absl::StrCat("OffscreenRenderer: label ", item.label, " outside [0, 255]"));
    }
    if (!(item.blend_weight > 0.0f && item.blend_weight <= 1.0f)) {
      return absl::InvalidArgumentError(
          absl::StrCat("OffscreenRenderer: blend_weight ", item.blend_weight, " outside (0, 1]"));
    }
    if (!item.world_from_model.matrix().allFinite()) {
      return absl::InvalidArgumentError("OffscreenRenderer: world_from_model is not finite");
    }
  }
  return absl::OkStatus();
}

void OffscreenRenderer::Impl::SetFrameUniforms(const RenderCamera& camera) {
  glUseProgram(program.program);
  const Eigen::Vector3d centre = camera.world_from_camera.translation();
  const Eigen::Vector3d light = shading.direction_to_light_in_world.normalized();
  glUniform3f(program.camera_centre_world, static_cast<float>(centre.x()),
              static_cast<float>(centre.y()), static_cast<float>(centre.z()));
  glUniform3f(program.direction_to_light_world, static_cast<float>(light.x()),
              static_cast<float>(light.y()), static_cast<float>(light.z()));
  glUniform1i(program.headlight, shading.headlight ? 1 : 0);
  glUniform1f(program.ambient, shading.ambient);
  glUniform1f(program.diffuse, shading.diffuse);
  glUniform1i(program.texture, 0);
}

void OffscreenRenderer::Impl::DrawItems(const RenderCamera& camera,
                                        const std::vector<DrawItem>& items) {
  SetFrameUniforms(camera);
  const Eigen::Matrix4d camera_from_world = camera.world_from_camera.inverse().matrix();
  const Eigen::Matrix4d clip_from_world = ClipFromCamera(camera) * camera_from_world;
  glActiveTexture(GL_TEXTURE0);
  // Opaque items first, then the blended ones over them (colour only, where
  // their depth equals what is drawn: the same triangles again).
  bool blending = false;
  for (int pass = 0; pass < 2; ++pass) {
    for (const DrawItem& item : items) {
      if ((item.blend_weight < 1.0f) != (pass == 1)) continue;
      if (pass == 1 && !blending) {
        blending = true;
        glDepthFunc(GL_EQUAL);
        glDepthMask(GL_FALSE);
        for (int i = 1; i < kNumColourAttachments; ++i) {
          glColorMaski(i, GL_FALSE, GL_FALSE, GL_FALSE, GL_FALSE);
        }
        glEnablei(GL_BLEND, 0);
        glBlendFunci(0, GL_CONSTANT_ALPHA, GL_ONE_MINUS_CONSTANT_ALPHA);
      }
      if (pass == 1) glBlendColor(0.0f, 0.0f, 0.0f, item.blend_weight);
      DrawOne(camera_from_world, clip_from_world, item);
    }
  }
  if (blending) {
    glDisablei(GL_BLEND, 0);
    for (int i = 1; i < kNumColourAttachments; ++i) {
      glColorMaski(i, GL_TRUE, GL_TRUE, GL_TRUE, GL_TRUE);
    }
    glDepthMask(GL_TRUE);
    glDepthFunc(GL_LESS);
  }
  glBindVertexArray(0);
}

void OffscreenRenderer::Impl::DrawOne(const Eigen::Matrix4d& camera_from_world,
                                      const Eigen::Matrix4d& clip_from_world,
                                      const DrawItem& item) {
  {
    const MeshRecord& mesh = meshes[item.mesh.value];
    const Eigen::Matrix4d& world_from_model = item.world_from_model.matrix();
    const Eigen::Vector4d camera_z_from_model =
        (camera_from_world * world_from_model).row(2).transpose();
    glUniformMatrix4fv(program.clip_from_model, 1, GL_FALSE,
                       ToGl(clip_from_world * world_from_model).data());
    glUniformMatrix4fv(program.world_from_model, 1, GL_FALSE, ToGl(world_from_model).data());
    glUniform4f(program.camera_z_from_model, static_cast<float>(camera_z_from_model[0]),
                static_cast<float>(camera_z_from_model[1]),
                static_cast<float>(camera_z_from_model[2]),
                static_cast<float>(camera_z_from_model[3]));
    const int mode = item.texture.valid() ? 2 : (mesh.vbo[kColour] != 0 ? 1 : 0);
    glUniform1i(program.mode, mode);
    glUniform1i(program.lit, item.lit ? 1 : 0);
    glUniform1i(program.has_normals, mesh.vbo[kNormal] != 0 ? 1 : 0);
    glUniform3f(program.colour_linear, SrgbToLinear(item.colour_srgb.x()),
                SrgbToLinear(item.colour_srgb.y()), SrgbToLinear(item.colour_srgb.z()));
    glUniform1ui(program.label, static_cast<GLuint>(item.label));
    glBindTexture(GL_TEXTURE_2D, mode == 2 ? textures[item.texture.value] : 0);
    if (item.underlay) {
      glEnable(GL_POLYGON_OFFSET_FILL);
      glPolygonOffset(1.0f, 4.0f);
    }
    if (item.cull_back_faces) glEnable(GL_CULL_FACE);
    glBindVertexArray(mesh.vao);
    glDrawElements(GL_TRIANGLES, mesh.num_indices, GL_UNSIGNED_INT, nullptr);
    if (item.underlay) glDisable(GL_POLYGON_OFFSET_FILL);
    if (item.cull_back_faces) glDisable(GL_CULL_FACE);
  }
}

void OffscreenRenderer::Impl::Resolve(int width, int height, uint32_t requested) {
  glBindFramebuffer(GL_READ_FRAMEBUFFER, multisample.fbo);
  glBindFramebuffer(GL_DRAW_FRAMEBUFFER, resolved.fbo);
  for (int i = 0; i < kNumColourAttachments; ++i) {
    if ((requested & kAttachmentOutput[i]) == 0) continue;
    std::array<GLenum, kNumColourAttachments> buffers;
    buffers.fill(GL_NONE);
    buffers[i] = GL_COLOR_ATTACHMENT0 + i;
    glReadBuffer(GL_COLOR_ATTACHMENT0 + i);
    glDrawBuffers(kNumColourAttachments, buffers.data());
    glBlitFramebuffer(0, 0, width, height, 0, 0, width, height, GL_COLOR_BUFFER_BIT, GL_NEAREST);
  }
}

void OffscreenRenderer::Impl::ReadBack(int width, int height, RenderOutputs* out) {
  glBindFramebuffer(GL_READ_FRAMEBUFFER, resolved.fbo);
  auto read = [&](int attachment, GLenum format, GLenum type, void* data) {
    glReadBuffer(GL_COLOR_ATTACHMENT0 + attachment);
    glReadPixels(0, 0, width, height, format, type, data);
  };
  if (out->requested & kRenderColour) {
    out->colour = RgbImage(width, height);
    read(0, GL_RGB, GL_UNSIGNED_BYTE, out->colour.data.data());
  }
  if (out->requested & kRenderDepth) {
    out->depth_m = FloatImage(width, height);
    read(1, GL_RED, GL_FLOAT, out->depth_m.data.data());
  }
  if (out->requested & kRenderLabel) {
    out->label = MaskImage(width, height);
    read(2, GL_RED_INTEGER, GL_UNSIGNED_BYTE, out->label.data.data());
  }
  if (out->requested & kRenderNormals) {
    out->normals_in_world = Vec3Image(width, height);
    read(3, GL_RGB, GL_FLOAT, out->normals_in_world.data.data());
  }
}

OffscreenRenderer::OffscreenRenderer(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}

OffscreenRenderer::~OffscreenRenderer() = default;

absl::StatusOr<std::unique_ptr<OffscreenRenderer>> OffscreenRenderer::Create(
    const RendererOptions& options) {
  RETURN_IF_ERROR(options.Validate());
  auto impl = std::make_unique<Impl>();
  impl->options = options;
  ASSIGN_OR_RETURN(impl->display, OpenDisplay());
  auto context = CreateContext(impl->display);
  if (!context.ok()) {
    ReleaseDisplay(impl->display);
    return context.status();
  }
  impl->context = *context;  // From here ~Impl releases the context and display.
  RETURN_IF_ERROR(impl->InitGl());
  return std::unique_ptr<OffscreenRenderer>(new OffscreenRenderer(std::move(impl)));
}

absl::Status OffscreenRenderer::MakeCurrent() { return impl_->MakeCurrent(); }

absl::Status OffscreenRenderer::ReleaseCurrent() {
  if (eglGetCurrentContext() != impl_->context) return absl::OkStatus();
  if (eglMakeCurrent(impl_->display, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT) != EGL_TRUE) {
    return absl::InternalError(
        absl::StrCat("OffscreenRenderer: cannot release the context (", EglErrorText(), ")"));
  }
  return absl::OkStatus();
}

absl::StatusOr<MeshId> OffscreenRenderer::UploadMesh(const MeshData& mesh) {
  RETURN_IF_ERROR(ValidateMeshData(mesh));
  RETURN_IF_ERROR(impl_->MakeCurrent());
  MeshRecord record;
  record.alive = true;
  record.num_vertices = mesh.num_vertices();
  record.num_indices = static_cast<GLsizei>(mesh.triangles.size() * 3);
  record.source_vertex = mesh.source_vertex;
  record.num_source_vertices = mesh.num_source_vertices;
  record.source_triangles = mesh.triangles;
  for (Eigen::Vector3i& t : record.source_triangles) {
    if (!record.source_vertex.empty()) {
      t = Eigen::Vector3i(record.source_vertex[t[0]], record.source_vertex[t[1]],
                          record.source_vertex[t[2]]);
    }
  }
  glGenVertexArrays(1, &record.vao);
  glBindVertexArray(record.vao);
  record.vbo[kPosition] = MakeAttribute<3>(kPosition, mesh.positions_m, GL_DYNAMIC_DRAW);
  record.vbo[kNormal] = MakeAttribute<3>(kNormal, mesh.normals, GL_DYNAMIC_DRAW);
  record.vbo[kUv] = MakeAttribute<2>(kUv, mesh.uvs, GL_STATIC_DRAW);
  record.vbo[kColour] = MakeAttribute<3>(kColour, mesh.colours_srgb, GL_STATIC_DRAW);
  static_assert(sizeof(Eigen::Vector3i) == 3 * sizeof(GLuint));
  record.index_buffer = MakeBuffer(GL_ELEMENT_ARRAY_BUFFER, mesh.triangles.data(),
                                   mesh.triangles.size() * sizeof(Eigen::Vector3i), GL_STATIC_DRAW);
  glBindVertexArray(0);
  RETURN_IF_ERROR(CheckGl("UploadMesh"));
  // Reuse a freed slot, so that transient meshes do not grow the table.
  std::vector<MeshRecord>& meshes = impl_->meshes;
  for (size_t i = 0; i < meshes.size(); ++i) {
    if (meshes[i].alive) continue;
    meshes[i] = std::move(record);
    return MeshId{static_cast<int>(i)};
  }
  meshes.push_back(std::move(record));
  return MeshId{static_cast<int>(meshes.size()) - 1};
}

absl::Status OffscreenRenderer::UpdateMeshPositions(MeshId id, const Eigen::Matrix3Xf& positions_m,
                                                    const Eigen::Matrix3Xf& normals) {
  RETURN_IF_ERROR(impl_->MakeCurrent());
  ASSIGN_OR_RETURN(MeshRecord * mesh, impl_->FindMesh(id));
  const bool remapped = !mesh->source_vertex.empty();
  const int expected = remapped ? mesh->num_source_vertices : mesh->num_vertices;
  if (positions_m.cols() != expected || (normals.cols() != 0 && normals.cols() != expected)) {
    return absl::InvalidArgumentError(absl::StrCat("UpdateMeshPositions: got ", positions_m.cols(),
                                                   " positions and ", normals.cols(),
                                                   " normals, expected ", expected));
  }
  if (!positions_m.allFinite()) {
    return absl::InvalidArgumentError("UpdateMeshPositions: positions_m are not finite");
  }
  const bool has_normals = mesh->vbo[kNormal] != 0;
  Eigen::Matrix3Xf new_normals;
  if (has_normals) {
    new_normals =
        normals.cols() != 0 ? normals : ComputeVertexNormals(positions_m, mesh->source_triangles);
  }
  auto upload = [&](GLuint buffer, const Eigen::Matrix3Xf& source) {
    Eigen::Matrix3Xf expanded;
    if (remapped) {
      expanded.resize(3, mesh->num_vertices);
      for (int i = 0; i < mesh->num_vertices; ++i) {
        expanded.col(i) = source.col(mesh->source_vertex[i]);
      }
    }
    const Eigen::Matrix3Xf& values = remapped ? expanded : source;
    glBindBuffer(GL_ARRAY_BUFFER, buffer);
    glBufferSubData(GL_ARRAY_BUFFER, 0, static_cast<GLsizeiptr>(values.size() * sizeof(float)),
                    values.data());
  };
  upload(mesh->vbo[kPosition], positions_m);
  if (has_normals) upload(mesh->vbo[kNormal], new_normals);
  return CheckGl("UpdateMeshPositions");
}

absl::StatusOr<TextureId> OffscreenRenderer::UploadTexture(const RgbImage& image_srgb) {
  return impl_->UploadTexture(image_srgb.width, image_srgb.height, 3, image_srgb.data);
}

absl::StatusOr<TextureId> OffscreenRenderer::UploadTexture(const RgbaImage& image_srgb_alpha) {
  return impl_->UploadTexture(image_srgb_alpha.width, image_srgb_alpha.height, 4,
                              image_srgb_alpha.data);
}

absl::StatusOr<TextureId> OffscreenRenderer::Impl::UploadTexture(int width, int height,
                                                                 int channels,
                                                                 const std::vector<uint8_t>& data) {
  RETURN_IF_ERROR(MakeCurrent());
  GLint max_size = 0;
  glGetIntegerv(GL_MAX_TEXTURE_SIZE, &max_size);
  if (width <= 0 || height <= 0 || width > max_size || height > max_size ||
      data.size() != static_cast<size_t>(width) * height * channels) {
    return absl::InvalidArgumentError(absl::StrCat("UploadTexture: image of ", width, "x", height,
                                                   " is empty, inconsistent or larger than ",
                                                   max_size));
  }
  GLuint texture = 0;
  glGenTextures(1, &texture);
  glBindTexture(GL_TEXTURE_2D, texture);
  glTexImage2D(GL_TEXTURE_2D, 0, channels == 4 ? GL_SRGB8_ALPHA8 : GL_SRGB8, width, height, 0,
               channels == 4 ? GL_RGBA : GL_RGB, GL_UNSIGNED_BYTE, data.data());
  glGenerateMipmap(GL_TEXTURE_2D);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_LINEAR_MIPMAP_LINEAR);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);
  glBindTexture(GL_TEXTURE_2D, 0);
  if (auto status = CheckGl("UploadTexture"); !status.ok()) {
    glDeleteTextures(1, &texture);
    return status;
  }
  // Reuse a freed slot, so that uploading and releasing textures frame after
  // frame does not grow the table.
  for (size_t i = 0; i < textures.size(); ++i) {
    if (textures[i] != 0) continue;
    textures[i] = texture;
    return TextureId{static_cast<int>(i)};
  }
  textures.push_back(texture);
  return TextureId{static_cast<int>(textures.size()) - 1};
}

absl::Status OffscreenRenderer::ReleaseMesh(MeshId id) {
  RETURN_IF_ERROR(impl_->MakeCurrent());
  ASSIGN_OR_RETURN(MeshRecord * mesh, impl_->FindMesh(id));
  glDeleteBuffers(static_cast<GLsizei>(mesh->vbo.size()), mesh->vbo.data());
  glDeleteBuffers(1, &mesh->index_buffer);
  glDeleteVertexArrays(1, &mesh->vao);
  *mesh = MeshRecord();
  return CheckGl("ReleaseMesh");
}

absl::Status OffscreenRenderer::UpdateTexture(TextureId id, const RgbImage& image_srgb) {
  RETURN_IF_ERROR(impl_->MakeCurrent());
  if (id.value < 0 || id.value >= static_cast<int>(impl_->textures.size()) ||
      impl_->textures[id.value] == 0) {
    return absl::NotFoundError(absl::StrCat("UpdateTexture: unknown texture id ", id.value));
  }
  glBindTexture(GL_TEXTURE_2D, impl_->textures[id.value]);
  GLint width = 0;
  GLint height = 0;
  GLint format = 0;
  glGetTexLevelParameteriv(GL_TEXTURE_2D, 0, GL_TEXTURE_WIDTH, &width);
  glGetTexLevelParameteriv(GL_TEXTURE_2D, 0, GL_TEXTURE_HEIGHT, &height);
  glGetTexLevelParameteriv(GL_TEXTURE_2D, 0, GL_TEXTURE_INTERNAL_FORMAT, &format);
  if (width != image_srgb.width || height != image_srgb.height || format != GL_SRGB8 ||
      image_srgb.data.size() != static_cast<size_t>(width) * height * 3) {
    glBindTexture(GL_TEXTURE_2D, 0);
    return absl::InvalidArgumentError(absl::StrCat(
        "UpdateTexture: an opaque image of ", image_srgb.width, "x", image_srgb.height,
        " for a texture of ", width, "x", height, format == GL_SRGB8 ? "" : " with alpha"));
  }
  glPixelStorei(GL_UNPACK_ALIGNMENT, 1);
  glTexSubImage2D(GL_TEXTURE_2D, 0, 0, 0, width, height, GL_RGB, GL_UNSIGNED_BYTE,
                  image_srgb.data.data());
  glGenerateMipmap(GL_TEXTURE_2D);
  glBindTexture(GL_TEXTURE_2D, 0);
  return CheckGl("UpdateTexture");
}

absl::Status OffscreenRenderer::ReleaseTexture(TextureId id) {
  RETURN_IF_ERROR(impl_->MakeCurrent());
  if (id.value < 0 || id.value >= static_cast<int>(impl_->textures.size()) ||
      impl_->textures[id.value] == 0) {
    return absl::NotFoundError(absl::StrCat("ReleaseTexture: unknown texture id ", id.value));
  }
  glDeleteTextures(1, &impl_->textures[id.value]);
  impl_->textures[id.value] = 0;
  return CheckGl("ReleaseTexture");
}

absl::Status OffscreenRenderer::SetShading(const ShadingOptions& shading) {
  RETURN_IF_ERROR(shading.Validate());
  impl_->shading = shading;
  return absl::OkStatus();
}

absl::Status OffscreenRenderer::Render(const RenderCamera& camera,
                                       const std::vector<DrawItem>& items, RenderOutputs* out) {
  RETURN_IF_ERROR(camera.Validate());
  if (camera.width > impl_->options.max_width || camera.height > impl_->options.max_height) {
    return absl::InvalidArgumentError(absl::StrCat(
        "Render: camera of ", camera.width, "x", camera.height, " exceeds the framebuffer of ",
        impl_->options.max_width, "x", impl_->options.max_height));
  }
  RETURN_IF_ERROR(impl_->CheckItems(items));
  RETURN_IF_ERROR(impl_->MakeCurrent());
  const bool msaa = impl_->options.msaa_samples > 0;
  glBindFramebuffer(GL_FRAMEBUFFER, msaa ? impl_->multisample.fbo : impl_->resolved.fbo);
  glViewport(0, 0, camera.width, camera.height);
  glScissor(0, 0, camera.width, camera.height);  // Clears touch only this corner.
  std::array<GLenum, kNumColourAttachments> buffers;
  for (int i = 0; i < kNumColourAttachments; ++i) {
    buffers[i] = (out->requested & kAttachmentOutput[i]) ? GL_COLOR_ATTACHMENT0 + i : GL_NONE;
  }
  glDrawBuffers(kNumColourAttachments, buffers.data());
  glEnable(GL_FRAMEBUFFER_SRGB);
  const Eigen::Vector3f& b = impl_->shading.background_srgb;
  const float background[4] = {SrgbToLinear(b.x()), SrgbToLinear(b.y()), SrgbToLinear(b.z()), 1};
  const float zeros[4] = {0, 0, 0, 0};
  const GLuint zero_label[4] = {0, 0, 0, 0};
  const float far_depth = 1.0f;
  glClearBufferfv(GL_COLOR, 0, background);
  glClearBufferfv(GL_COLOR, 1, zeros);
  glClearBufferuiv(GL_COLOR, 2, zero_label);
  glClearBufferfv(GL_COLOR, 3, zeros);
  glClearBufferfv(GL_DEPTH, 0, &far_depth);
  impl_->DrawItems(camera, items);
  if (msaa) impl_->Resolve(camera.width, camera.height, out->requested);
  glDisable(GL_FRAMEBUFFER_SRGB);
  impl_->ReadBack(camera.width, camera.height, out);
  glBindFramebuffer(GL_FRAMEBUFFER, 0);
  if (!(out->requested & kRenderColour)) out->colour = RgbImage();
  if (!(out->requested & kRenderDepth)) out->depth_m = FloatImage();
  if (!(out->requested & kRenderLabel)) out->label = MaskImage();
  if (!(out->requested & kRenderNormals)) out->normals_in_world = Vec3Image();
  return CheckGl("Render");
}

std::string OffscreenRenderer::Description() const { return impl_->description; }

}  // namespace reenact::render
