// Synthetic takes: a body model performing a motion, seen by virtual Kinect v2
// sensors with a published noise model, written as an MCAP take with ground
// truth. The built-in teacher of Reenact, and the source of every accuracy
// figure measured against ground truth.
#pragma once

#include <cstdint>
#include <string>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "common/base/progress.h"
#include "common/geometry/transforms.h"
#include "common/synth/depth_noise.h"

namespace reenact::synth {

struct SynthOptions {
  // "builtin:NAME" (see BuiltinMotionNames) or a .bvh / .amc file.
  std::string motion = "builtin:arm-raise";
  // The ASF skeleton of an .amc motion.
  std::string asf_path;
  // A file motion's joint map (body::ReadJointMap: JSON of "their joint
  // name": "Kinect v2 joint name"), for namings the readers do not
  // recognise; empty: none. Not for builtin motions.
  std::string joint_map_path;
  // A file motion's length unit, metres per file unit, overriding the ASF
  // header or the BVH's stature detection; 0: the file's own. Within
  // [0, body::kMaxMetresPerUnit]; not for builtin motions.
  double metres_per_unit = 0.0;
  // "procedural" (built by our code) or "makehuman:DIR" (MakeHuman assets).
  std::string body = "procedural";
  // "mean", or "random" / "random:SEED": shape coefficients drawn from the
  // model's shape space (standard normal, clamped to +-2 sigma).
  std::string shape = "mean";
  // What the actor wears (synth::Wardrobe, clothing.h): "default" (striped
  // shirt, teal sleeves, checked denim), "solid", "print" or "stripes". It
  // is the albedo of the ground truth (/ground_truth/topology).
  std::string wardrobe = "default";
  int num_sensors = 2;             // 1..8, evenly spaced round the actor.
  double sensor_distance_m = 2.5;  // From the actor's starting position.
  double seconds = 10.0;           // Length of the take (clipped to a file motion's length).
  double fps = 30.0;               // Frame rate of every sensor.
  int color_width = 1920;          // Colour resolution (Kinect v2: 1920x1080).
  int color_height = 1080;
  int jpeg_quality = 90;           // 1..100.
  double color_noise_sigma = 2.0;  // Sensor noise of colour, 8-bit levels.
  DepthNoiseOptions depth_noise;   // Kinect v2 time-of-flight noise.
  // Whether each sensor's stream carries a skeleton. kNone (the default): it
  // carries none, as the depth cameras a user has (Kinect v1, OpenNI2,
  // Kinect v2 without its SDK), and the capture daemon's tracker makes them.
  // kTruth: the true joints as this sensor sees them plus skeleton_jitter_m,
  // a stand-in for a vendor SDK (for tests of what comes after tracking).
  // The true joints are always in the ground-truth channels.
  enum class SensorSkeleton { kNone, kTruth };
  SensorSkeleton sensor_skeleton = SensorSkeleton::kNone;
  double skeleton_jitter_m = 0.01;  // Noise of the kTruth "sensor skeleton", per axis.
  // A tracker made worse on purpose (kTruth only), the same error in every
  // sensor's skeleton at an instant, as a tracker's fused skeleton has it:
  // Gaussian noise of `limb_noise_m` per axis on elbows, wrists, hands,
  // knees, ankles and feet; the left and right arms swapped in
  // `arm_swap_fraction` of the frames (chosen at random); the left leg
  // (knee, ankle, foot) not tracked for `leg_drop_s` seconds in the middle
  // of the take; no joint tracked for the first `lock_on_s` seconds (a
  // tracker that has not found the body yet).
  struct SkeletonErrors {
    double limb_noise_m = 0.0;
    double arm_swap_fraction = 0.0;
    double leg_drop_s = 0.0;
    double lock_on_s = 0.0;
    bool any() const {
      return limb_noise_m > 0 || arm_swap_fraction > 0 || leg_drop_s > 0 || lock_on_s > 0;
    }
  };
  SkeletonErrors skeleton_errors;
  // The last sensor's stored calibration is this far off its true pose,
  // metres along world +X (a rig knocked after it was calibrated); what the
  // sensors see stays true. Within [0, 2].
  double calibration_error_m = 0.0;
  bool center_motion = true;  // Centre the motion's mean floor position on the origin.
  // Turns the whole performance about the vertical (+Y) through the world
  // origin (after centring), degrees, counter-clockwise seen from above: the
  // actor turns to their own left, so 90 makes a motion that faces +Z face
  // +X. The sensors stay where they are; finite, within [-360, 360].
  double yaw_deg = 0.0;
  // The performer stands still in the motion's first pose for this many
  // seconds before the motion starts (a learner getting ready in front of
  // the mirror); counted in `seconds`. Within [0, 3600).
  double lead_in_s = 0.0;
  // A printed board (common/board/board_spec.h, e.g. kDefaultBoardSpecText)
  // lying face up on the floor, drawn into the colour images so that the
  // capture daemon can anchor the sensors on it; empty: none. Its pose goes
  // to GroundTruthTopology.world_from_board.
  std::string board;
  // Where the board's centre lies on the floor, world metres. The default is
  // beside the actor (+X, 1 m from the origin), where every sensor of the
  // default rig sees it past the actor at 2.7 m; within 4 m of the origin.
  double board_x_m = 1.0;
  double board_z_m = 0.0;
  // Turn of the board about the vertical, degrees, counter-clockwise seen
  // from above (0: its columns along world +X); finite, within [-360, 360].
  double board_yaw_deg = 0.0;
  bool ground_truth_mesh = true;  // Write the posed mesh of every frame.
  uint64_t seed = 1;              // Every random draw follows from it.

  absl::Status Validate() const;
  // The board fields alone: InvalidArgument for a bad spec, position or yaw.
  absl::Status ValidateBoard() const;
};

// The pose of the board of `options` (SynthOptions.board) in the world: its
// centre at (board_x_m, 0, board_z_m), turned by board_yaw_deg about +Y.
Rigid3d WorldFromBoard(const SynthOptions& options);

struct SynthSummary {
  int frames = 0;  // FrameSets (instants) written.
  int sensors = 0;
  int body_vertices = 0;
  int body_shape_components = 0;
  double motion_scale = 1.0;  // Retargeting scale (model / motion leg length).
  int64_t file_bytes = 0;
  double elapsed_s = 0.0;  // Wall time of the synthesis.
  std::string renderer;    // GL_RENDERER / GL_VERSION of the context.
};

// Synthesises the take into `out_path` (replaced if present; written through
// a temporary name so a failed run leaves no partial take behind).
// `progress` may be empty; returning false from it cancels (Cancelled).
absl::StatusOr<SynthSummary> SynthesizeTake(const SynthOptions& options,
                                            const std::string& out_path,
                                            const ProgressCallback& progress = {});

}  // namespace reenact::synth
