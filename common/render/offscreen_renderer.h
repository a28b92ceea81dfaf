// Headless OpenGL 3.3 core renderer of textured triangle meshes with colour,
// metric depth, label and normal outputs. The context comes from EGL without
// a display: Mesa's surfaceless platform, else the EGL device platform
// (NVIDIA), else the default display; drawing goes to an offscreen
// framebuffer. OpenGL and EGL appear only in offscreen_renderer.cc.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "common/base/image.h"
#include "common/render/mesh_data.h"
#include "common/render/render_types.h"

namespace reenact::render {

// Threads: a renderer owns one GL context and is not thread-safe. Call it from
// one thread at a time. Every method makes the context current on the calling
// thread when it is not already; to move to another thread, call
// ReleaseCurrent() on the old thread first. Ids are valid only with the
// renderer that returned them.
class OffscreenRenderer {
 public:
  // Creates the EGL context (OpenGL 3.3 core or newer), compiles the shaders
  // and allocates a framebuffer of options.max_width x max_height, and leaves
  // the context current on the calling thread. InvalidArgument for bad
  // options; Unavailable when no EGL display or GL 3.3 core context can be
  // had (no driver, no GPU and no Mesa), with the EGL error in the message.
  static absl::StatusOr<std::unique_ptr<OffscreenRenderer>> Create(const RendererOptions& options);

  ~OffscreenRenderer();
  OffscreenRenderer(const OffscreenRenderer&) = delete;
  OffscreenRenderer& operator=(const OffscreenRenderer&) = delete;

  // Makes the context current on the calling thread; FailedPrecondition when it
  // is current on another thread.
  absl::Status MakeCurrent();
  // Detaches the context from the calling thread so another thread may use it.
  absl::Status ReleaseCurrent();

  // Copies a mesh to the GPU (ValidateMeshData first). Positions and normals
  // stay updatable; the rest is fixed.
  absl::StatusOr<MeshId> UploadMesh(const MeshData& mesh);

  // Replaces the positions (and normals) of an uploaded mesh, e.g. each frame
  // of an animation. For a mesh with MeshData::source_vertex both are given
  // per original vertex (3 x num_source_vertices), else per mesh vertex.
  // `normals` empty: a mesh uploaded with normals gets area-weighted normals
  // recomputed from the new positions (across seams); a mesh without keeps
  // none. NotFound for an unknown id, InvalidArgument for wrong sizes.
  absl::Status UpdateMeshPositions(MeshId mesh, const Eigen::Matrix3Xf& positions_m,
                                   const Eigen::Matrix3Xf& normals = Eigen::Matrix3Xf());

  // Copies an sRGB image (top row first) to the GPU as a texture with linear
  // filtering and mipmaps; uv (0,0) is its bottom-left corner.
  // InvalidArgument for an empty image or one larger than the GL limit.
  absl::StatusOr<TextureId> UploadTexture(const RgbImage& image_srgb);
  // The same for an alpha-tested texture: fragments where the filtered alpha
  // (linear, 0..255 -> 0..1) is below 0.5 are discarded, so they write no
  // colour, depth, label or normal (e.g. texels that are not the actor).
  absl::StatusOr<TextureId> UploadTexture(const RgbaImage& image_srgb_alpha);
  // Replaces the texels of an uploaded opaque texture in place (and its
  // mipmaps), e.g. each frame of a texture video, without a new allocation.
  // NotFound for an unknown id; InvalidArgument when the image's size is not
  // the texture's.
  absl::Status UpdateTexture(TextureId texture, const RgbImage& image_srgb);

  // Frees a mesh or a texture; NotFound for an unknown id. A later upload
  // may reuse a freed id.
  absl::Status ReleaseMesh(MeshId mesh);
  absl::Status ReleaseTexture(TextureId texture);

  // Sets the light and background used by later Render calls.
  absl::Status SetShading(const ShadingOptions& shading);

  // Draws `items` seen by `camera` (nearest surface wins) and reads back the
  // outputs selected by out->requested, each camera.width x camera.height, top
  // row first. InvalidArgument for a bad camera, one larger than the
  // framebuffer, an unknown id, a texture on a mesh without uvs or a label
  // outside [0, 255]; Internal when OpenGL reports an error.
  absl::Status Render(const RenderCamera& camera, const std::vector<DrawItem>& items,
                      RenderOutputs* out);

  // The GL_VERSION and GL_RENDERER strings of the context, e.g. for logs.
  std::string Description() const;

 private:
  struct Impl;
  explicit OffscreenRenderer(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace reenact::render
