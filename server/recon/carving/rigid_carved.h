// The method "rigid-carved" (thesis 3.4, voxel carving-based reenactment):
// its options, RunRigidCarved and its registration (RigidCarvedMethod, listed
// in server/recon/registry.cc).
#pragma once

#include <map>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "common/base/progress.h"
#include "common/model/reenactment.h"
#include "server/recon/reconstruction_method.h"
#include "server/recon/rigid_texturing.h"
#include "server/recon/take_frames.h"

namespace reenact::recon {

// The method's options; each is also a job option of the same name (listed
// with bounds and documentation by `reenact jobs methods`).
struct RigidCarvedOptions {
  // Eq. 3.8 weights (options "w_o", "w_s_per_voxel", "twist_weight"): w_s =
  // w_s_per_voxel x |V_b| per anchor (the thesis: 0.5; tuned here, see the
  // file comment), twist_weight the weight of the X-axis anchor.
  double w_o = 1.0;
  double w_s_per_voxel = 0.005;
  double twist_weight = 0.0;
  // Voxel side and truncation mu of Eq. 3.11, millimetres ("voxel_mm", "mu_mm").
  double voxel_mm = 8.0;
  double mu_mm = 20.0;
  // Fast motion ("max_drift_mm", 0: off): a part whose registered pose
  // puts its joint anchors farther than this from where the instant's
  // skeleton puts them (the chain drifted, or the step jumped to another
  // surface), or that found nothing to register against, restarts from the
  // skeleton's pose at that instant.
  double max_drift_mm = 60.0;
  // Registration ("max_iterations", "max_pair_distance_mm",
  // "max_normal_angle_deg", "min_update_deg", "min_update_mm").
  int max_iterations = 10;
  double max_pair_distance_mm = 40.0;
  double max_normal_angle_deg = 45.0;
  double min_update_deg = 0.01;
  double min_update_mm = 0.01;
  // Depth decimation for registration and labels ("depth_step"), and the
  // most points a part registers with per instant ("max_points_per_part").
  int depth_step = 2;
  int max_points_per_part = 1200;
  // Optical flow ("use_flow"; "flow_width_px": colour is decoded at the
  // smallest of 1, 1/2, 1/4, 1/8 of its size that is at least this wide).
  bool use_flow = true;
  int flow_width_px = 320;
  // Depth pixels at discontinuities are dropped ("edge_filter_mm", 0: off;
  // sensor_frame.h RemoveDepthEdges).
  int edge_filter_mm = 30;
  // Nominal part shapes (ShapeOf) scaled across the bone by radius_scale;
  // volume boxes grow them by a quarter plus margin_mm ("radius_scale",
  // "margin_mm").
  double radius_scale = 1.0;
  double margin_mm = 30.0;
  // Fuse every fuse_stride-th instant ("fuse_stride"); 0: about 15 fused
  // instants per second of take (every instant at 15 fps, every other at 30).
  int fuse_stride = 0;
  // Decoded depth and labels kept from registration for fusion, at most
  // this many MiB ("cache_mb"); instants beyond are decoded again.
  int cache_mb = 512;
  // Mesh components smaller than this fraction of a part's largest are
  // dropped as floaters ("min_component_fraction"; with sensors facing each
  // other a part's front and back can be separate components).
  double min_component_fraction = 0.1;
  // Voxels no depth image observed (N*(v) = 0) that lie inside the part's
  // nominal shape count as inside (-mu) when meshing ("fill_unseen").
  bool fill_unseen = true;
  // Depth pixels without a return that lie off the actor mask carve their
  // ray as free space ("carve_no_return"; see MarkFreeRays), up to
  // free_ray_max_mm from the sensor ("free_ray_max_mm": beyond the sensor's
  // range an actor returns nothing either).
  bool carve_no_return = true;
  double free_ray_max_mm = 4000.0;
  // Label pixels by the nearest nominal part ("ownership"; false: the
  // thesis' volumes: a part registers every point inside its box and fuses
  // every pixel).
  bool ownership = true;
  RigidTexturingOptions texturing;

  // Reads every option above and the texturing ones.
  absl::Status Read(OptionReader& reader);
  // InvalidArgument naming the first bad field (mu_mm below voxel_mm, bad
  // registration or texturing options).
  absl::Status Validate() const;
  // The method's own share of a job's memory (memory_estimate.h): every
  // part's volume, the decoded depth it keeps (cache_mb), the meshes and
  // their texturing.
  int64_t MemoryBytes(const TakeSize& take) const;
};

// Runs rigid-carved on a loaded take: per-part registration (Eq. 3.7-3.9),
// per-part truncated SDF (Eq. 3.10-3.11), marching cubes, texture keyframes
// and baked textures (server/recon/rigid_texturing.h AddRigidTextures, the same
// call the cylinders method makes).
//
// Options other than the defaults come from the job (TypedMethod parses
// and validates them) or from callers such as tests and benchmarks.
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
// `context.progress`: stages "register", "fuse", "mesh", "texture" (items:
// instants done / total); fraction over the whole call. Returning false from
// it makes the method stop with Cancelled. `context.log` may be empty.
// InvalidArgument for bad options or a take without a valid instant;
// Cancelled; DataLoss when a frame of the take does not decode.
absl::StatusOr<Reenactment> RunRigidCarved(const TakeFrames& take,
                                           const RigidCarvedOptions& options = {},
                                           const MethodContext& context = {});

// One take split across several workers (ReconstructionMethod::Prepare).
// Registration is a chain from each part's first instant (Eq. 3.7: T_{b,n}
// = dT T_{b,n-1}) and fusion adds every instant into one volume per part
// in the frames that chain defines, so both stay in the prepare phase:
// PrepareRigidCarved registers, fuses and meshes the whole take and packs
// the untextured reenactment (rigid_texturing.h PackUntexturedRigid).
// Texturing is split as rigid_texturing.h says: each segment makes its
// instants' keyframes against the prepared meshes, the stitch bakes. The
// stitched reenactment equals RunRigidCarved's but for the texturing's
// timing and the figure "segments". Prepare decodes every instant's depth
// and (with use_flow) colour. Errors as RunRigidCarved's.
absl::StatusOr<std::string> PrepareRigidCarved(const TakeFrames& take,
                                               const RigidCarvedOptions& options,
                                               const MethodContext& context = {});

// The method "rigid-carved" for the registry (registry.cc).
const ReconstructionMethod& RigidCarvedMethod();

}  // namespace reenact::recon
