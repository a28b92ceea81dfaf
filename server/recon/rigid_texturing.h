// The texturing stage both rigid methods share: texture keyframes (one per
// kept instant and sensor, server/recon/texturing.h MakeTextureKeyframe) and
// baked per-part textures (BakePartTextures), added to a reenactment whose
// meshes and frames are done.
#pragma once

#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/str_cat.h"
#include "common/base/progress.h"
#include "common/base/status_macros.h"
#include "common/model/reenactment.h"
#include "server/recon/memory_estimate.h"
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

  // The texturing's share of a job's memory on a take of `take`'s size
  // (memory_estimate.h): its keyframes with the visibility bits of
  // `vertices` (all parts) and, when baking, a texture grown for each part
  // of `part_triangles` triangles and the split meshes.
  int64_t MemoryBytes(const TakeSize& take, const std::vector<int64_t>& part_triangles,
                      int64_t vertices) const;
};

// Every instant for takes up to 20 s; longer takes keep at most 600
// keyframes in all (instants x sensors with colour).
int DefaultKeyframeStride(const TakeFrames& take);
// options.keyframe_stride when set, else DefaultKeyframeStride(take).
int KeyframeStride(const TakeFrames& take, const RigidTexturingOptions& options);

struct RigidTexturingSummary {
  int keyframe_stride = 0;
  int keyframes = 0;          // Kept.
  int keyframes_skipped = 0;  // No actor in view, no colour, invalid instant.
  BakeSummary bake;
  double seconds = 0.0;
};

// The instants of [first, end) (clipped to the take's num_instants) that are
// texture keyframes at `keyframe_stride` (every stride-th from instant 0).
std::vector<int> KeyframeInstants(int num_instants, int keyframe_stride, int first, int end);

// The keyframes of the instants [first, end) that are keyframes at
// `keyframe_stride` (> 0), for a reenactment whose meshes and frames are
// done (data.parts before baking; frames matched by frame_index = instant),
// in instant order, then sensor order. A view without colour bytes, an
// instant with no valid pose and a view with no actor to crop count as
// skipped. `progress` gets stage "texture", fractions 0..1 of the planned
// keyframes. Errors as AddRigidTextures'.
struct RigidKeyframes {
  std::vector<TextureKeyframe> keyframes;
  int planned = 0;  // Views decoded.
  int skipped = 0;
  double seconds = 0.0;
};
absl::StatusOr<RigidKeyframes> MakeRigidKeyframes(const TakeFrames& take,
                                                  const RigidTexturingOptions& options,
                                                  int keyframe_stride, const Reenactment& data,
                                                  int first, int end,
                                                  const ProgressCallback& progress = {});

// With options.bake and some keyframe: bakes data->parts from
// data->keyframes (BakePartTextures, cameras from the take's sensors) and
// carries the keyframes' visibility bits over to the baked vertex order.
// Errors as BakePartTextures'.
absl::Status BakeRigidTextures(const TakeFrames& take, const RigidTexturingOptions& options,
                               Reenactment* data, BakeSummary* summary);

// The texturing figures of a reenactment ("keyframes", "keyframe_stride",
// "texture_seconds", "baked_unobserved_fraction"), and its log line.
void AddTexturingFigures(const RigidTexturingSummary& summary,
                         std::map<std::string, double>* figures);
std::string TexturingLine(const RigidTexturingSummary& summary);

// Adds keyframes to `data->keyframes` (instants whose frame is in
// `data->frames`, matched by frame_index = instant index) and, with
// options.bake, rewrites `data->parts` with baked textures. Baking splits
// mesh vertices per triangle corner, so the keyframes' vertex_visible_bits
// (made for the meshes as they came in) are then carried over to the baked
// vertex order (texturing.h RemapVisibilityBitsToBakedMeshes). Adds the
// texturing figures (AddTexturingFigures) to data->info. `progress` gets
// fractions 0..1 of this stage (items: keyframes made / planned). InvalidArgument
// for inconsistent data; DataLoss when a frame does not decode; Cancelled.
absl::StatusOr<RigidTexturingSummary> AddRigidTextures(const TakeFrames& take,
                                                       const RigidTexturingOptions& options,
                                                       Reenactment* data,
                                                       const ProgressCallback& progress = {},
                                                       const LogCallback& log = {});

