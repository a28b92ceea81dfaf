// Fitting the statistical body model to merged point clouds (thesis 4.3).
//
// The thesis minimises, over all frames f (Eq. 4.7),
//   sum_f [ M(Y_f, Theta_f, v) + w_z P(Y_f) ] + w_r sum_f R(Theta_f, Theta_f+1)
// with M the model term (Eq. 4.4: the mesh's triangle edges against the
// model's prediction from pose and shape), P the point term (Eq. 4.5: each
// cloud point against its nearest mesh vertex, nearest in the normal-aware
// sense of Eq. 4.8), R the pose smoothness (Eq. 4.6: squared Frobenius norm
// of the change of each part rotation) and one shape v for all frames. It
// alternates (coordinate descent) between the meshes Y_f, the poses and the
// shape, and needed 5 minutes per frame.
//
// We solve the same objective in two steps per frame:
//  1. Pose (and, on a few frames at the start, shape) with Ceres: the mesh is
//     tied to the model's prediction (Y_f = M(theta_f, beta), so M = 0) and the
//     point term, the smoothness to the previous frame and two priors are
//     minimised by Levenberg-Marquardt with analytic Jacobians of linear
//     blend skinning (body_model.h). Correspondences (Eq. 4.8) are found
//     again after each round, as in ICP.
//  2. The free-form mesh Y_f: with pose and shape fixed, Eq. 4.4 + w_z Eq. 4.5
//     is linear in Y_f (sparse linear least squares over the triangle edges
//     and the point correspondences), solved by a sparse Cholesky factor.
//
// Departures from the thesis, and why:
//  - Our model (procedural or MakeHuman, SMPL-style skinning) stands in for
//    TenBo; its prediction M(theta, beta) is the skinned shaped template, so
//    Eq. 4.4 compares Y_f's edges with the skinned template's edges.
//  - In step 1 the point term measures each point's distance along its own
//    normal (point-to-plane) to its Eq. 4.8 vertex instead of the full vector
//    (Eq. 4.5): with vertices about 1.5 cm apart the full vector ties the
//    surface to vertex positions and converges slowly in sliding directions.
//    Step 2 uses Eq. 4.5 as written.
//  - Frames are fitted one after another with the previous frame fixed (a
//    causal window of two instead of the thesis's sliding window of three),
//    so a take can be followed live (a job that has the whole take then
//    fits the frames this left unfitted or doubtful again backwards, from
//    the frames after them: body_method.cc, FitBackward); the shape is
//    fitted jointly over a few
//    frames spread over the take (or the first frames when live) and then
//    held, which is the thesis's "one shape for all frames".
//  - Eq. 4.6 is applied to the joints' local rotations (relative to their
//    parents), the parameters our model is posed by.
//  - Two priors the thesis does not have: the sensors' skeleton (joint
//    positions, weak; it also initialises the first frame) keeps limbs that
//    no sensor sees in place, and a Gaussian prior on the shape
//    coefficients keeps the shape inside the population.
//  - A robust (Huber) loss on the point term, since masks and depth edges
//    leave stray points.
//  - Step 1 uses a deterministic subset of the points per round, weighted
//    by the cloud's size over the subset's so that the term still stands
//    for the sum over every point of Eq. 4.5.
//  - Each frame starts from the previous frame's pose carried to the
//    current skeleton (FollowSkeleton), not from the previous pose alone:
//    at 15 fps a dance moves limbs by 10 cm between frames, beyond the
//    reach of nearest-vertex correspondences.
//  - A tracker's skeleton can be wrong where the sensors see the body (an
//    arm or a leg swapped left for right, a limb off by decimetres), and a
//    fit started from it stays wrong: nearest-vertex correspondences cannot
//    move an arm across the body. So FitNext starts from several poses
//    (hypotheses: the previous fit carried to the skeleton, the previous
//    fit as it was, the skeleton with its arms or its legs swapped, the
//    skeleton alone), scores each by how much of the cloud it explains
//    (ExplainPose: a truncated point-to-plane cost, unexplained points at
//    the truncation), fits the two best and keeps the fit that explains the
//    cloud best. Where sensors see the body the points decide; the
//    skeleton still places what no sensor sees. A swapped start is made
//    only for a limb whose sides the skeleton may have swapped since the
//    previous fit (its left joints about as near the previous right ones as
//    the left ones), so a frame whose limbs kept their sides costs little
//    more than one start.
#pragma once

