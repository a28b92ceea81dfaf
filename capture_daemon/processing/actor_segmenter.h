// Segments the actor in the depth images of one static sensor, for sources
// that give no mask (Kinect v1, OpenNI2 devices; the Kinect SDK's body index
// that the thesis relied on, ch. 3 and 4, is not available to them).
//
// 1. Background model: every valid sample of the frames in the first
//    `background_seconds` is kept, and each pixel's background depth is a high
//    percentile of its samples (median-type background of depth cameras, as in
//    Stone and Skubic, "Evaluation of an inexpensive depth camera for passive
//    in-home fall risk assessment", PervasiveHealth 2011; the high percentile
//    rather than the median keeps the room behind an actor who is already in
//    view but moving). Pixels valid in fewer than a fifth of those frames have
//    no background.
// 2. Foreground: a valid pixel closer than its background by more than
//    max(min_margin_mm, noise_sigmas * sigma_z(background)), where sigma_z is
//    the axial noise of the sensor: Fankhauser et al., ICAR 2015 for Kinect v2
//    (sigma_z = 1.5 - 0.5 z + 0.3 z^2 mm at normal incidence, the model of
//    common/synth/depth_noise.h), Khoshelham and Oude Elberink, Sensors 2012
//    for Kinect v1 and structured-light devices (sigma_z = 1.425 z^2 mm, z in
//    m). A valid pixel without background is foreground.
// 3. Floor: the dominant plane whose normal lies within 40 degrees of "up" (the
//    world's +Y through world_from_depth when the sensor is placed, the
//    image's up direction otherwise) is found by RANSAC (Fischler and Bolles,
//    CACM 1981) on the background model's points and refined by least
//    squares; foreground points less than floor_distance_mm above it (or
//    below it) are dropped. Departure from fitting per frame: the floor does
//    not move, so it is fitted once, when the background model is complete
//    (or on the first frame when there is no background phase).
// 4. Body: 8-connected components (OpenCV connectedComponentsWithStats) of the
//    foreground after cutting it at depth discontinuities (neighbours more
//    than max(depth_step_mm, noise_sigmas * sigma_z) apart), so an actor
//    touching a closer or farther object is not merged with it; the largest
//    component is the actor (body index 1), with the cut pixels next to it
//    restored. Components smaller than min_body_fraction of the image are
//    ignored.
//
// During the background phase the masks are empty (all background).
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "common/base/image.h"
#include "common/geometry/camera.h"
#include "common/geometry/transforms.h"

namespace reenact::capture {

struct SegmenterOptions {
  // Length of the background phase, seconds of stream time (>= 0; 0: no
  // background model, every valid pixel is a candidate).
  double background_seconds = 1.0;
  // At most this many frames are kept for the model (later ones in the phase
  // are skipped).
  int max_background_frames = 90;
  // Percentile of a pixel's valid samples taken as its background, in (0, 1].
  double background_percentile = 0.75;
  // Foreground margin: max(min_margin_mm, noise_sigmas * sigma_z(z)).
  double min_margin_mm = 60.0;
  double noise_sigmas = 5.0;
  // Noise model: "kinect_v2" (time of flight) or anything else (structured
  // light, Kinect v1 model).
  std::string noise_model = "kinect_v1";
  // Points closer than this to the floor plane (or under it) are not actor.
  double floor_distance_mm = 30.0;
  // RANSAC inlier distance and iterations of the floor fit.
  double floor_inlier_mm = 25.0;
  int floor_iterations = 300;
  // Neighbouring pixels farther apart than max(depth_step_mm, noise_sigmas *
  // sigma_z) are not connected.
  double depth_step_mm = 80.0;
  // Smallest accepted body, fraction of the image's pixels.
  double min_body_fraction = 0.002;
  // Seed of the RANSAC draws (results are deterministic).
  uint64_t seed = 1;

  absl::Status Validate() const;
};

// A plane n . p + d = 0 in the depth camera frame, metres; n is unit and
// points up (away from the floor).
struct FloorPlane {
  Eigen::Vector3d normal = Eigen::Vector3d::UnitY();
  double offset_m = 0.0;
  int inliers = 0;  // Points of the fit within floor_inlier_mm.
};

class ActorSegmenter {
 public:
  // `intrinsics`: of the depth images to segment. `depth_from_world`: places
  // the sensor (identity when it is not placed). InvalidArgument for invalid
  // options or intrinsics.
  static absl::StatusOr<ActorSegmenter> Create(const CameraIntrinsics& intrinsics,
                                               const Rigid3d& world_from_depth,
                                               const SegmenterOptions& options);

  // The mask of `depth_mm` (0 background, 1 actor). `stamp_ns` is the frame's
  // stream time; frames within background_seconds of the first one build the
  // background model and get an empty mask. InvalidArgument when the size
  // does not match the intrinsics.
  absl::StatusOr<MaskImage> Segment(const DepthImageMm& depth_mm, int64_t stamp_ns);

  // True once the background phase is over.
  bool background_ready() const { return ready_; }
  // The floor, once found.
  const std::optional<FloorPlane>& floor() const { return floor_; }
  // Background depth per pixel (0: none), once ready.
  const DepthImageMm& background_mm() const { return background_mm_; }

  // Axial depth noise sigma in mm at `z_m` for `noise_model` (see the file
  // comment).
  static double AxialSigmaMm(const std::string& noise_model, double z_m);

 private:
  ActorSegmenter() = default;
  void BuildBackground();
  void FitFloor(const DepthImageMm& depth_mm);
  double MarginMm(double z_mm) const;

  CameraIntrinsics intrinsics_;
  SegmenterOptions options_;
  Eigen::Vector3d up_in_depth_ = -Eigen::Vector3d::UnitY();
  std::vector<Eigen::Vector2f> rays_;  // Undistorted (x/z, y/z) per pixel.
  bool started_ = false;
  int64_t first_stamp_ns_ = 0;
  bool ready_ = false;
  std::vector<DepthImageMm> samples_;
  DepthImageMm background_mm_;
  std::optional<FloorPlane> floor_;
  bool floor_tried_ = false;
};

}  // namespace reenact::capture
