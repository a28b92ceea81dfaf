// The procedural human body: Reenact's default body model, built entirely by
// our own code (no downloaded assets).
//
// Construction:
//  1. A smooth signed distance field of a neutral body of the requested
//     stature: a smooth union (Quilez' polynomial smooth minimum) of ellipsoids
//     and rounded cones, one or two per segment. Segment lengths and joint
//     heights are fractions of stature H from Drillis & Contini (1966) as
//     reproduced in D. A. Winter, "Biomechanics and Motor Control of Human
//     Movement", 4th ed., Fig. 4.1 (shoulder height 0.818H, hip 0.530H, knee
//     0.285H, ankle 0.039H, upper arm 0.186H, forearm 0.146H, hand 0.108H,
//     shoulder width 0.259H, foot length 0.152H, chin 0.870H); hip joint
//     centres from Bell, Pedersen & Brand (1990); girths after typical adult
//     circumferences (ANSUR II, Gordon et al. 2014).
//  2. Polygonisation by marching cubes on a regular grid, face by face (each
//     cube face is resolved by the asymptotic decider, so neighbouring cubes
//     agree and the surface is closed), sharing vertices by grid edge, then
//     Taubin smoothing. The result is one closed, consistently oriented
//     2-manifold.
//  3. Skinning weights from distances to the bones of the Kinect v2 tree, a
//     joint regressor from rings of vertices around each joint, per-region UV
//     charts packed into [0,1]^2.
//  4. A shape space: a population of bodies with sampled anthropometric
//     parameters (stature, limb and trunk proportions, shoulder and hip
//     widths, girths, fullness) is made by deforming the neutral mesh segment
//     by segment (so every member shares its topology), and PCA of the
//     population (shape_space.h) gives the mean (the template) and the shape
//     directions.
//
// Rest pose: an A-pose. Arms hang `arm_angle_below_horizontal_deg` (default
// 40) below horizontal in the frontal plane with the palms facing the thighs
// and thumbs forward; legs slightly apart; feet flat on y = 0, facing +Z; the
// person's left (Kinect "Left") at +X. Hands are mittens with a separate
// thumb (fingers are not modelled one by one).
#pragma once

#include <array>
#include <cstdint>
#include <string_view>
#include <vector>

#include <Eigen/Core>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "common/body/body_model.h"
#include "common/body/joint_set.h"

namespace reenact::body {

struct ProceduralBodyOptions {
  // Stature (floor to vertex of the head) of the template, metres; also the
  // mean stature of the population the shape space is learned from.
  double stature_m = 1.75;
  // Spacing of the polygonisation grid, metres, for the default stature (it
  // scales with stature). 0.015 gives about 13,000 vertices.
  double grid_spacing_m = 0.015;
  // Taubin smoothing passes applied after polygonisation (0 = none).
  int smoothing_iterations = 6;
  // Arm angle below horizontal in the rest pose, degrees, in [20, 60].
  double arm_angle_below_horizontal_deg = 40.0;
  // Members of the generated population the shape space is learned from.
  int population_size = 200;
  // Further members generated the same way but kept out of learning, for
  // validation (ProceduralBody::held_out_members_m).
  int num_held_out = 20;
  // Shape components kept (at least 8, fewer than population_size).
  int num_shape_components = 10;
  // Seed of the population sampler; equal seeds give equal models.
  uint64_t seed = 20240607;

  absl::Status Validate() const;
};

// Body regions for texturing (clothing, skin, shoes). Left and right limbs
// share a region.
enum class BodyRegion : uint8_t {
  kHead = 0,  // Head and neck.
  kTorso = 1,
  kUpperArm = 2,
  kForearm = 3,
  kHand = 4,
  kThigh = 5,
  kShin = 6,
  kFoot = 7,
};
inline constexpr int kNumBodyRegions = 8;

// "head", "torso", "upper_arm", ... ("unknown" outside the enum).
std::string_view BodyRegionName(BodyRegion region);

struct ProceduralBody {
  // The model: template = population mean, shape directions, regressor,
  // skinning, UVs. Its name is "procedural".
  BodyModel model;
  // Per triangle of `model.triangles`, its region. Each region's triangles
  // have their own UV charts (one per side for limbs).
  std::vector<BodyRegion> triangle_region;
  // Anatomical rest joints of the template, metres (world frame). The model's
  // regressor reproduces them from the template vertices.
  std::array<Eigen::Vector3d, kNumKinectV2Joints> rest_joints_m;
  // Per shape component, its share of the population variance.
  std::vector<double> explained_variance_ratio;
  // Population members not used for learning (3 x V each, in correspondence
  // with the template), to measure how well the shape space generalises.
  std::vector<Eigen::Matrix3Xd> held_out_members_m;
};

// Builds the procedural body with its regions and figures. InvalidArgument
// when the options do not validate; Internal if the polygonisation does not
// yield a closed manifold (not expected for valid options).
absl::StatusOr<ProceduralBody> BuildProceduralBodyDetailed(
    const ProceduralBodyOptions& options = {});

// The model alone (BuildProceduralBodyDetailed(options).model).
absl::StatusOr<BodyModel> BuildProceduralBody(const ProceduralBodyOptions& options = {});

}  // namespace reenact::body
