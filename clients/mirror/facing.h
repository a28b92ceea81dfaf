// Which way a person faces, when a learner holds still, and how far to turn
// the teacher so that it faces the viewer the way the learner faces the
// mirror.
//
// Thesis sec. 4.5.1: the mirror uses "the learner's shoulders' position [to]
// compute the learner's direction", rotates the reenactment "in the same way,
// so that the reenactment and the learner are facing the same way", fixes the
// rotation "after a fixed amount of time" and starts playing; once the action
// has played it "resets and the learner can adjust his or her facing again".
//
// Facing yaw, the one convention used throughout:
//   A person's forward is the horizontal direction out of their chest,
//   computed as left x up with left = ShoulderRight -> ShoulderLeft (or
//   HipRight -> HipLeft when a shoulder is missing) made horizontal. A facing
//   yaw is the angle from a reference direction to that forward, about the
//   up axis by the right-hand rule: POSITIVE = COUNTER-CLOCKWISE SEEN FROM
//   ABOVE = the person has turned to THEIR OWN LEFT. Degrees in (-180, 180].
//   - In a sensor or camera frame (OpenCV: x right, y down, z forward) the
//     reference is the direction from the person back toward the sensor (the
//     optical axis reversed, -z, made horizontal): yaw 0 faces the sensor,
//     +90 has turned to their left and shows the sensor their right side
//     (their forward is then +x, image right before any flip), 180 shows
//     their back. The optical axis, not the ray to the person, is the
//     reference: it is the normal of the mirror, as with a real mirror.
//   - In world (+Y up) the reference is +Z: yaw 0 faces +Z, +90 faces +X.
//
// The teacher turn and the mirror flip. The app films the learner with the
// mirror's sensor and shows the colour image flipped left-right. It renders
// the teacher with a virtual camera that stands to the teacher as the sensor
// stands to the learner, and flips that render left-right too. Both pictures
// are made the same way (a camera, then a flip), so they match exactly when
// the teacher stands to the virtual camera as the learner stands to the
// sensor: the teacher's facing yaw relative to the virtual camera must EQUAL
// the learner's facing yaw relative to the sensor, same sign, no negation.
// Then a learner at +90 (turned to their left, right side toward the screen)
// sees, like in a real mirror, their reflection facing toward their own left
// and showing their right side, and beside it the teacher also facing that way
// and showing its right side, right hand on the same side of the screen as the
// learner's right hand. The two flips cancel in the comparison; the flip
// would matter only if one image were flipped and not the other (an unflipped
// teacher would need -90 to look turned the same way, and would then show its
// left side where the learner shows their right).
#pragma once

#include <cstdint>
#include <deque>
#include <optional>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "common/body/joint_set.h"

namespace reenact::mirror {

// Wraps an angle to (-180, 180] degrees.
double WrapDeg180(double angle_deg);

// Circular mean of angles in degrees, in (-180, 180]; nullopt for an empty
// list or angles that cancel out (resultant length under 1e-9 per sample).
std::optional<double> CircularMeanDeg(const std::vector<double>& angles_deg);

// "Up" in a level sensor's OpenCV frame: -y. A tilted sensor passes its own
// (e.g. the negated normal of the floor plane the tracker reports).
Eigen::Vector3d LevelSensorUp();

// The person's forward made horizontal (perpendicular to `up`), unit length,
// in the skeleton's frame. Uses the shoulder line, else the hip line; nullopt
// when neither pair is usable or the line's horizontal part is under 5 cm.
std::optional<Eigen::Vector3d> HorizontalForward(const body::SkeletonPose& pose,
                                                 const Eigen::Vector3d& up);

// Facing yaw of a skeleton given in a sensor's OpenCV frame (see the
// convention above). `up_in_sensor` need not be unit length. nullopt as for
// HorizontalForward, or when the optical axis is vertical.
std::optional<double> FacingYawInSensorDeg(const body::SkeletonPose& pose_in_sensor,
                                           const Eigen::Vector3d& up_in_sensor = LevelSensorUp());

// Facing yaw of a skeleton in world (+Y up; 0 faces +Z, +90 faces +X).
std::optional<double> FacingYawInWorldDeg(const body::SkeletonPose& pose_in_world);

// Applies `b_from_a` to every joint; validity flags are kept.
body::SkeletonPose TransformPose(const Eigen::Isometry3d& b_from_a,
                                 const body::SkeletonPose& pose_in_a);

struct SteadinessOptions {
  // Every sample of the held window lies within +-tolerance_deg of the
  // window's circular mean. Must be in (0, 90).
  double tolerance_deg = 10.0;
  // How long (seconds) the facing must stay within the tolerance. Must be
  // >= 0 and finite.
  double hold_s = 2.0;
  // Each sample is first replaced by the circular mean of the facings of
  // the last smoothing_s seconds: a tracker's facing jitters by several
  // degrees from frame to frame, most when the learner stands side on and
  // one shoulder is hidden (the Kinect v2 model of the synthetic takes:
  // 3 cm per axis on inferred joints, about 7 degrees on a 35 cm shoulder
  // line), which would keep a raw window from ever holding within +-10
  // degrees. Costs up to smoothing_s of lag after a turn. >= 0 and finite;
  // 0 uses the raw facings.
  double smoothing_s = 0.5;

