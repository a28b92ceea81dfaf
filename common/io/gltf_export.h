// Export of a reenactment (common/io/reenactment_file.h) to glTF 2.0 binary
// (.glb, https://registry.khronos.org/glTF/specs/2.0/glTF-2.0.html) through
// tinygltf, for any glTF viewer (three.js in the browser, Blender, ...).
//
// What the file holds:
//   - one scene with a root node (named after the reenactment id, the info's
//     take, method and fps in its extras) and one child node per body part,
//     named after the part;
//   - per part a mesh: POSITION (part frame, metres, with min/max), NORMAL
//     (normalised), TEXCOORD_0 when textured (v flipped: the reenactment's
//     (0, 0) is the bottom-left of the image, glTF's the top-left) and uint32
//     indices;
//   - per part a material whose baseColorTexture is the part's baked JPEG,
//     stored as is (image/jpeg bufferView), with KHR_materials_unlit: the
//     texture is a photograph that already holds the light;
//   - one animation: translation, rotation and scale channels per part node,
//     keyed at every frame, times in seconds from the first frame's stamp,
//     LINEAR. PartPose.world_from_part maps directly onto glTF's node TRS
//     (point_in_world = T + R (s point_in_part); glTF world is +Y up,
//     metres, as ours).
// Departures / choices:
//   - a pose that is not valid hides its part (scale 0), holding the last
//     (or next) valid translation and rotation; where a part appears or
//     disappears an extra key 1 ms (at most a quarter of the frame interval)
//     before the frame makes the change a step instead of a one-frame grow;
//   - quaternion signs are flipped where needed so that consecutive keys lie
//     in the same hemisphere (LINEAR slerps the short way in every viewer);
//   - frame stamps that do not increase strictly (never in files the
//     methods write) fall back to frame_index / fps for the key times;
//   - parts without triangles get a node without a mesh; parts without a
//     baked texture get a plain grey material.
#pragma once

#include <cstdint>
#include <string>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "common/model/reenactment.h"
#include "reenact/v1/reenactment.pb.h"

namespace reenact {

struct GltfExportOptions {
  // Materials with the baked textures; false: plain grey materials (smaller
  // files, e.g. to look at the motion only).
  bool textures = true;
  // Mark materials KHR_materials_unlit (the baked textures hold the light).
  bool unlit = true;
  // Key times when the stamps do not increase, frames per second; 0: the
  // info's fps (30 when that is 0 too).
  double fallback_fps = 0.0;

  // InvalidArgument naming the first bad field.
  absl::Status Validate() const;
};

// What an export wrote.
struct GltfExportSummary {
  int nodes = 0;     // Root + parts (body: root + joints + the mesh node).
  int meshes = 0;    // Parts with triangles (body: 1).
  int textures = 0;  // Baked textures (body: the atlas) embedded.
  int animation_channels = 0;
  int keys = 0;    // Animation keys over all parts (frames + steps) or joints.
  int joints = 0;  // Skin joints (body-model reenactments: 25).
  // Body-model reenactments: frames whose vertex offsets were left out.
  int frames_offsets_left_out = 0;
  double duration_s = 0.0;
  bool stamps_fell_back = false;  // Key times from frame_index / fps.
  int64_t bytes = 0;              // Size of the .glb.

  // One line for logs and CLI output.
  std::string BriefReport() const;
};

// The .glb bytes of `data` (validated first: InvalidArgument when it is not
// a valid reenactment). Keyframes are not used and may be absent.
absl::StatusOr<std::string> ExportReenactmentGlb(const Reenactment& data,
                                                 const GltfExportOptions& options = {},
                                                 GltfExportSummary* summary = nullptr);

// The .glb of a body mesh alone, in its rest pose: the skinned mesh and its
// 25 joint nodes (Kinect v2 order, named after the joints, skin joint j =
// joint j) as ExportReenactmentGlb writes them for a body-model
// reenactment, without an animation; the atlas as material when the mesh
// has one (plain grey otherwise). A viewer poses it by setting joint j's
// rotation to BodyPose.local_rotations[j] and the root joint's
// (SpineBase's) translation to its rest position plus root_translation_m.
absl::StatusOr<std::string> ExportBodyMeshGlb(const BodyMesh& mesh,
                                              const GltfExportOptions& options = {},
                                              GltfExportSummary* summary = nullptr);
// The same for a BodyMesh message (live previews send them); InvalidArgument
// when it does not decode.
absl::StatusOr<std::string> ExportBodyMeshGlb(const v1::BodyMesh& mesh,
                                              const GltfExportOptions& options = {},
                                              GltfExportSummary* summary = nullptr);

// ExportReenactmentGlb written to `path` through a temporary file.
absl::Status WriteReenactmentGlb(const Reenactment& data, const std::string& path,
                                 const GltfExportOptions& options = {},
                                 GltfExportSummary* summary = nullptr);

}  // namespace reenact
