// The method "body" (thesis ch. 4): per instant the merged point cloud of all
// sensors (body_cloud.h), the fit of the statistical body model with one
// shape for the take (body_fit.h), and the atlas (body_texturing.h); the
// result is a body-model reenactment (common/io/body_reenactment.h).
//
// Options (strings, as submitted with the job; BodyMethodOptions::Read):
//   model              "procedural" (default) or "makehuman:NAME", NAME a
//                      folder under the server's asset roots (model_spec.h)
//   point_weight       w_z of Eq. 4.7 (1)
//   smoothness_weight  w_r of Eq. 4.7 (0.001; see body_fit.h)
//   skeleton_weight    the sensors' skeleton prior (0.1)
//   shape_frames       instants the shape is fitted on (5)
//   rounds, iterations correspondence rounds and LM iterations per frame (3, 5)
//   max_points         points per round (1200)
//   refine_vertices    the free-form mesh step (true)
//   hypotheses         start each frame from several poses and keep the fit
//                      that explains the points best (true; body_fit.h)
//   explained_m        a point this near the body is explained (0.03)
//   look_ahead         frames the forward pass could not fit or fitted
//                      doubtfully are fitted again backwards from the frames
//                      after them (true; body_method.cc, FitBackward)
//   atlas_px           atlas side (1024)
//   visibility_m       T of thesis 4.4 (0.10)
//   texture_every      use every k-th instant for the atlas (2)
//   texture_scale      decode colour at 1/k for the atlas (2: 960x540 of 1080p)
//   texture_sharpness  p of the cos^p frontality weight of observations (2)
//   measured_m         texels must lie this near the sensor's own depth (0.02;
//                      0: the thesis's test alone)
//   segment_warmup_s   a take split across workers: how long before its first
//                      instant each segment's fit starts (1 s)
//
// One take across several workers (a job's segments > 1; the scheduler's
// segmented jobs): PrepareBody fits the shape once from instants spread over
// the whole take, exactly as RunBody chooses and fits them; FitBodySegment
// fits the instants of one segment with that shape, each from the previous
// fit as RunBody does, starting segment_warmup_s earlier so that the motion
// is carried into the segment (thesis Eq. 4.6 needs the previous frame's
// pose; a segment that started cold from the skeleton would differ from the
// whole run in its first frames), and sums its instants' share of the
// atlas; StitchBody adds the atlas sums (the atlas is a weighted average,
// so sums made apart add up to the whole take's), fills and encodes the
// atlas, and assembles the frames. The result equals RunBody's within the
// tolerances body_segments_test checks.
//
// Figures of how well the fits explain what the sensors saw (in the
// reenactment's figures, `reenact reenactments show`): explained_fraction
// (the mean share of each instant's points within explained_m of the
// fitted body), unexplained_frames (fits explaining under half of their
// points: kept, but marked invalid, so that viewers and the mirror treat
// them as unknown) and hypothesis_<start> (how many kept fits started from
// each hypothesis of bodyfit::FitNext: follow_skeleton, previous,
// arms_swapped, legs_swapped, skeleton).
//
// The diagnosis (body_diagnosis.h): every fitted frame carries, per sensor
// that saw it, how well its fit explains that sensor's view
// (BodyPose.sensor_fits: points, share explained, their RMS, share of the
// fitted surface facing the sensor that the sensor saw;
// bodyfit::BodyFitter::DiagnoseFit); the figures give each sensor's means
// ("sensor.ID.explained_fraction", "sensor.ID.rms_mm",
// "sensor.ID.surface_seen_fraction") and the doubtful frames; and the
// reenactment lists the spans of frames a sensor contradicts
// (ReenactmentInfo.doubtful_spans, with the reason), which
// `reenact jobs show` prints.
#pragma once

#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "common/base/progress.h"
#include "common/body/body_model.h"
#include "common/bodyfit/body_fit.h"
#include "common/model/reenactment.h"
#include "server/recon/body/body_texturing.h"
#include "server/recon/method_util.h"
#include "server/recon/reconstruction_method.h"
#include "server/recon/take_frames.h"

namespace reenact::recon {

// The method's options, read by key (the list above).
struct BodyMethodOptions {
  // "makehuman:NAME" is looked up in MethodContext::asset_roots (the
  // server's --assets folders; a client names no server path).
  std::string model = "procedural";
  bodyfit::BodyFitOptions fit;
  AtlasOptions atlas;
  // Per-frame appearance (body_texturing.h), stored as an H.264 video in
  // the reenactment (AppearanceVideo); off: the static atlas alone.
  bool appearance = true;
  AppearanceOptions appearance_options;
  int appearance_crf = 23;  // H.264 constant rate factor of that video.
  double segment_warmup_s = 1.0;
  bool look_ahead = true;
  // InvalidArgument naming the key for a value that does not parse or lies
  // outside its bounds.
  absl::Status Read(OptionReader& reader);
  // InvalidArgument for a model that is no asset name, or bad fit or atlas
  // options.
  absl::Status Validate() const;
  // The method's own share of a job's memory (memory_estimate.h): the
  // model, its posed mesh at every instant, the shape's clouds and the
  // atlas.
  int64_t MemoryBytes(const TakeSize& take) const;
};

// The frame of one fitted instant: its body pose (with the offsets of step
// 2 when present), point RMS, valid flag and fitted joints.
ReenactmentFrame BodyFrame(int frame_index, int64_t stamp_ns, const bodyfit::FrameFit& fit,
                           bool valid);

// Runs the method on a loaded take. InvalidArgument for options that fail
// Validate() or a take without a usable instant (no skeleton with a torso
// and no points); NotFound for a model name the context's asset roots do
// not hold; Cancelled when the context's progress returned false.
absl::StatusOr<Reenactment> RunBody(const TakeFrames& take, const BodyMethodOptions& options = {},
                                    const MethodContext& context = {});

// The phases of a run split across workers (see above); the bytes are
// serialised v1::BodyShapePart and v1::BodySegmentPart
// (proto/reenact/v1/segments.proto). Errors as RunBody; InvalidArgument for
// a segment that does not exist, parts of another take or model, or
// segments that do not tile the take; DataLoss for parts that do not parse.
absl::StatusOr<std::string> PrepareBody(const TakeFrames& take, const BodyMethodOptions& options,
                                        const MethodContext& context = {});
absl::StatusOr<std::string> FitBodySegment(const TakeFrames& take, const BodyMethodOptions& options,
                                           const MethodContext& context,
                                           const std::string& prepared, int index, int count);
absl::StatusOr<Reenactment> StitchBody(const TakeFrames& take, const BodyMethodOptions& options,
                                       const MethodContext& context, const std::string& prepared,
                                       const std::vector<std::string>& segments);

// What each phase decodes (ReconstructionMethod::Needs): prepare every
// instant's depth (the shape's instants are chosen by their clouds),
// segment K the depth from its warm-up on and the colour of the atlas's
// instants in it, the stitch no image at all.
absl::StatusOr<TakeNeeds> BodyNeeds(const TakeFrames& take, const BodyMethodOptions& options,
                                    MethodPhase phase, int index, int count);

// The method "body" for the registry (registry.cc); it can follow a take
// live (live_body.h, LiveBodyOptions).
const ReconstructionMethod& BodyMethod();

}  // namespace reenact::recon
