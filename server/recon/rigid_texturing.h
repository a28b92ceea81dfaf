// The texturing stage both rigid methods share: texture keyframes (one per
// kept instant and sensor, server/recon/texturing.h MakeTextureKeyframe) and
// baked per-part textures (BakePartTextures), added to a reenactment whose
// meshes and frames are done.
#pragma once

#include <string>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "common/base/progress.h"
#include "common/model/reenactment.h"
#include "server/recon/method_util.h"
#include "server/recon/reconstruction_method.h"
#include "server/recon/take_frames.h"
#include "server/recon/texturing.h"

namespace reenact::recon {

struct RigidTexturingOptions {
  // Keep every keyframe_stride-th instant as a texture keyframe (every
  // sensor of it). 0: DefaultKeyframeStride(take).
  int keyframe_stride = 0;
  // Decode colour at 1/color_scale of its size (1, 2, 4 or 8) before
  // cropping; smaller is faster and makes smaller keyframes.
  int color_scale = 1;
  // Bake the static per-part textures (glTF export, viewers without VDTM).
  bool bake = true;
  KeyframeOptions keyframe;
  BakeOptions baking;

  // Reads "keyframe_stride", "color_scale", "bake", "texture_size_px",
  // "keyframe_jpeg_quality", "max_crop_side_px" from `reader`.
  absl::Status Read(OptionReader& reader);
  // InvalidArgument naming the first bad field.
  absl::Status Validate() const;
};

// Every instant for takes up to 20 s; longer takes keep at most 600
// keyframes in all (instants x sensors with colour).
int DefaultKeyframeStride(const TakeFrames& take);

struct RigidTexturingSummary {
  int keyframe_stride = 0;
  int keyframes = 0;          // Kept.
  int keyframes_skipped = 0;  // No actor in view, no colour, invalid instant.
  BakeSummary bake;
  double seconds = 0.0;
};

// Adds keyframes to `data->keyframes` (instants whose frame is in
// `data->frames`, matched by frame_index = instant index) and, with
// options.bake, rewrites `data->parts` with baked textures. Baking splits
// mesh vertices per triangle corner, so the keyframes' vertex_visible_bits
// (made for the meshes as they came in) are then carried over to the baked
// vertex order (texturing.h RemapVisibilityBitsToBakedMeshes). `progress` gets
// fractions 0..1 of this stage (items: keyframes made / planned). InvalidArgument
// for inconsistent data; DataLoss when a frame does not decode; Cancelled.
absl::StatusOr<RigidTexturingSummary> AddRigidTextures(const TakeFrames& take,
                                                       const RigidTexturingOptions& options,
                                                       Reenactment* data,
                                                       const ProgressCallback& progress = {},
                                                       const LogCallback& log = {});

}  // namespace reenact::recon
