// Texturing of the fitted body (thesis 4.4): colour from each sensor's image
// where the surface is visible, baked into an atlas over the template's UVs.
//
// The thesis projects each triangle of the fitted mesh M_Y,f into the images
// I_f^1, I_f^2, tests its vertices against a depth map of the mesh rendered
// for that sensor (visible when within T = 10 cm of the rendered depth), and
// colours triangles seen by no sensor with the average of their visible
// observations over the whole sequence.
//
// Here every texel of the atlas is one surface point (a triangle and
// barycentric coordinates). For each used instant and sensor we render the
// posed mesh's depth in the colour camera (a CPU z-buffer), and a texel is
// visible when its point faces the camera and lies within
// `visibility_threshold_m` of the rendered depth (the thesis's T); its colour
// is then read from the image (bilinear). The atlas holds, per texel, the
// average of its visible observations over the sequence, weighted by how
// squarely the sensor saw the surface (cos^2 of the angle to the normal).
// Departures, and why: the thesis's per-frame per-triangle colours become
// one static atlas (a skinned glTF and the viewers carry one texture; the
// clothes of a take do not change), sampled per texel rather than per
// triangle so that a triangle (about 1.5 cm) does not flatten the clothing's
// pattern; texels no sensor ever saw take the colour of the nearest
// observed texels (push-pull fill) instead of staying black.
// Beyond the thesis's visibility test, an observation is used only where all
// four pixels of its bilinear lookup show the posed mesh no farther than T
// behind the texel: at the mesh's silhouette the lookup would blend in the
// background, at an occlusion edge the surface behind. Those are the
// observations of surfaces seen edge-on, the ones a view from the side
// shows. Measured with bench/novel_view_e2e (3 held-out motions x 4
// wardrobes): mean PSNR90 22.15 -> 22.34 dB fitting the body's own model
// (+0.55 dB at best on a take, -0.03 at worst), 18.48 -> 18.53 dB with the
// procedural model, 24.19 -> 24.63 dB on the true geometry; on the take of
// tests/body_fidelity_test.cc 25.37 -> 25.29 dB.
#pragma once

#include <functional>
#include <vector>

#include <Eigen/Core>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "common/base/image.h"
#include "common/base/progress.h"
#include "common/model/reenactment.h"
#include "server/recon/take_frames.h"

