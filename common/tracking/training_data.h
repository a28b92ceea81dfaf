// Training and test images for the body tracker, synthesised from motions and
// body models: a body posed by a retargeted motion frame, seen by a virtual
// depth camera placed at random round it, rasterised on the CPU into ideal
// depth and per-pixel body parts, then degraded by a sensor noise model
// (time of flight, common/synth/depth_noise.h, or structured light below).
//
// Body parts: a vertex belongs to the part of its most weighted skinning
// joint, so a part is the stretch of body a Kinect v2 joint moves (parts are
// numbered by body::KinectV2Joint). Shotton et al. (CVPR 2011) hand-painted 31
// parts; skinning gives ours for any body model, MakeHuman's included.
//
// Structured light (Kinect v1, OpenNI devices): depth is triangulated from a
// disparity measured in 1/8 pixel steps, so depth comes in steps of
// z^2 / (8 f b) (f b = 580 px * 0.075 m; Khoshelham and Oude Elberink,
// Sensors 2012), with axial noise sigma_z(z) = 0.0012 + 0.0019 (z - 0.4)^2 m
// (Nguyen, Izadi and Lovell, 3DIMPVT 2012); a projector shadow leaves no
// measurement beside depth edges instead of flying pixels.
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "common/base/image.h"
#include "common/base/progress.h"
#include "common/body/body_model.h"
#include "common/geometry/camera.h"

namespace reenact::tracking {

inline constexpr uint8_t kNoPart = 255;

// The part of every vertex of `model` (its most weighted skinning joint).
std::vector<uint8_t> VertexParts(const body::BodyModel& model);

struct TrainingDataOptions {
  // Motions (BVH, or AMC with `asf_paths` at the same index, "" for none).
  std::vector<std::string> motion_paths;
  std::vector<std::string> asf_paths;
  // Body models ("procedural", "makehuman:DIR"); each gets `shapes_per_body`
  // random shapes (the synthesiser's "random" draw).
  std::vector<std::string> bodies = {"procedural"};
  int shapes_per_body = 6;
  int num_images = 2000;
  // Camera distance from the actor and height above the floor, metres.
  double min_distance_m = 1.3;
  double max_distance_m = 4.0;
  double min_height_m = 0.5;
  double max_height_m = 1.7;
  // Share of images taken close up (0.8-1.3 m, upper body) and of images
  // whose camera looks past the actor so that the image border cuts them.
  double close_up_fraction = 0.08;
  double off_centre_fraction = 0.08;
  // Share of images degraded by the structured-light model (the rest: time
  // of flight).
  double structured_light_fraction = 0.4;
  // Share of images whose arms are posed at random in front of the body
  // (guards, crossed arms, hands at the face) instead of as the motion has
  // them; never in a sequence.
  double arm_pose_fraction = 0.3;
  // Frames of a motion between samples (motions are 30-120 fps).
  int frame_stride = 3;
  // A take instead of a shuffle: image i is the i-th sampled frame of the
  // first motion on the first actor, seen by one camera that stays put.
  bool sequence = false;
  // When set, every image is taken by this camera (its distortion ignored);
  // otherwise by a 512x424 Kinect v2 depth camera of a random focal length.
  std::optional<CameraIntrinsics> camera;
  uint64_t seed = 1;

  absl::Status Validate() const;
};

// One synthesised image, cropped to the person's bounding box.
struct TrainingImage {
  CameraIntrinsics intrinsics;  // Of the crop (principal point moved).
  // Depth of the person in metres, kBackgroundDepthM (body_part_forest.h) off
  // the person and where there is no measurement; width x height.
  FloatImage depth_m;
  std::vector<uint8_t> part;  // Per pixel: body part, kNoPart off the person.
  std::array<Eigen::Vector3d, body::kNumKinectV2Joints> joints_in_camera_m;
  // The uncropped image: noisy depth with the room (mm) and the person's
  // mask, kept only when asked (TrainingDataOptions are for the forest, the
  // full frames for end-to-end tests of the tracker).
  DepthImageMm full_depth_mm;
  MaskImage full_mask;
  CameraIntrinsics full_intrinsics;
};

// Options for `frames` consecutive frames of one motion (a BVH) seen by a
// fixed Kinect v2 camera `min_distance_m`..`max_distance_m` away, ToF noise
// only, no close-ups: a take-like sequence for tests and benchmarks.
TrainingDataOptions SequenceOptions(const std::string& motion_path, int frames,
                                    double min_distance_m, double max_distance_m, uint64_t seed);

// Synthesises `options.num_images` images (deterministic for a seed).
// `keep_full_frames` also keeps the uncropped noisy depth and mask.
absl::StatusOr<std::vector<TrainingImage>> SynthesizeTrainingImages(
    const TrainingDataOptions& options, bool keep_full_frames = false,
    const ProgressCallback& progress = {});

// The structured-light model of the file comment, applied to ideal depth in
// metres (0: nothing); deterministic for a seed.
DepthImageMm ApplyStructuredLightNoise(const FloatImage& ideal_depth_m, uint64_t seed);

}  // namespace reenact::tracking
