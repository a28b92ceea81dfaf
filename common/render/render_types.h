// Plain types of the renderer: typed ids, cameras, draw items, outputs and
// options. Free of OpenGL, so callers and tests need no GL headers.
#pragma once

#include <compare>
#include <cstdint>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "absl/status/status.h"
#include "common/base/image.h"

namespace reenact::render {

// Handle of a mesh uploaded to one renderer; invalid when value < 0.
struct MeshId {
  int value = -1;
  bool valid() const { return value >= 0; }
  auto operator<=>(const MeshId&) const = default;
};

// Handle of a texture uploaded to one renderer; invalid when value < 0.
struct TextureId {
  int value = -1;
  bool valid() const { return value >= 0; }
  auto operator<=>(const TextureId&) const = default;
};

// Per-pixel 3-vectors (x y z interleaved), e.g. unit normals in the world frame.
using Vec3Image = Image<float, 3>;

// sRGB colour with a linear alpha (R G B A), e.g. a texture whose alpha marks
// the texels to draw (OffscreenRenderer::UploadTexture).
using RgbaImage = Image<uint8_t, 4>;

// A pinhole camera, OpenCV convention: x right, y down, z forward (optical
// axis). A point (X, Y, Z) in the camera frame lands at the continuous image
// position (fx X / Z + cx, fy Y / Z + cy), pixels. Pixel (u, v) covers
// [u, u + 1) x [v, v + 1) and is sampled at its centre (u + 0.5, v + 0.5); so
// the image centre is (width / 2, height / 2). For intrinsics calibrated with
// pixel centres at integers (OpenCV calibration), pass cx + 0.5 and cy + 0.5.
struct RenderCamera {
  int width = 0;    // Pixels.
  int height = 0;   // Pixels.
  double fx = 0.0;  // Focal lengths, pixels.
  double fy = 0.0;
  double cx = 0.0;  // Principal point, pixels (see the convention above).
  double cy = 0.0;
  // Pose of the camera: maps camera-frame points to world points, metres.
  Eigen::Isometry3d world_from_camera = Eigen::Isometry3d::Identity();
  double near_m = 0.1;  // Clipping planes along the optical axis, metres.
  double far_m = 20.0;

  // InvalidArgument when sizes or focal lengths are not positive, or
  // 0 < near_m < far_m does not hold, or a value is not finite.
  absl::Status Validate() const;
};

// The OpenGL clip-space matrix of `camera`: clip = ClipFromCamera * (X, Y, Z, 1)
// for a point in the OpenCV camera frame, with w_clip = Z. Image row v maps to
// framebuffer row v (OpenGL's bottom row holds the image's top row), so a
// framebuffer read back with glReadPixels is already top row first; the image
// is mirrored in y relative to OpenGL, so front faces are clockwise in window
// coordinates. NDC z is -1 at near_m and +1 at far_m.
Eigen::Matrix4d ClipFromCamera(const RenderCamera& camera);

// One mesh instance to draw.
struct DrawItem {
  MeshId mesh;
  // Pose of the mesh: maps model-frame points to world points, metres.
  Eigen::Isometry3d world_from_model = Eigen::Isometry3d::Identity();
  // Surface colour, in order of precedence: the texture when valid (the mesh
  // must have uvs); else the mesh's vertex colours when it has them; else
  // colour_srgb (components in [0,1]). Fragments whose texture alpha is below
  // 0.5 are discarded (only RGBA textures have alpha below 1).
  TextureId texture;
  Eigen::Vector3f colour_srgb{0.8f, 0.8f, 0.8f};
  // Written to the label image where this item is visible: 1..255 (e.g. body
  // index); 0 is the background and makes the item invisible in the labels.
  int label = 1;
  // Lambert + ambient shading (ShadingOptions) when true; the plain surface
  // colour when false.
  bool lit = true;
  // Drawn pushed back in depth (a slope-scaled polygon offset), so that a
  // coincident surface of another item wins wherever it is drawn and this
  // one shows only where that one leaves a gap (e.g. discarded texels).
  bool underlay = false;
  // Skips the triangles that face away from the camera: for closed meshes
  // whose triangles wind counter-clockwise seen from outside (mesh_data.h),
  // such as a body model. Their back faces are hidden anyway, and on a
  // software renderer (llvmpipe) rasterising them costs about a third of a
  // body's frame. Open meshes keep both sides (false).
  bool cull_back_faces = false;
  // Opaque when 1. Below 1 (in (0, 1)): blended over what the opaque items
  // drew at the same depth, colour = w x this + (1 - w) x that, e.g. a second
  // texture of the same triangles (view-dependent texture blending). Such
  // items are drawn after every opaque one, in their order, pass only where
  // their depth equals what is drawn there (the same triangles drawn again,
  // so never over the background, a discarded texel or a nearer surface),
  // and write only the colour (not the depth, label or normal).
  float blend_weight = 1.0f;
};

// Light and background shared by all items of a frame.
struct ShadingOptions {
  // When true the light sits at the camera (direction_to_light_in_world is
  // ignored); otherwise a directional light.
  bool headlight = true;
  // Unit-free direction from the surface toward the light, world frame.
  Eigen::Vector3d direction_to_light_in_world{0.3, 1.0, 0.5};
  float ambient = 0.3f;  // Fraction of the albedo seen everywhere.
  float diffuse = 0.7f;  // Lambert weight of the light.
  // Colour image where no item is drawn, sRGB in [0,1].
  Eigen::Vector3f background_srgb{0.0f, 0.0f, 0.0f};

  // InvalidArgument on negative weights, a zero light direction or colours
  // outside [0,1].
  absl::Status Validate() const;
};

// Output selection bits for RenderOutputs::requested.
enum RenderOutput : uint32_t {
  kRenderColour = 1u << 0,
  kRenderDepth = 1u << 1,
  kRenderLabel = 1u << 2,
  kRenderNormals = 1u << 3,
};

// The images of one frame, camera.width x camera.height, top row first. Only
// the requested ones are filled; the others are left empty.
struct RenderOutputs {
  uint32_t requested = kRenderColour | kRenderDepth | kRenderLabel;
  RgbImage colour;     // sRGB.
  FloatImage depth_m;  // Z along the optical axis, metres; 0 where nothing.
  MaskImage label;     // DrawItem::label of the visible item; 0 where nothing.
  // Unit surface normal of the visible item, world frame, pointing out of the
  // surface (out of counter-clockwise faces); (0,0,0) where nothing.
  Vec3Image normals_in_world;
};

// Options of OffscreenRenderer::Create.
struct RendererOptions {
  // Largest image that Render accepts, pixels; the framebuffer has this size.
  int max_width = 1920;
  int max_height = 1080;
  // Multisampling: 0 (off) or 2, 4, 8 samples per pixel. When on, colour
  // edges are antialiased; depth and normals at silhouette pixels are then
  // averages over the samples (background counts as 0) and the label is one
  // of the samples, so keep it off for sensor simulation.
  int msaa_samples = 0;

  // InvalidArgument when a size is outside [1, 16384] or msaa_samples is not
  // one of 0, 2, 4, 8.
  absl::Status Validate() const;
};

}  // namespace reenact::render