#include <array>
#include <functional>
#include <memory>
#include <optional>
#include <vector>

#include <Eigen/Core>
#include <Eigen/SparseCholesky>
#include <Eigen/SparseCore>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "common/body/body_model.h"

namespace reenact::bodyfit {

// A merged point cloud of one instant, world frame (metres), with unit
// normals facing the sensor that saw each point.
struct PointCloud {
  std::vector<Eigen::Vector3f> points_m;
  std::vector<Eigen::Vector3f> normals;
  // Which sensor saw which points: points [begin, end) of each range came
  // from `sensor` (the take's sensor index), ranges in order; empty when
  // unknown.
  struct SensorRange {
    int sensor = 0;
    size_t begin = 0;
    size_t end = 0;
  };
  std::vector<SensorRange> sensor_ranges;
  size_t size() const { return points_m.size(); }
};

struct BodyFitOptions {
  // w_z of Eq. 4.7: weight of the point term against the model term (step 2)
  // and against the smoothness (step 1). Thesis: 1.
  double point_weight = 1.0;
  // w_r of Eq. 4.7: weight of the pose smoothness (Eq. 4.6). The thesis
  // uses 0.05, but the balance of Eq. 4.7 depends on the units and the
  // number of points: with points in metres and a two-sensor cloud of about
  // 10^4 points, 0.05 holds a fast dance (CMU 131_01 at 15 fps) back by
  // centimetres (MPJPE 14.8 mm; 0.001: 3.6 mm; 0: 3.9 mm).
  double smoothness_weight = 0.001;
  // Weight of the skeleton prior per joint, 1/m^2 against the point term's
  // 1/m^2 per point (0: off).
  double skeleton_weight = 0.1;
  // Weight of the shape prior (sum of beta_k^2, standard deviations).
  double shape_prior_weight = 1e-4;
  // epsilon of Eq. 4.8 (> 1): how much normal agreement counts.
  double normal_epsilon = 1.5;
  // Correspondences farther than this, or whose normals disagree by more
  // than acos(min_normal_dot), are not used.
  double max_distance_m = 0.08;
  double min_normal_dot = 0.2;
  // Huber scale of the point term, metres.
  double huber_m = 0.02;
  // Points used per round (a deterministic subset of the cloud).
  int max_points = 1200;
  // Rounds (correspondences found anew) and Levenberg-Marquardt iterations
  // per round, per frame.
  int rounds = 3;
  int iterations_per_round = 5;
  // Shape: frames fitted jointly and rounds.
  int shape_frames = 5;
  int shape_rounds = 12;
  // Step 2, the free-form mesh Y_f.
  bool refine_vertices = true;
  // Correspondences of step 2 farther than this are not used, metres.
  double refine_max_distance_m = 0.03;
  // FitNext: a fit with a point RMS above this lost the body, mm.
  double lost_rms_mm = 25.0;
  // FitNext tries several starting poses and keeps the fit that explains
  // the cloud best (see the top of this file); false: the previous fit
  // carried to the skeleton, started again from the skeleton when that
  // lost the body (lost_rms_mm).
  bool hypotheses = true;
  // A point is explained when a model vertex lies within this distance
  // (metres); an unexplained point costs this much (ExplainPose).
  double explained_m = 0.03;

