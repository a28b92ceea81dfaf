// The method "body" (thesis ch. 4): per instant the merged point cloud of all
// sensors (body_cloud.h), the fit of the statistical body model with one
// shape for the take (body_fit.h), and the atlas (body_texturing.h); the
// result is a body-model reenactment (common/io/body_reenactment.h).
//
// Options (strings, as submitted with the job):
//   model              "procedural" (default) or "makehuman:NAME", NAME a
//                      folder under the server's asset roots (model_spec.h)
//   point_weight       w_z of Eq. 4.7 (1)
//   smoothness_weight  w_r of Eq. 4.7 (0.001; see body_fit.h)
//   skeleton_weight    the sensors' skeleton prior (0.1)
//   shape_frames       instants the shape is fitted on (5)
//   rounds, iterations correspondence rounds and LM iterations per frame (3, 5)
//   max_points         points per round (1200)
//   refine_vertices    the free-form mesh step (true)
//   atlas_px           atlas side (1024)
//   visibility_m       T of thesis 4.4 (0.10)
//   texture_every      use every k-th instant for the atlas (2)
//   texture_scale      decode colour at 1/k for the atlas (2: 960x540 of 1080p)
//   texture_sharpness  p of the cos^p frontality weight of observations (2)
//   measured_m         texels must lie this near the sensor's own depth (0.02;
//                      0: the thesis's test alone)
#pragma once

#include <map>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "common/base/progress.h"
#include "common/body/body_model.h"
#include "common/bodyfit/body_fit.h"
#include "common/io/reenactment_file.h"
#include "server/recon/body/body_texturing.h"
#include "server/recon/method_util.h"
#include "server/recon/methods.h"
#include "server/recon/take_frames.h"

namespace reenact::recon {

// The method's options, read by key (the list above).
struct BodyMethodOptions {
  std::string model = "procedural";
  // Where "makehuman:NAME" is looked up: the server's --assets folders. Set
  // by the caller, never from the options (a client names no server path).
  std::vector<std::string> asset_roots = {};
  bodyfit::BodyFitOptions fit;
  AtlasOptions atlas;
  // InvalidArgument naming the key for a value that does not parse or fit.
  absl::Status Read(OptionReader& reader);
};

// The PartFrame of one fitted instant: its BodyPose (with the offsets of
// step 2 when present), point RMS, valid flag and fitted joints.
v1::PartFrame BodyFrameToProto(int frame_index, int64_t stamp_ns, const bodyfit::FrameFit& fit,
                               bool valid);

// Reads and checks the options without running (InvalidArgument naming the
// key), so a job can be rejected before the take is loaded.
absl::Status CheckBodyOptions(const std::map<std::string, std::string>& options);

// Runs the method on a loaded take. InvalidArgument for bad options or a
// take without a usable instant (no skeleton with a torso and no points);
// Cancelled when `progress` returned false.
// `asset_roots`: BodyMethodOptions::asset_roots.
absl::StatusOr<ReenactmentData> RunBody(const TakeFrames& take,
                                        const std::map<std::string, std::string>& options,
                                        const std::vector<std::string>& asset_roots,
                                        const ProgressCallback& progress, const LogCallback& log);

}  // namespace reenact::recon