// A rigid method split across several workers (ReconstructionMethod::
// Prepare) splits its texturing, which needs its meshes and poses whole:
// its prepare phase makes the reenactment up to texturing (meshes before
// baking, one frame per instant) and packs it with PackUntexturedRigid;
// segment `index` of `count` (SegmentOf without warm-up) makes the
// keyframes of its instants against those meshes, crops and visibility
// exactly as a whole run does (RigidTextureSegment); the stitch gathers them
// in order and bakes (StitchRigidTextures). The stitched reenactment equals
// the whole run's but for the texturing's timing and the figure "segments".

// The prepared part (v1::RigidUntexturedPart): `data`'s meshes, frames
// (poses bit for bit) and figures, and the keyframe stride.
std::string PackUntexturedRigid(const Reenactment& data, int keyframe_stride);

// The prepared reenactment for `take`, with frame_count, fps and part
// names. DataLoss for bytes that do not parse; InvalidArgument for a part of
// a take with another number of instants, a stride below 1, frames out of
// order, poses that are not rigid or a reenactment that does not validate.
absl::StatusOr<Reenactment> UnpackUntexturedRigid(const std::string& prepared,
                                                  const TakeFrames& take, int* keyframe_stride);

// The keyframes of segment `index` of `count` (v1::RigidKeyframesPart).
// InvalidArgument for a segment that does not exist; errors of
// UnpackUntexturedRigid and MakeRigidKeyframes.
absl::StatusOr<std::string> RigidTextureSegment(const TakeFrames& take,
                                                const RigidTexturingOptions& options,
                                                const MethodContext& context,
                                                const std::string& prepared, int index, int count);

// The prepared reenactment with every segment's keyframes, baked, with the
// texturing figures and "segments". DataLoss for a segment that does not
// parse; InvalidArgument for segments missing or out of order, keyframes
// outside their segment's instants, or keyframes that do not fit the
// prepared meshes, frames or the take's sensors.
absl::StatusOr<Reenactment> StitchRigidTextures(const TakeFrames& take,
                                                const RigidTexturingOptions& options,
                                                const MethodContext& context,
                                                const std::string& prepared,
                                                const std::vector<std::string>& segments);

// What segment `index` of `count` decodes: the depth, actor mask and colour
// of its keyframe instants (the stride as options and the take give it).
TakeNeeds RigidTextureSegmentNeeds(const TakeFrames& take, const RigidTexturingOptions& options,
                                   int index, int count);

// The phases of a rigid method with options `Options` (a Validate() and
// the RigidTexturingOptions `texturing`) whose prepare phase packs with
// PackUntexturedRigid: SegmentFunctions' segment, stitch and needs, with
// `PrepareNeeds` naming what its prepare phase decodes.
template <typename Options>
absl::StatusOr<std::string> RigidSegmentPhase(const TakeFrames& take, const Options& options,
                                              const MethodContext& context,
                                              const std::string& prepared, int index, int count) {
  RETURN_IF_ERROR(options.Validate());
  return RigidTextureSegment(take, options.texturing, context, prepared, index, count);
}

template <typename Options>
absl::StatusOr<Reenactment> RigidStitchPhase(const TakeFrames& take, const Options& options,
                                             const MethodContext& context,
                                             const std::string& prepared,
                                             const std::vector<std::string>& segments) {
  RETURN_IF_ERROR(options.Validate());
  return StitchRigidTextures(take, options.texturing, context, prepared, segments);
}

template <typename Options, TakeNeeds (*PrepareNeeds)(const TakeFrames&, const Options&)>
absl::StatusOr<TakeNeeds> RigidPhaseNeeds(const TakeFrames& take, const Options& options,
                                          MethodPhase phase, int index, int count) {
  RETURN_IF_ERROR(options.Validate());
  switch (phase) {
    case MethodPhase::kWhole:
      return TakeNeeds::All(take);
    case MethodPhase::kPrepare:
      return PrepareNeeds(take, options);
    case MethodPhase::kSegment:
      if (count < 1 || index < 0 || index >= count) {
        return absl::InvalidArgumentError(
            absl::StrCat("segment ", index, " of ", count, " does not exist"));
      }
      return RigidTextureSegmentNeeds(take, options.texturing, index, count);
    case MethodPhase::kStitch:
      break;  // Part files, calibrations and skeletons alone.
  }
  return TakeNeeds();
}

}  // namespace reenact::recon