  absl::Status Validate() const;
};

// 25 Kinect v2 joints, metres, world frame; NaN where missing.
using SkeletonJoints = std::array<Eigen::Vector3d, body::kNumKinectV2Joints>;
SkeletonJoints NoSkeletonJoints();
// True when the skeleton has what PoseFromSkeleton needs: spine base and
// shoulder, and both hips or both shoulders.
bool HasTorso(const SkeletonJoints& skeleton_m);

// One instant to fit: its cloud and the sensors' skeleton.
struct FitInput {
  const PointCloud* cloud = nullptr;
  SkeletonJoints skeleton_m = NoSkeletonJoints();
};

struct FrameFit {
  body::BodyPose pose;
  Eigen::Matrix3Xd vertices_m;  // The model's prediction M(theta, beta), 3 x V.
  Eigen::Matrix3Xd offsets_m;   // Y_f - M (empty when step 2 is off).
  std::array<Eigen::Vector3d, body::kNumKinectV2Joints> joints_m;
  // RMS distance of the used points to their vertices' tangent planes, mm.
  double point_rms_mm = 0.0;
  int correspondences = 0;
  // How well the fit explains the cloud (ExplainPose, over the points the
  // RMS was measured on): the share of points within explained_m of a
  // vertex, and the mean truncated squared point-to-plane distance, m^2.
  double explained_fraction = 0.0;
  double explanation_cost = 0.0;
};

// How well a posed mesh explains a cloud: over `sample` points of the
// cloud (-1: all), each point's normal-aware nearest vertex (Eq. 4.8)
// within `explained_m`; an explained point costs its squared distance to
// the vertex's tangent plane, an unexplained one explained_m^2.
struct Explanation {
  int points = 0;
  int explained = 0;
  double cost = 0.0;  // Mean, m^2.
  double fraction() const { return points > 0 ? static_cast<double>(explained) / points : 0.0; }
};

// How well a fitted surface explains one sensor's view (BodyFitter::
// DiagnoseFit): its points within explained_m of a vertex (normal-aware,
// Eq. 4.8) and their RMS distance to the vertices' tangent planes; and the
// surface's vertices that face the sensor and are not hidden behind what it
// saw, with those it saw (one of its points within explained_m). A vertex
// whose line of sight holds no point of the sensor, or only points behind
// it, is not seen: the model claims a surface where the sensor saw none.
struct SensorDiagnosis {
  int sensor = 0;  // PointCloud::SensorRange::sensor.
  int points = 0;
  int explained = 0;
  double rms_mm = 0.0;  // Of the explained points.
  int facing_vertices = 0;
  int seen_vertices = 0;
  // The same surface as area (a third of each adjacent triangle per
  // vertex), m^2: a model's dense parts (face, fingers) count as much
  // surface as they are, not as many vertices as they have.
  double facing_area_m2 = 0.0;
  double seen_area_m2 = 0.0;
  double explained_fraction() const {
    return points > 0 ? static_cast<double>(explained) / points : 0.0;
  }
  // 1 when no surface faces the sensor within its view: nothing there
  // contradicts the fit.
  double surface_seen_fraction() const {
    return facing_area_m2 > 0 ? seen_area_m2 / facing_area_m2 : 1.0;
  }
};

// A sensor as DiagnoseFit needs it: its optical centre (world frame) and
// what its image holds (empty: everything), so that surface outside its
// field of view is not taken for surface it failed to see.
struct SensorView {
  Eigen::Vector3d centre_m = Eigen::Vector3d::Zero();
  std::function<bool(const Eigen::Vector3d& point_m)> sees;
};

// Where a frame's fit started from (BodyFitter::FitNext).
enum class Hypothesis {
  kFollowSkeleton,  // The previous fit carried to the skeleton.
  kPrevious,        // The previous fit as it was.
  kArmsSwapped,     // The previous fit carried to the skeleton, its arms swapped.
  kLegsSwapped,     // The same, its legs swapped.
  kSkeleton,        // The skeleton alone (PoseFromSkeleton).
};
inline constexpr int kNumHypotheses = 5;
const char* HypothesisName(Hypothesis hypothesis);

// The skeleton with its left and right arms (shoulder to hand tip and
// thumb), or legs (knee, ankle, foot), swapped.
SkeletonJoints SwapArms(const SkeletonJoints& skeleton_m);
SkeletonJoints SwapLegs(const SkeletonJoints& skeleton_m);

// Per-pose parameters as Ceres sees them: an angle-axis per joint (local
// rotation) and the root translation.
struct PoseParameters {
  std::array<Eigen::Vector3d, body::kNumKinectV2Joints> angle_axis;
  Eigen::Vector3d translation_m = Eigen::Vector3d::Zero();
  static PoseParameters FromPose(const body::BodyPose& pose);
  body::BodyPose ToPose() const;
};

class ModelData;    // Precomputed model arrays (body_terms.h).
struct ShapedRest;  // Rest vertices and joints of the current shape.

class BodyFitter {
 public:
  // InvalidArgument when the model or options do not validate.
  static absl::StatusOr<std::unique_ptr<BodyFitter>> Create(const body::BodyModel& model,
                                                            const BodyFitOptions& options = {});
  ~BodyFitter();

  const body::BodyModel& model() const { return model_; }
  const BodyFitOptions& options() const { return options_; }
  // The current shape (zeros until FitShape or set_shape).
  const Eigen::VectorXd& shape() const { return shape_; }
  absl::Status set_shape(const Eigen::VectorXd& shape);

