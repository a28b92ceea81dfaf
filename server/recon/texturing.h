// Texturing of rigid body parts (thesis 3.4.2, "Appropriate texture search"
// and "Applying textures", Eq. 3.13-3.15, Fig. 3.7):
//
//  * MakeTextureKeyframe keeps one colour image of the take as a texture
//    source: cropped to the actor, with the actor mask in crop pixels and,
//    per part, which mesh vertices the image shows. Occlusion follows
//    Fig. 3.7: every posed part is rendered into a depth buffer of the colour
//    camera, and a vertex counts as seen only where its depth agrees with
//    that buffer. Viewers (VDTM, Eq. 3.13) use the bits to pass over
//    keyframes in which a part is occluded and take the next-best one.
//  * BakePartTextures bakes one static texture per part from the keyframes
//    (for viewers without VDTM, and the glTF export): every texel takes the
//    colour of its surface point in the keyframes that see it most frontally.
//  * ProjectToKeyframeCrop is Eq. 3.14-3.15 written once, so that the client
//    renderer can mirror it exactly.
//
// Departures from the thesis:
//  * The thesis tests occlusion per pixel at render time against the
//    selected frame's rendered depth. Here the test runs once per keyframe
//    and vertex, offline, and is stored as bits (vertex_visible_bits); a
//    renderer interpolates the bits across a triangle. A vertex also needs
//    to face the camera and to land on the actor's mask (the thesis shows
//    the live image where the texture lookup lands on background).
//  * The depth buffer is rasterised on the CPU at the crop's resolution with
//    straight edges between the (distorted) projections of the vertices.
//  * Baking is not in the thesis (which always renders with VDTM). Keyframe
//    choice per triangle: visible in the keyframe (all three vertex bits;
//    when no keyframe sees all three, those that see some, tested per texel
//    by the bit of the nearest vertex) and most frontal (largest
//    -normal . view direction); the best few are blended by frontality, and
//    a texel whose point lands off the keyframe's actor mask is not taken
//    from it. The atlas maps each triangle to a right triangle, so texel
//    density varies with the triangle's shape; two neighbours across an edge
//    share a square cell, that edge its diagonal, so that they share its
//    two vertices and a lookup across it finds the neighbour's colours.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "common/base/image.h"
#include "common/geometry/camera.h"
#include "common/geometry/transforms.h"
#include "common/model/reenactment.h"

namespace reenact::recon {

// Parts are common/model's PartMesh (the shape of one body part in its part
// frame: positions in metres, unit vertex normals, counter-clockwise
// triangles seen from outside; one normal per position is required here)
// and PartPose (point_in_world = scale * (R * point_in_part) + t).

// One sensor's images at one instant.
struct SensorImages {
  // The sensor's calibration: colour intrinsics at the colour camera's full
  // resolution (crop_x/y of the keyframe are in those pixels), depth
  // intrinsics, color_from_depth and world_from_depth.
  const SensorCalibration& calibration;
  // Colour image, full resolution or scaled by the same factor along both
  // axes (the scale is width / color_intrinsics.width_px; its intrinsics are
  // ScaledIntrinsics of the calibration's).
  const RgbImage& colour;
  // Actor mask in depth pixels (> 0 actor) and depth (mm along the depth
  // camera's z, 0 = none), both of the depth intrinsics' size.
  const MaskImage& mask;
  const DepthImageMm& depth;
};

struct KeyframeOptions {
  // Margin around the actor's bounding box, full-resolution colour pixels.
  int margin_px = 16;
  // JPEG quality of the crop, 1..100.
  int jpeg_quality = 85;
  // Crops whose longer side exceeds this (in the colour image's pixels
  // after any scaling) are downscaled to it; the scale is recorded in
  // TextureKeyframe.crop_scale. 0: never downscale.
  int max_crop_side_px = 1024;
  // A vertex is visible when its depth in the colour camera is at most this
  // much behind the rendered depth of all parts at its pixel, metres.
  double visibility_tolerance_m = 0.03;

