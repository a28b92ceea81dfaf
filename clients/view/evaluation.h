// Accuracy of a reenactment (rigid parts or body model) against the ground
// truth of the synthetic take it was made from (common/synth:
// /ground_truth/mesh, /ground_truth/topology with the truth's appearance,
// /ground_truth/joints):
//
//  * Surface: per evaluated instant, the reconstructed surface (the posed
//    meshes of the valid parts; for a body-model reenactment the posed body
//    mesh, PoseBodyMesh with the frame's vertex offsets, triangles over the
//    model vertices, none where the pose is not valid) against the true
//    posed mesh, both ways, vertex to surface (point-to-triangle,
//    TriangleSurfaceIndex):
//      surface_accuracy_mm      mean distance of reconstructed vertices to
//                               the true surface (recon -> truth);
//      surface_completeness_mm  mean distance of true vertices to the
//                               reconstructed surface (truth -> recon);
//      surface_mm               their mean (a symmetric surface distance).
//    Means are pooled over the vertices of all evaluated instants.
//  * Novel view 90 degrees from the capture sensors: sensor 0's colour
//    camera turned +90 degrees about the vertical (+Y) axis through the
//    actor's mean true root (SpineBase) position over the evaluated
//    instants; with two facing sensors this is the view farthest from both.
//    Rendered at 960 x 540 (the colour intrinsics scaled, distortion left
//    out) twice by the same renderer: the reenactment (VDTM, or baked; a
//    body-model reenactment with its atlas, ReenactmentRenderer) and the
//    truth (true posed mesh with its albedo texture under the take's light,
//    lit).
//      psnr_db_90  PSNR (8-bit, peak 255) over the pixels where both show
//                  the person, MSE pooled over RGB and all evaluated instants;
//      iou_90      mean over instants of the silhouette IoU;
//      ssim_90     structural similarity (Wang, Bovik, Sheikh, Simoncelli
//                  2004) on the same pixels as psnr_db_90: with M the mask
//                  of pixels where both images show the person, and per
//                  channel (R, G, B; 8-bit levels) the local means,
//                  variances and covariance taken over an 11 x 11 Gaussian
//                  window (sigma 1.5 px) restricted to M (the window's
//                  weights renormalised over its pixels in M), SSIM(p) =
//                  (2 mu_x mu_y + C1)(2 sigma_xy + C2) /
//                  ((mu_x^2 + mu_y^2 + C1)(sigma_x^2 + sigma_y^2 + C2)),
//                  C1 = (0.01 * 255)^2, C2 = (0.03 * 255)^2; ssim_90 is
//                  the mean of SSIM(p) over the channels and over every
//                  pixel of M of every evaluated instant (1: identical).
//                  Background pixels never enter a window, so a silhouette
//                  error shows in iou_90 only, as for PSNR.
//  * mpjpe_mm: mean distance of PartFrame.joints_in_world_m to the true
//    joints, over the 25 Kinect v2 joints and the evaluated instants
//    (joints the reenactment lacks are left out).
//
// Instants are matched by index: PartFrame.frame_index is the ground truth's
// frame_index (a synthetic take has one instant per ground-truth frame).
#pragma once

#include <cstdint>
#include <limits>
#include <map>
#include <set>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "clients/view/reenactment_renderer.h"
#include "common/base/progress.h"
#include "common/model/ground_truth.h"

namespace reenact::view {

struct EvaluationOptions {
  // Evaluate every k-th instant (0, k, 2k, ...), k >= 1.
  int every = 1;
  // Which figures to measure.
  bool surface = true;
  bool novel_view = true;
  bool joints = true;
  // Novel view: size (pixels) and turn about the vertical, degrees.
  int novel_width = 960;
  int novel_height = 540;
  double novel_angle_deg = 90.0;
  // Texturing of the reenactment in the novel view.
  TextureMode mode = TextureMode::kVdtm;
  // Cell of the surface-distance grid, metres.
  double grid_cell_m = 0.02;
  // When not empty, each evaluated novel view is written there as a PNG,
  // reenactment left and truth right ("novel_<frame>.png").
  std::string image_dir;

  // InvalidArgument naming the first bad field.
  absl::Status Validate() const;
};

struct EvaluationResult {
  static constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
  int frames_evaluated = 0;  // Instants visited (every k-th).
  // Surface (NaN when not measured).
  double surface_mm = kNaN;
  double surface_accuracy_mm = kNaN;
  double surface_completeness_mm = kNaN;
  int surface_frames = 0;
  // Novel view (NaN when not measured; PSNR NaN also when no pixel overlaps
  // or the take has no albedo).
  double psnr_db_90 = kNaN;
  double iou_90 = kNaN;
  double ssim_90 = kNaN;  // NaN as psnr_db_90.
  int64_t psnr_pixels = 0;
  int novel_view_frames = 0;
  // Joints.
  double mpjpe_mm = kNaN;
  int64_t mpjpe_joints = 0;

  // Every figure by name (the names above), for JSON output.
  std::map<std::string, double> Figures() const;
};

// The frames whose true meshes EvaluateReenactment needs for `data` under
// `options` (none when it measures joints only): read the ground truth with
// them, e.g. ReadGroundTruth(take, EvaluationMeshFrames(data, options))
// (common/io/take_convert.h).
std::set<int64_t> EvaluationMeshFrames(const Reenactment& data, const EvaluationOptions& options);

// Measures `data` against the take's ground truth `truth` (see the file
// comment); instants whose true mesh `truth` lacks are left out when the
// surface or the novel view is measured. FailedPrecondition when no instant
// is shared; InvalidArgument for bad options or a reenactment that does not
// validate; Unavailable when no GL context can be had for the novel view;
// Cancelled when `progress` returns false.
absl::StatusOr<EvaluationResult> EvaluateReenactment(const Reenactment& data,
                                                     const GroundTruth& truth,
                                                     const EvaluationOptions& options = {},
                                                     const ProgressCallback& progress = {});

// Sums of the masked SSIM (the definition of ssim_90 above) of two 8-bit
// RGB images of the same size over the pixels where `mask` (row-major,
// width x height) is non-zero: `sum` of SSIM(p) averaged over the channels,
// `pixels` counted. Empty sums for images of different sizes.
struct SsimSums {
  double sum = 0.0;
  int64_t pixels = 0;
};
SsimSums MaskedSsim(const RgbImage& a, const RgbImage& b, const std::vector<uint8_t>& mask);

// The pooled PSNR of 8-bit images from a sum of squared differences over
// `count` samples, dB (infinity for zero error, NaN for no samples).
double PsnrDb(double sum_squared_error, int64_t count);

}  // namespace reenact::view
