// Where the magic mirror's learner comes from (thesis sec. 4.5.1: one RGB-D
// sensor films the learner in front of the screen): a recorded take played at
// its own stamps, or a live capture daemon (live_learner_source.h). Either
// way the app pulls one frame at a time: its stamp, the tracked learner in
// the sensor's colour camera frame, and the colour image.
//
// Frames. Takes store skeletons in the sensor's DEPTH camera frame
// (sensor.proto Joint.position_in_depth_m, OpenCV axes); the mirror draws on
// the colour image and reads the facing relative to the colour camera, so
// every source converts them with the calibration's color_from_depth.
//
// Clock. A frame's stamp is its exposure time on the take's host timeline,
// device_stamp_ns + clock_offset_ns (sensor.proto), which is steadier than
// the arrival stamp (host_stamp_ns carries the transfer latency); the host
// stamp is used where a message has no device stamp.
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "absl/status/statusor.h"
#include "common/base/image.h"
#include "common/body/joint_set.h"
#include "common/geometry/camera.h"
#include "common/geometry/transforms.h"
#include "reenact/v1/sensor.pb.h"

namespace reenact::mirror {

// One frame of the learner.
struct LearnerFrame {
  // Exposure time, nanoseconds on the source's clock (see the top).
  int64_t stamp_ns = 0;
  // A live frame: when it reached the capture host (its host_stamp_ns, the
  // host's wall clock), for the learner-to-screen latency; 0 when unknown.
  int64_t host_stamp_ns = 0;
  // The tracked learner in the sensor's colour camera frame (OpenCV: x right,
  // y down, z forward; metres; joints labelled with the person's own sides,
  // not mirrored); nullopt when nobody is tracked.
  std::optional<body::SkeletonPose> skeleton_in_color;
  // Per joint of skeleton_in_color: seen by the sensor (TRACKED), as opposed
  // to inferred (hidden or outside the view); all false without a skeleton.
  std::array<bool, body::kNumKinectV2Joints> joint_seen{};
  // How many people the tracker found in the frame (bodies with a usable
  // joint); the learner is the one ChooseLearnerSkeleton picks.
  int people_in_view = 0;
  // The colour image (sRGB, top row first); nullopt when the frame has none
  // or it did not decode.
  std::optional<RgbImage> color;
};

// What a source knows about its sensor.
struct LearnerSensor {
  std::string sensor_id;
  // Intrinsics of the colour camera at its calibrated size; an image of
  // another size is the same camera resampled (ScaledIntrinsics).
  CameraIntrinsics color_intrinsics;
  // Against gravity, in the colour camera frame, unit length.
  Eigen::Vector3d up_in_color{0.0, -1.0, 0.0};
  // Nominal frame rate, frames per second (> 0).
  double nominal_fps = 30.0;
  // Frames arrive in real time (a live daemon); false: a recording that the
  // app may pace by its stamps.
  bool live = false;
};

class LearnerSource {
 public:
  virtual ~LearnerSource() = default;

  virtual const LearnerSensor& sensor() const = 0;
  // The next frame, stamps non-decreasing; nullopt once the stream has
  // ended. An error ends the stream (the message says what failed).
  virtual absl::StatusOr<std::optional<LearnerFrame>> Next() = 0;
  // E.g. "take /data/kick.mcap, sensor k0", for messages.
  virtual std::string Describe() const = 0;
  // Frames dropped because the app fell behind a live stream.
  virtual int64_t frames_dropped() const { return 0; }
};

// The colour camera's pose relative to the depth camera. A sensor with no
// colour camera (a depth-only recording: colour intrinsics of size 0) has
// its depth camera stand in for it: identity.
absl::StatusOr<Rigid3d> LearnerColorFromDepth(const v1::SensorCalibration& calibration);

// The learner sensor of a calibration (the depth camera standing in for the
// colour camera of a depth-only sensor, as LearnerColorFromDepth): its colour intrinsics and fps,
// and up as the world's +Y seen from the colour camera when the calibration's world is plausibly
// gravity-aligned (that up within 45 degrees of a level sensor's -y); otherwise (e.g. a world that
// is just the depth camera's frame) a level sensor's up. InvalidArgument for bad intrinsics or
// poses.
absl::StatusOr<LearnerSensor> LearnerSensorFromCalibration(
    const v1::SensorCalibration& calibration);

// The learner among the skeletons tracked in one frame, in the colour camera
// frame (color_from_depth * position_in_depth_m): the body with the most
// usable joints, ties to the nearest SpineBase. Joints are taken by name
// (Kinect v2 names; by position in the list when unnamed); a joint that is
// NOT_TRACKED or not finite is invalid. nullopt when no body has a usable
// joint.
std::optional<body::SkeletonPose> LearnerSkeletonInColor(
    const std::vector<const v1::Skeleton*>& skeletons, const Rigid3d& color_from_depth);

// The same skeleton with, per joint, whether the sensor saw it (its state is
// TRACKED rather than INFERRED).
struct LearnerSkeleton {
  body::SkeletonPose pose;
  std::array<bool, body::kNumKinectV2Joints> seen{};
  // Bodies in the frame with a usable joint (>= 1).
  int people = 1;
};
std::optional<LearnerSkeleton> ChooseLearnerSkeleton(
    const std::vector<const v1::Skeleton*>& skeletons, const Rigid3d& color_from_depth);

// The exposure stamp (see the top): device + offset, or host when the
// device stamp is 0.
int64_t ExposureStampNs(int64_t device_stamp_ns, int64_t host_stamp_ns, int64_t clock_offset_ns);

// A recorded take's sensor `sensor_id` (empty: the first sensor, by id, that
// has skeletons, or else the first with depth). A sensor whose take stores no
// skeletons (a recording of a sensor that gives none, made without reenactd's
// tracker) is tracked from its depth when the source opens, as reenactd
// would track it live (tracking::TrackTakeSensor, the shipped forest or
// $REENACT_TRACKER_FOREST). Frames follow the colour stream (each with the
// skeletons exposed within half a frame of it), or the skeleton stream when
// the sensor has no colour. Colour is decoded ahead on a thread of the
// source. NotFound for a missing file or sensor; FailedPrecondition when the
// sensor (or the take) has neither skeletons nor depth; the reader's errors
// for a file that is not a take.
absl::StatusOr<std::unique_ptr<LearnerSource>> OpenTakeLearner(const std::string& path,
                                                               const std::string& sensor_id = "");

}  // namespace reenact::mirror