  absl::Status Validate() const;
};

struct SteadinessStatus {
  // True once the held window spans at least hold_s.
  bool steady = false;
  // Span of the held window, seconds (0 after a reset).
  double held_s = 0.0;
  // Circular mean of the held window, degrees; the locked facing once steady.
  std::optional<double> mean_yaw_deg;
};

// Decides when a facing has been held still (thesis sec. 4.5.1: "after a fixed
// amount of time, the system fixes the rotation"). Feed one sample per frame.
// Samples are smoothed over smoothing_s; the held window is the longest run
// of recent smoothed samples that all lie within the tolerance of their
// circular mean (so a turn drops the samples before it), trimmed to the
// last hold_s. Angles wrap at +-180. Deterministic: time comes only from the
// stamps.
class SteadinessDetector {
 public:
  // InvalidArgument for invalid options.
  static absl::StatusOr<SteadinessDetector> Create(const SteadinessOptions& options);

  // Adds a sample. A missing or non-finite yaw, or a stamp earlier than the
  // previous one, restarts the detector (the sample then starts the new
  // window when it has a yaw).
  const SteadinessStatus& Add(int64_t stamp_ns, std::optional<double> yaw_deg);

  // Forgets every sample.
  void Reset();

  const SteadinessStatus& status() const { return status_; }

 private:
  struct Sample {
    int64_t stamp_ns;
    double yaw_deg;
  };
  explicit SteadinessDetector(const SteadinessOptions& options) : options_(options) {}
  bool WithinTolerance() const;
  void UpdateStatus();

  SteadinessOptions options_;
  std::deque<Sample> raw_;  // The last smoothing_s of raw samples.
  std::deque<Sample> window_;
  SteadinessStatus status_;
};

// Where the teacher stands and which way it faces in world.
struct TeacherFacing {
  // Mean SpineBase over the frames that have one, metres, world: the pivot of
  // the teacher turn.
  Eigen::Vector3d pivot_in_world = Eigen::Vector3d::Zero();
  // Circular mean of FacingYawInWorldDeg over the first `window_s` of the
  // action (the facing the learner copies before starting), degrees.
  double facing_yaw_world_deg = 0.0;
  // Frames whose facing went into the mean.
  int num_facing_frames = 0;
};

// Measures the teacher's pivot and start facing from its per-frame skeletons
// in world (`fps` frames a second). window_s <= 0 takes the facing over the
// whole action. InvalidArgument for fps <= 0 or no frame with a SpineBase or
// a facing in the window.
absl::StatusOr<TeacherFacing> MeasureTeacherFacing(
    const std::vector<body::SkeletonPose>& teacher_in_world, double fps, double window_s);

// world_from_camera (OpenCV convention) of a virtual camera placed like the
// mirror's sensor: horizontally `distance_m` from `target_in_world` in the
// direction `bearing_yaw_world_deg` (world yaw convention: 0 = +Z), at
// `height_m` above the floor (y = 0), looking at the target, with no roll
// (image x stays horizontal). Pass the teacher's facing yaw as the bearing to
// put the camera in front of the teacher. InvalidArgument for a non-positive
// or non-finite distance.
absl::StatusOr<Eigen::Isometry3d> PlaceVirtualCamera(const Eigen::Vector3d& target_in_world,
                                                     double bearing_yaw_world_deg,
                                                     double distance_m, double height_m);

// The rotation of the teacher about the vertical through its pivot.
struct TeacherTurn {
  // Rotation about world +Y, degrees in (-180, 180]; positive =
  // counter-clockwise seen from above.
  double turn_yaw_deg = 0.0;
  // The teacher's facing yaw relative to the virtual camera after the turn
  // (the requested view), degrees.
  double view_yaw_deg = 0.0;
  // Maps a teacher point in world to its turned place in world:
  // point_turned_in_world = turned_from_original * point_in_world.
  Eigen::Isometry3d turned_from_original = Eigen::Isometry3d::Identity();
};

// The turn that makes the teacher's facing relative to the virtual camera
// equal `view_yaw_deg` (same convention as FacingYawInSensorDeg). To follow
// the learner, pass the learner's facing yaw relative to the mirror's sensor
// unchanged (see "The teacher turn and the mirror flip" above):
//   turn = view_yaw + yaw_world(-camera forward, horizontal) - teacher facing.
// A camera in front of the teacher (PlaceVirtualCamera with the teacher's
// facing as bearing) gives turn = view_yaw. InvalidArgument when the
// camera looks straight up or down or view_yaw_deg is not finite.
absl::StatusOr<TeacherTurn> ComputeTeacherTurn(const TeacherFacing& teacher, double view_yaw_deg,
                                               const Eigen::Isometry3d& world_from_virtual_camera);

}  // namespace reenact::mirror
