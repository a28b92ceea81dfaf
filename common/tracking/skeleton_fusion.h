// Fusion of the skeletons that several sensors tracked of one person at one
// instant into one skeleton in the world frame (metres, +Y up).
//
// Three steps, per instant:
//  1. Left/right swaps. A tracker that sees a person from behind takes the
//     back for the front and labels the left limbs as right. For each limb
//     pair (LimbPair) the swap of every sensor is chosen jointly: the
//     assignment of "swapped / as labelled" to the sensors that makes their
//     joints (and the previous fused skeleton, when given) agree best under
//     a robust cost. Without a previous skeleton, swapping every sensor
//     agrees as well as swapping none; the tie goes to the labelling whose
//     facing (the left-to-right line crossed with up) agrees with where each
//     sensor's feet point, then to the fewest swaps.
//  2. Weights: confidence times a weight per state (tracked >> inferred);
//     not-tracked and non-finite joints are left out.
//  3. Per joint, a robust weighted mean: iteratively reweighted least squares
//     (Holland & Welsch, "Robust regression using iteratively reweighted
//     least-squares", Commun. Stat. Theory Methods 6(9), 1977) of the
//     M-estimator of location of Huber ("Robust estimation of a location
//     parameter", Ann. Math. Stat. 35(1), 1964), with the Cauchy (Lorentzian)
//     kernel by default: a joint 40 cm off the others' consensus (a lost
//     hand) keeps 1 % of its weight at a 4 cm scale, where Huber's kernel
//     keeps 10 % (both kernels as listed by Zhang, "Parameter estimation
//     techniques: a tutorial with application to conic fitting", Image Vis.
//     Comput. 15(1), 1997). With only two sensors that disagree, neither is
//     the consensus: the start of the iteration decides (see FuseSkeletons).
//
// Plain C++ and Eigen; no protobuf (the callers convert at their edges).
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <Eigen/Core>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "common/body/joint_set.h"
#include "common/geometry/transforms.h"
#include "common/tracking/tracking_types.h"

namespace reenact::tracking {

// The joint on the other side of the body: ShoulderLeft <-> ShoulderRight,
// ..., ThumbLeft <-> ThumbRight; joints on the midline (SpineBase, SpineMid,
// SpineShoulder, Neck, Head) are their own mirror.
body::KinectV2Joint MirrorKinectV2Joint(body::KinectV2Joint joint);

// Groups of left/right joints whose labels a tracker swaps together; the
// fusion decides a swap per sensor and per group.
enum class LimbPair : int {
  kShoulders = 0,  // ShoulderLeft/Right.
  kArms = 1,       // ElbowLeft/Right, WristLeft/Right.
  kHands = 2,      // HandLeft/Right, HandTipLeft/Right, ThumbLeft/Right.
  kHips = 3,       // HipLeft/Right.
  kLegs = 4,       // KneeLeft/Right, AnkleLeft/Right.
  kFeet = 5,       // FootLeft/Right.
};
inline constexpr int kNumLimbPairs = 6;

// "shoulders", "arms", "hands", "hips", "legs", "feet".
std::string_view LimbPairName(LimbPair pair);

// The left joints of `pair` (their mirrors are the right ones).
const std::vector<body::KinectV2Joint>& LimbPairLeftJoints(LimbPair pair);

// The most sensors one call fuses (the swap search visits 2^n labellings).
inline constexpr int kMaxFusionSensors = 10;

struct SkeletonFusionOptions {
  // Weight of a joint = confidence * the weight of its state. Tracked joints
  // lie on a surface the sensor sees; inferred ones are guesses, about 3x
  // noisier (the synthetic sensor's model), so 1/9 of the weight by inverse
  // variance.
  double tracked_weight = 1.0;
  double inferred_weight = 0.1;
  // Joints with a confidence below this are left out, in [0, 1).
  double min_confidence = 0.0;
  // Robust kernel of the per-joint mean and its scale, metres: residuals
  // well below the scale count fully, far beyond it hardly (Cauchy weight
  // 1 / (1 + (r / scale)^2); Huber weight min(1, scale / r)).
  enum class Kernel { kCauchy, kHuber };
  Kernel kernel = Kernel::kCauchy;
  double robust_scale_m = 0.04;
  // IRLS stops after this many reweightings, or once the estimate moves
  // less than `convergence_m` in one.
  int max_iterations = 20;
  double convergence_m = 1e-5;
  // Scale of the Cauchy cost that compares labellings in the swap search,
  // metres: larger than the joint noise, smaller than the distance between
  // left and right limbs (a shoulder width is about 0.35 m).
  double swap_scale_m = 0.10;
  // A labelling with swaps is chosen only when its cost is lower than the
  // labelling without them by more than this (a sum of Cauchy costs
  // log(1 + (d / swap_scale_m)^2) times the joints' weights; one tracked
  // joint pair 0.3 m off costs 2.3).
  double min_swap_gain = 0.5;
  // Weight of each joint of the previous fused skeleton in the swap search,
  // as if one more sensor had seen it (never swapped); 0 ignores it there.
  double previous_weight = 0.5;
  // SequentialSkeletonFusion: after this many instants in a row in which
  // the previous skeleton overruled every sensor's labelling of a limb pair
  // (each one swapped), the previous skeleton is taken to be the one that is
  // wrong (an early swap it would otherwise carry on for ever) and the
  // instant is fused from the sensors alone; 0: never.
  int max_overruled_instants = 3;
  // Fused joints keep "tracked" only where a tracked estimate kept at least
  // this share of its weight through the robust reweighting, in (0, 1].
  double inlier_weight_share = 0.5;