  // A pose whose joints match the skeleton (root frame from the hips and
  // shoulders, then the skeleton term alone). FailedPrecondition when the
  // skeleton lacks the torso joints.
  absl::StatusOr<body::BodyPose> PoseFromSkeleton(const SkeletonJoints& skeleton_m) const;

  // The pose nearest to `start` whose joints match the skeleton (the
  // skeleton term alone, with `stay_weight` of Eq. 4.6 towards `start` for
  // what joint positions leave open: twists, hands, feet). Used to carry the
  // previous frame's fit to the current skeleton before the cloud fit.
  absl::StatusOr<body::BodyPose> FollowSkeleton(const body::BodyPose& start,
                                                const SkeletonJoints& skeleton_m,
                                                double stay_weight = 1e-3) const;

  // Fits one shape to several instants together, with a pose each (Eq. 4.7
  // without R: the instants are far apart). `poses` holds the initial poses
  // and receives the fitted ones.
  absl::Status FitShape(const std::vector<FitInput>& frames, std::vector<body::BodyPose>* poses);

  // FitShape from poses PoseFromSkeleton makes of each frame's skeleton.
  absl::Status FitShapeFromSkeletons(const std::vector<FitInput>& frames);

  // Where an instant's fit starts: `previous` (may be null) carried to the
  // skeleton when it has a torso (FollowSkeleton), `previous` itself when
  // it has not, the skeleton alone (PoseFromSkeleton) without a previous
  // fit; nullopt when there is neither.
  absl::StatusOr<std::optional<body::BodyPose>> InitialPose(const body::BodyPose* previous,
                                                            const SkeletonJoints& skeleton_m) const;

  // Fits one instant with the shape held: from `initial`, smooth towards
  // `previous` when given (Eq. 4.6), then step 2 when enabled.
  absl::StatusOr<FrameFit> FitFrame(const FitInput& input, const body::BodyPose& initial,
                                    const body::BodyPose* previous);

  // One instant of a sequence: FitFrame from InitialPose, started again from
  // the skeleton alone (PoseFromSkeleton) when the fit lost the body (point
  // RMS above lost_rms_mm: fast motion), keeping the better of the two.
  // nullopt when InitialPose has nothing to start from.
  struct SequenceFit {
    FrameFit fit;
    bool restarted = false;  // The fit kept is the one started from the skeleton.
    Hypothesis hypothesis = Hypothesis::kFollowSkeleton;  // Where the kept fit started.
  };
  absl::StatusOr<std::optional<SequenceFit>> FitNext(const FitInput& input,
                                                     const body::BodyPose* previous);

  // How well the model in `pose` (the current shape, no offsets) explains
  // `cloud` (Explanation; `sample` points spread over it, -1: all).
  Explanation ExplainPose(const body::BodyPose& pose, const PointCloud& cloud, int sample) const;

  // Per sensor range of `cloud`, how well `fit` (its prediction plus its
  // offsets) explains that sensor's points and view (SensorDiagnosis);
  // `sensors[s]` is sensor s. Ranges naming a sensor not in `sensors` are
  // left out.
  std::vector<SensorDiagnosis> DiagnoseFit(const FrameFit& fit, const PointCloud& cloud,
                                           const std::vector<SensorView>& sensors) const;

 private:
  // FitNext with hypotheses (options_.hypotheses, a previous fit and a
  // skeleton with a torso).
  absl::StatusOr<SequenceFit> FitHypotheses(const FitInput& input, const body::BodyPose& previous);
  // The posed vertices and their normals of `pose` (current shape).
  void PoseMesh(const body::BodyPose& pose, Eigen::Matrix3Xd* posed,
                Eigen::Matrix3Xd* normals) const;

  BodyFitter(const body::BodyModel& model, const BodyFitOptions& options);

  const body::BodyModel& model_;
  BodyFitOptions options_;
  Eigen::VectorXd shape_;
  std::unique_ptr<ModelData> data_;
  std::unique_ptr<ShapedRest> rest_;
  // Step 2: the edge Laplacian E^T E and its symbolic factorisation.
  bool refine_solver_ready_ = false;
  Eigen::SparseMatrix<double> laplacian_;
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> refine_solver_;
};

}  // namespace reenact::bodyfit
