// Test helper: a rigid-part reenactment built by hand from a synthetic take's
// ground truth, as good as 15 rigid parts can be. The true mesh of instant 0
// is cut into the 15 parts by each vertex's dominant skinning joint (the body
// model the take was made with), every part moves rigidly with the true
// transform of its proximal joint (PoseBody of /ground_truth/body), and the
// texture keyframes are the take's colour images, whole, with the actor mask
// and per-vertex visibility from renders of the truth and of the posed parts
// into each colour camera.
#pragma once

#include <string>

#include "absl/status/statusor.h"
#include "common/body/body_model.h"
#include "common/io/take.h"
#include "common/model/reenactment.h"

namespace reenact::view::testing {

struct TruthReenactmentOptions {
  // Keyframes from every k-th instant, all sensors.
  int keyframe_every = 1;
  // A vertex is visible in a keyframe when within this of the parts' depth.
  double visibility_tolerance_m = 0.02;
  std::string method = "rigid-carved";
};

absl::StatusOr<Reenactment> MakeTruthReenactment(const TakeReader& take,
                                                 const body::BodyModel& model,
                                                 const TruthReenactmentOptions& options = {});

// A body-model reenactment (method "body") of the take's ground truth: the
// BodyMesh of `model` (the synthesizer's model) with the true shape
// (/ground_truth/body) and the truth's albedo (/ground_truth/topology, as a
// JPEG) as its atlas; per instant the true pose and vertex offsets that take
// the skinned mesh onto /ground_truth/mesh (what BodyMesh leaves out, the
// pose correctives, plus float rounding), so the posed mesh is the truth;
// the frames' joints are the posed joints. FailedPrecondition when the take
// lacks that ground truth or its mesh is not `model`'s.
absl::StatusOr<Reenactment> MakeTruthBodyReenactment(const TakeReader& take,
                                                     const body::BodyModel& model);

// Moves every part of every frame by `offset_m` (world frame) and turns it by
// `angle_deg` about its own part-frame X axis.
void PerturbPoses(Reenactment* data, const Eigen::Vector3d& offset_m, double angle_deg);

}  // namespace reenact::view::testing