  // InvalidArgument naming the first bad field.
  absl::Status Validate() const;
};

// Makes the texture keyframe of one sensor at one instant: crop, crop_scale,
// JPEG, actor mask in crop pixels and per-part vertex visibility bits (see
// the file comment). `parts` and `poses` are in part-id order and of equal
// length; parts with an invalid pose get all-zero bits.
// InvalidArgument for inconsistent or non-finite input (image sizes that
// disagree with the calibration, a mask/depth size mismatch, NaN poses,
// malformed geometry, bad options); NotFound when the mask holds no actor
// pixel with depth that projects into the colour image (nothing to crop;
// callers skip the instant).
absl::StatusOr<TextureKeyframe> MakeTextureKeyframe(const std::vector<PartMesh>& parts,
                                                    const std::vector<reenact::PartPose>& poses,
                                                    const SensorImages& images, int frame_index,
                                                    int64_t stamp_ns, const std::string& sensor_id,
                                                    const KeyframeOptions& options = {});

// Everything needed to project into one keyframe's crop.
struct KeyframeCamera {
  CameraIntrinsics color_intrinsics;  // Full resolution (the calibration's).
  Rigid3d color_from_world;           // = color_from_depth * world_from_depth^-1.
  int crop_x_px = 0;                  // TextureKeyframe.crop_x_px / crop_y_px.
  int crop_y_px = 0;
  double crop_scale = 1.0;  // TextureKeyframe.crop_scale (0 read as 1).
};

// The camera of `keyframe` from its sensor's calibration. InvalidArgument
// for an invalid calibration or a negative or non-finite crop_scale.
absl::StatusOr<KeyframeCamera> KeyframeCameraOf(const SensorCalibration& calibration,
                                                const TextureKeyframe& keyframe);

// Eq. 3.14-3.15: the pixel of a point of a part (part frame, metres) in a
// keyframe's crop image, for the part's pose at the keyframe's instant:
//   x_world = scale * R * x_part + t                       (Eq. 3.14, T_{b,n})
//   x_color = color_from_world * x_world
//   u_full  = rho(x_color)  (colour intrinsics, distortion included; Eq. 3.15)
//   u_crop  = (u_full - crop_xy + 0.5) * crop_scale - 0.5
// Pixel centres are at integer coordinates (origin at the centre of the
// crop's top-left pixel). Eq. 3.14's T_b^{*-1} x^* (viewer point back to the
// part frame) is the caller's. nullopt when the point is behind the camera.
// The pixel may fall outside the crop.
std::optional<Eigen::Vector2d> ProjectToKeyframeCrop(const Eigen::Vector3d& point_in_part_m,
                                                     const reenact::PartPose& pose,
                                                     const KeyframeCamera& camera);

// Bit `vertex` of one part's vertex_visible_bits (LSB first); false when the
// bytes are too short.
bool VertexVisible(const std::string& bits, int vertex);

inline constexpr int kMaxGrownTexturePx = 4096;

struct BakeOptions {
  // Side of each part's square texture, pixels; a part with too many
  // triangles for cells of 4 px gets a larger one (doubling, up to
  // kMaxGrownTexturePx).
  int texture_size_px = 512;
  // JPEG quality of the baked textures, 1..100.
  int jpeg_quality = 90;
  // Keyframes blended per triangle (the most frontal ones), >= 1.
  int blend_count = 3;
  // Keyframes less frontal than the best by more than this (in -n . v, the
  // cosine of the viewing angle) are not blended in.
  double blend_frontality_window = 0.15;

  // InvalidArgument naming the first bad field.
  absl::Status Validate() const;
};

// Figures of one bake.
struct BakeSummary {
  int parts_baked = 0;
  int triangles = 0;
  // Triangles seen in no keyframe (their texels got the part's mean colour).
  int triangles_unobserved = 0;
  // Atlas cell side, pixels (smallest over parts).
  int min_cell_px = 0;
};

// Bakes one texture per part from `keyframes` (from MakeTextureKeyframe) and
// rewrites `parts` (PartMesh with positions, normals, triangles in; part id
// = PartMesh.part) to carry it: an atlas of one square cell per pair of
// triangles (each triangle a right triangle in one half, 1.5 px gutters
// along the cell's edges, every texel of a cell filled). Neighbours across
// an edge are paired where they can be (greedily, in triangle order), that
// edge the cell's diagonal; two triangles that are not neighbours keep
// 1.5-3 px gutters about the diagonal too. Vertices are split so that each
// corner has its own uv, except that a pair shares the two vertices of its
// diagonal: about 2 vertices per triangle instead of 3 (positions, normals
// and vertex indices rewritten; the triangles keep their order and the
// shape is unchanged), uvs ((0, 0) bottom-left) and baked_texture_jpeg. Keyframe
// poses come from `frames` (by frame_index), cameras from
// `sensors` (by sensor_id). Texels that no keyframe sees take the part's
// mean observed colour (mid grey when the part is seen nowhere). Crops are
// decoded one keyframe at a time; memory is about 16 bytes per texel of all
// parts. Valid poses need a positive scale (carved parts: 1).
// InvalidArgument for malformed meshes, keyframes naming unknown frames or
// sensors, bits whose length disagrees with a part's vertex count,
// undecodable crops or masks, non-finite poses, or bad options; `parts` is
// left unchanged on error.
absl::Status BakePartTextures(const std::vector<TextureKeyframe>& keyframes,
                              const std::vector<ReenactmentFrame>& frames,
                              const std::vector<SensorCalibration>& sensors,
                              const BakeOptions& options, std::vector<PartMesh>* parts,
                              BakeSummary* summary = nullptr);

// Keyframes made before BakePartTextures carry bits in the old vertex order;
// this rewrites them for the baked meshes, each of whose vertices copies a
// vertex of the mesh before baking (`before_bake`: the PartMesh list as it
// was passed to BakePartTextures; bits indexed by PartMesh.part). The split
// is a function of each mesh alone, so it is made again here.
// InvalidArgument (keyframes unchanged) when a mesh is malformed or a
// keyframe's bits for a part disagree with its vertex count.
absl::Status RemapVisibilityBitsToBakedMeshes(const std::vector<PartMesh>& before_bake,
                                              std::vector<TextureKeyframe>* keyframes);

}  // namespace reenact::recon