  // InvalidArgument naming the first bad field.
  absl::Status Validate() const;
};

// One sensor's skeleton of the person at the instant.
struct SensorSkeleton {
  std::string sensor_id;
  // The sensor's camera (whose frame the joints are in) in the world.
  Rigid3d world_from_camera;
  // Indexed by body::KinectV2Joint, in the camera frame (OpenCV axes).
  std::array<TrackedJoint, body::kNumKinectV2Joints> joints;
};

struct FusedJoint {
  Eigen::Vector3d position_in_world_m = Eigen::Vector3d::Zero();  // Zero when not tracked.
  // 1 - prod_k (1 - confidence_k * robust weight share_k) over the sensors
  // that saw the joint: the chance that at least one agreeing sensor is right.
  double confidence = 0.0;
  // Tracked when a tracked estimate survived the reweighting (see
  // inlier_weight_share), inferred when only other estimates did or none
  // survived, not tracked when no sensor had the joint.
  JointState state = JointState::kNotTracked;
  // Indices into the input of the sensors whose estimate kept at least
  // inlier_weight_share of its weight.
  std::vector<int> sensors;
};

struct FusedSkeleton {
  std::array<FusedJoint, body::kNumKinectV2Joints> joints;
};

// What the fusion did with one input sensor.
struct SensorFusionReport {
  std::string sensor_id;
  // False when the sensor's pose is not finite or none of its joints was usable.
  bool used = false;
  // Whether its left and right joints were swapped before fusing, per
  // LimbPair, and whether any pair was.
  std::array<bool, kNumLimbPairs> swapped_limbs{};
  bool swapped_left_right = false;
  // Facing agreement in [-1, 1]: the cosine between the facing its labels
  // imply and where its feet point; 0 when either is unknown.
  double facing_agreement = 0.0;
  int joints_used = 0;      // Finite, not "not tracked", confident enough.
  int joints_rejected = 0;  // Non-finite position or confidence.
  int joints_outlying = 0;  // Ended below inlier_weight_share of their weight.
};

struct SkeletonFusionSummary {
  FusedSkeleton skeleton;
  std::vector<SensorFusionReport> sensors;  // Parallel to the input.
  int num_tracked = 0;                      // Fused joints by state.
  int num_inferred = 0;
  int max_iterations_used = 0;  // Most IRLS iterations any joint took.
  bool used_previous = false;   // A previous skeleton took part in the swap search.

  // One line: joints by state, sensors used and swapped, outliers.
  std::string BriefReport() const;
};

// Fuses the skeletons of one instant, each given in its sensor's camera
// frame with the sensor's world_from_camera, into one world skeleton.
// `previous` (may be null): the fused skeleton of the instant before, which
// takes part in the swap search (and alone decides it for a single sensor).
// Each joint's iteration starts from the weighted mean or, when the
// estimates spread wider than three robust scales, from the weighted medoid
// (the estimate that agrees best with the others and with `previous`); two
// disagreeing estimates of equal weight and no previous skeleton keep the
// mean, and the joint comes out inferred with a low confidence.
// InvalidArgument for bad options, no sensors, or more than
// kMaxFusionSensors. Non-finite joints or poses are left out and counted,
// never an error; a skeleton of which nothing was usable comes back with
// every joint not tracked.
absl::StatusOr<SkeletonFusionSummary> FuseSkeletons(const std::vector<SensorSkeleton>& sensors,
                                                    const SkeletonFusionOptions& options = {},
                                                    const FusedSkeleton* previous = nullptr);

// FuseSkeletons over a sequence: each call hands the last fused skeleton to
// the next as `previous` while they are at most `max_gap_ns` apart.
class SequentialSkeletonFusion {
 public:
  explicit SequentialSkeletonFusion(SkeletonFusionOptions options = {},
                                    int64_t max_gap_ns = 250'000'000);

  // Fuses the instant at `stamp_ns` (any monotonic clock, nanoseconds).
  absl::StatusOr<SkeletonFusionSummary> Fuse(const std::vector<SensorSkeleton>& sensors,
                                             int64_t stamp_ns);
  // Forgets the previous skeleton (a cut, another person).
  void Reset() {
    previous_.reset();
    overruled_run_ = 0;
  }

 private:
  SkeletonFusionOptions options_;
  int64_t max_gap_ns_;
  std::optional<FusedSkeleton> previous_;
  int64_t previous_stamp_ns_ = 0;
  int overruled_run_ = 0;  // Instants in a row the previous overruled every sensor.
};

}  // namespace reenact::tracking
