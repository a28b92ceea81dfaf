// Contract of the method "rigid-carved" (thesis 3.4, voxel carving-based
// reenactment): server/recon/methods.cc dispatches to RunRigidCarved; engineer
// "carving" implements it in rigid_carved.cc.
#pragma once

#include <map>
#include <string>

#include "absl/status/statusor.h"
#include "common/base/progress.h"
#include "common/io/reenactment_file.h"
#include "server/recon/methods.h"
#include "server/recon/take_frames.h"

namespace reenact::recon {

// Runs rigid-carved on a loaded take: per-part registration (Eq. 3.7-3.9),
// per-part truncated SDF (Eq. 3.10-3.11), marching cubes, texture keyframes
// and baked textures (server/recon/rigid_texturing.h AddRigidTextures, the same
// call the cylinders method makes).
//
// `options`: the job's method options as submitted; every key is the
// method's to parse (server/recon/method_util.h OptionReader helps), and an
// unknown key or a malformed value is InvalidArgument naming it. Common keys
// that the cylinders method also accepts and that this method should accept
// too: "keyframe_stride", "color_scale", "bake", "texture_size_px",
// "keyframe_jpeg_quality", "max_crop_side_px" (RigidTexturingOptions::Read
// reads them all).
//
// Returns the reenactment without its bookkeeping: `parts` (15 PartMesh in
// part-id order, radius_rate 0, reference_length_m as in reenactment.proto),
// `frames` (one PartFrame per take instant, frame_index = the instant's
// index in `take`, stamp = Instant.stamp_ns, PartPose scale 1,
// joints_in_world_m = the instant's fused skeleton), `keyframes`, and in
// `info`: frame_count, fps, part_names and figures (e.g.
// "registration_rms_mm", "mean_iterations", "voxels"). RunMethod fills the
// rest of `info` (ids, method, options, created_unix_ns, generator,
// sensors, "seconds", "frames_per_second") and writes the file.
//
// `progress`: stages "register", "fuse", "mesh", "texture" (items: instants
// done / total); fraction over the whole call. Returning false from it makes
// the method stop with Cancelled. `log` may be empty.
// InvalidArgument for bad options or a take without a valid instant;
// Cancelled; DataLoss when a frame of the take does not decode.
absl::StatusOr<ReenactmentData> RunRigidCarved(const TakeFrames& take,
                                               const std::map<std::string, std::string>& options,
                                               const ProgressCallback& progress = {},
                                               const LogCallback& log = {});

}  // namespace reenact::recon