namespace reenact::recon {

struct AtlasOptions {
  int size_px = 1024;                    // Atlas side, pixels.
  double visibility_threshold_m = 0.10;  // T (thesis: 10 cm).
  int every = 2;                         // Use every k-th instant.
  int colour_denominator = 2;            // Decode colour at 1/k (1, 2, 4, 8).
  // Observations are weighted by cos^p of the angle between the view ray
  // and the surface normal.
  double frontality_power = 2.0;
  // Beyond the thesis's test: a texel is used only where the sensor's own
  // actor depth lies within this distance of it (0: off), so that a
  // surface the fit placed slightly wrong, or one behind a hand within T,
  // does not take another surface's colour. Measured on a MakeHuman take
  // (CMU 131_01): PSNR90 24.25 dB without, 24.58 dB with 2 cm.
  double measured_threshold_m = 0.02;
  absl::Status Validate() const;
};

struct AtlasResult {
  RgbImage atlas;
  double observed_fraction = 0.0;  // Of the atlas's surface texels, seen at least once.
  int views = 0;                   // (instant, sensor) images used.
};

// The weighted colour sums of an atlas before it is finished: per texel
// (row-major, size_px x size_px) r, g, b times the observations' weights,
// and the sum of the weights. Sums of instants baked apart (segments of a
// take on different workers) add up to those of the whole take.
struct AtlasSums {
  int size_px = 0;
  int views = 0;  // (instant, sensor) images summed.
  std::vector<Eigen::Vector4f> sums;
};

// The sums of the instants in [first, end) (end < 0: the take's end) that
// are multiples of options.every; errors as BakeBodyAtlas.
absl::StatusOr<AtlasSums> AccumulateBodyAtlas(const TakeFrames& take, const BodyMesh& mesh,
                                              const std::vector<Eigen::Matrix3Xd>& posed_vertices_m,
                                              const AtlasOptions& options = {},
                                              const ProgressCallback& progress = {}, int first = 0,
                                              int end = -1);

// Adds `part` to `total` (empty `total`: becomes `part`). InvalidArgument
// for sums of different sizes.
absl::Status AddAtlasSums(const AtlasSums& part, AtlasSums& total);

// The atlas of the sums: each texel the weighted average of its
// observations, unobserved texels filled from the nearest observed ones
// (push-pull). InvalidArgument for sums of a bad size.
absl::StatusOr<AtlasResult> FinishBodyAtlas(const BodyMesh& mesh, AtlasSums sums);

// Bakes the atlas of `mesh` (its texture vertices, UVs and triangles) posed
// per instant as `posed_vertices_m[i]` (3 x V; an empty matrix skips the
// instant). InvalidArgument for bad options or sizes; errors of the take's
// decoders; Cancelled when `progress` returns false (stage "texture").
absl::StatusOr<AtlasResult> BakeBodyAtlas(const TakeFrames& take, const BodyMesh& mesh,
                                          const std::vector<Eigen::Matrix3Xd>& posed_vertices_m,
                                          const AtlasOptions& options = {},
                                          const ProgressCallback& progress = {});

// Per-frame appearance: the atlas of every instant from what the sensors saw
// at that instant. The thesis keeps per-frame colours per triangle for the
// triangles seen at an instant and the sequence's average for the others
// (4.4); here every texel of instant i blends
//   * the observations of instants i-w .. i+w (temporal weight 2^-|k|),
//     each weighted as in the static atlas (cos^p of the angle to the
//     normal, the visibility and measured-surface tests) and, beyond the
//     thesis, ramped down near the posed mesh's silhouette and occlusion
//     edges in the sensor's image, where the fit's small misplacements put
//     the lookup on another surface or the background;
//   * the static atlas, with the weight of `prior_weight` frontal
//     observations, so that a texel no sensor sees at an instant shows the
//     static atlas and one seen squarely shows that instant's colour,
//     with a smooth passage between the two (no seam where a sensor's view
//     ends).
// A turning limb's shading and a shirt's folds thus follow the performance,
// which one static atlas cannot hold.
struct AppearanceOptions {
  int size_px = 512;             // Side of each instant's atlas, pixels.
  int window = 1;                // w: instants either side blended in.
  double prior_weight = 0.1;     // Of the static atlas, in frontal observations.
  double edge_falloff_px = 4.0;  // Ramp width at image edges, decoded colour pixels.
  absl::Status Validate() const;
};

struct AppearanceFigures {
  int frames = 0;
  // Mean over frames of the share of surface texels observed in the frame's
  // window (the rest show the static atlas).
  double mean_observed_fraction = 0.0;
};

// Calls `sink(i, atlas_i)` for every instant i of the take in order, with
// the per-frame atlas (size_px square; instants without a posed mesh get
// the static atlas resampled). `static_atlas` is the finished atlas
// (FinishBodyAtlas) of any size; `atlas_options` gives the visibility,
// measured-surface, frontality and colour-scale settings. Errors as
// BakeBodyAtlas, and those `sink` returns; Cancelled when `progress`
// returns false (stage "appearance").
absl::Status BakeBodyAppearance(
    const TakeFrames& take, const BodyMesh& mesh,
    const std::vector<Eigen::Matrix3Xd>& posed_vertices_m, const RgbImage& static_atlas,
    const AtlasOptions& atlas_options, const AppearanceOptions& options,
    const std::function<absl::Status(int instant, const RgbImage& atlas)>& sink,
    const ProgressCallback& progress = {}, AppearanceFigures* figures = nullptr);

// BakeBodyAppearance encoded as an H.264 video (MPEG-4 part 2 where
// libavcodec has no H.264 encoder) at constant rate factor `crf`, one key
// frame a second, into `mesh`'s appearance fields (AppearanceVideo). Errors
// as BakeBodyAppearance and VideoWriter.
absl::Status BakeAppearanceVideo(const TakeFrames& take,
                                 const std::vector<Eigen::Matrix3Xd>& posed_vertices_m,
                                 const RgbImage& static_atlas, const AtlasOptions& atlas_options,
                                 const AppearanceOptions& options, int crf, BodyMesh* mesh,
                                 const ProgressCallback& progress = {},
                                 AppearanceFigures* figures = nullptr);

}  // namespace reenact::recon
