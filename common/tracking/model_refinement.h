// The generative step of the body tracker: the statistical body model
// (common/bodyfit, thesis 4.3) fitted to one person's points in one depth
// image, started from the forest's joints and, in later frames, from the
// person's previous fit (the temporal prior of Eq. 4.6). The forest's joints
// also enter the fit as the skeleton prior, which holds limbs the camera
// does not see. After `shape_frames` fitted frames `shape_spacing` apart the
// person's shape is fitted once (one shape per person, as the thesis has
// one per take) and held.
//
// The joints come out as the model defines them, so a teacher and a learner
// tracked through the same model are compared joint for joint.
#pragma once

#include <map>
#include <memory>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "common/tracking/tracking_types.h"

namespace reenact::tracking {

struct ModelRefinementOptions {
  // The body model ("procedural" or "makehuman:DIR", common/body/model_spec.h).
  std::string model = "procedural";
  int rounds = 2;                // Correspondence rounds per frame.
  int iterations_per_round = 4;  // Levenberg-Marquardt iterations per round.
  int max_points = 800;          // Points used per round.
  double skeleton_weight = 0.1;  // Of the forest's joints (bodyfit's skeleton prior).
  int shape_frames = 5;          // Frames of the shape fit (0: keep the mean shape).
  int shape_spacing = 6;         // Fitted frames between them.

  absl::Status Validate() const;
};

// One person's points in the camera frame (metres) with unit normals facing
// the camera.
struct PersonCloud {
  std::vector<Eigen::Vector3f> points_m;
  std::vector<Eigen::Vector3f> normals;
};

class BodyModelRefiner {
 public:
  static absl::StatusOr<std::unique_ptr<BodyModelRefiner>> Create(
      const ModelRefinementOptions& options);
  ~BodyModelRefiner();

  // Replaces `person`'s joint positions by the fitted model's joints
  // (confidence and state are left to the caller). A person whose forest
  // joints lack a torso and who has no earlier fit is left as it is
  // (returns false); errors of the fit are returned.
  absl::StatusOr<bool> Refine(const PersonCloud& cloud, TrackedPerson* person);

  // Forgets every person but those listed (people who left the view).
  void Keep(const std::vector<int>& person_ids);

 private:
  struct Impl;
  explicit BodyModelRefiner(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace reenact::tracking
