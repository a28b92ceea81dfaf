// Skeletons from depth on the CPU: the 25 Kinect v2 joints of every person in
// a depth image, with no vendor SDK.
//
// By default a small convolutional network finds the joints of each person
// (pose_net.h), trained on the project's own synthetic depth and on real
// Kinect recordings with the Kinect SDK's skeleton
// (models/tracker/README.md). The forest below remains as
// TrackerMethod::kForest.
//
// The forest's discriminative step after Shotton et al., "Real-Time Human Pose Recognition
// in Parts from Single Depth Images", CVPR 2011, and Girshick et al.,
// "Efficient Regression of General-Activity Human Poses from Depth Images",
// ICCV 2011: a randomised decision forest (body_part_forest.h) reads
// depth-difference features at every (subsampled) pixel of a person; each
// leaf holds a distribution over body parts and, per joint, a vote (offset
// from the pixel's 3D point to the joint). Votes are weighted by the pixel's
// world area (z^2, Shotton Eq. 5) and aggregated per joint by mean shift
// with a Gaussian kernel (Girshick sec. 3.2); the densest mode is the joint.
// A temporal step keeps person ids across frames.
//
// The forest is trained by `reenact tracker train` (tracker_training.h) on
// depth the project synthesises from the CMU motions and our body models;
// no weights come from anywhere else.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "common/base/image.h"
#include "common/geometry/camera.h"
#include "common/tracking/model_refinement.h"
#include "common/tracking/person_segmentation.h"
#include "common/tracking/skeleton_assembly.h"
#include "common/tracking/tracking_types.h"

namespace reenact::tracking {

class BodyPartForest;

// What finds the joints in a person's depth.
enum class TrackerMethod {
  kNetwork,  // The convolutional network of pose_net.h (the default).
  kForest,   // The body-part forest and its joint votes (body_part_forest.h).
};

struct BodyTrackerOptions {
  TrackerMethod method = TrackerMethod::kNetwork;
  // The trained network (.onnx); empty: DefaultPoseNetPath().
  std::string model_path;
  // The trained forest (.rtf) of kForest; empty: DefaultForestPath().
  std::string forest_path;
  // Every `pixel_stride`-th pixel in x and y is classified (1: all).
  int pixel_stride = 2;
  // Mean-shift bandwidth of the joint votes, metres (Girshick's b).
  double vote_bandwidth_m = 0.05;
  // Votes kept per joint (the heaviest), before mean shift.
  int max_votes_per_joint = 300;
  // Joints whose best mode holds less than this share of the joint's vote
  // weight are inferred even where the surface is seen.
  double min_tracked_confidence = 0.15;
  // A joint is tracked when it projects onto the person and lies at most
  // this far behind the surface seen there, metres: limbs and head.
  double max_behind_surface_m = 0.15;
  // The same for the trunk's joints (spine, neck, hips), whose depth under
  // the surface is half the trunk's thickness along the ray: 0.1-0.15 m
  // facing the sensor, up to 0.25 m turned 30-90 degrees. Measured on the
  // synthetic kick turned 30 and 60 degrees, those joints were within
  // 20-40 mm of the truth although 35-85 % of them lay deeper than 0.15 m.
  double max_behind_surface_trunk_m = 0.3;
  // Limbs assembled from several vote modes per joint (skeleton_assembly.h);
  // false: each joint's densest mode, as in Girshick et al.
  bool assemble = true;
  int modes_per_joint = 3;
  SkeletonAssemblyOptions assembly;
  // Used when Track is given no label image.
  PersonSegmentationOptions segmentation;
  // Largest distance between a person's centroids in consecutive frames
  // that keeps their id, metres.
  double max_id_jump_m = 0.5;
  // The generative step (model_refinement.h): the body model fitted to each
  // person's points from the joints found and the person's previous fit.
  // Off by default: on real depth it moved joints away from the Kinect
  // SDK's (models/tracker/README.md).
  bool refine = false;
  // Over time: a person's left and right limbs keep their sides from one
  // frame to the next unless the joints found say otherwise by a clear
  // margin (people do not swap arms between frames; a depth image alone
  // often cannot tell).
  bool keep_sides = true;
  ModelRefinementOptions refinement;
  // Forest joints below this confidence do not enter the fit as priors
  // (their position comes from the points and the previous frame).
  double min_prior_confidence = 0.1;

  absl::Status Validate() const;
};

// The forest shipped with the source tree (models/tracker/body_parts.rtf), or
// $REENACT_TRACKER_FOREST when set.
std::string DefaultForestPath();

// Whether a Kinect v2 joint index is one of the trunk's (spine, neck, hips),
// which count as seen up to BodyTrackerOptions::max_behind_surface_trunk_m
// behind the surface; the others up to max_behind_surface_m.
bool IsTrunkJoint(int joint);

class BodyTracker {
 public:
  // Loads the network (or the forest): NotFound / DataLoss / InvalidArgument
  // with the path when it is missing, corrupt or of another version.
  static absl::StatusOr<std::unique_ptr<BodyTracker>> Create(
      const BodyTrackerOptions& options = {});
  // Wraps an already loaded forest (tests, benchmarks).
  static absl::StatusOr<std::unique_ptr<BodyTracker>> Create(
      std::shared_ptr<const BodyPartForest> forest, const BodyTrackerOptions& options = {});
  ~BodyTracker();

  // People in one depth image (millimetres, 0 = no measurement) seen through
  // `intrinsics`. `labels`, when given, marks the people (the actor mask:
  // 0 background, k > 0 body k; same size as the depth); otherwise the
  // tracker segments the image itself (SegmentPeople). Person ids continue
  // those of the previous call. InvalidArgument for mismatched sizes or bad
  // intrinsics; an image with nobody gives an empty vector.
  // `own_labels_out`, when given and the tracker segmented the image itself,
  // receives that segmentation (0 background, k the pixels of the person
  // whose mask_label is k: a body index image, as a Kinect SDK gives one);
  // it is left untouched when `labels` was given.
  absl::StatusOr<std::vector<TrackedPerson>> Track(const DepthImageMm& depth,
                                                   const CameraIntrinsics& intrinsics,
                                                   const MaskImage* labels = nullptr,
                                                   MaskImage* own_labels_out = nullptr);

  // Forgets the people of earlier frames (new ids from 1).
  void Reset();

  const BodyTrackerOptions& options() const;

 private:
  struct Impl;
  explicit BodyTracker(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace reenact::tracking
