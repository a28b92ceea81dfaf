// Per-part rigid registration between two instants (thesis 3.4.1, "Body
// part registration", after Malleson et al. [57]):
//
//   T_{b,n} = dT T_{b,n-1}                                          (Eq. 3.7)
//   E(dT)   = E_p(dT) + w_o E_o(dT) + w_s E_s(dT)                   (Eq. 3.8)
//
// with dT linearised by the small-angle matrix of Eq. 3.9 and solved as a
// 6x6 symmetric system, iterated until the update is small.
//
//  * E_p, point-to-plane: each point of the part at n-1 (a depth pixel of
//    D_{n-1} inside the part's volume at T_{b,n-1}), moved by the current
//    dT, is projected into the same sensor's D_n; it pairs with the point at
//    that pixel and its tangent plane (projective association; the sensors
//    are static, so C_{n-1} = C_n). Pairs farther apart than a threshold or
//    with normals at too large an angle are rejected in that iteration.
//  * E_o, point-to-point: each point pairs with the point of D_n that the
//    optical flow between I_{n-1} and I_n leads to (the caller supplies this
//    flow target; see optical_flow.h), rejected when farther than a
//    threshold from the moved point.
//  * E_s, skeleton: anchor points of the part (its proximal and distal
//    joints and an axis point, in the world at T_{b,n-1}) against the same
//    points under the skeleton tracker's transform T*_{b,n}.
//
// Departures from the thesis:
//  * Several sensors: each source point carries its sensor; E_p pairs it in
//    that sensor's D_n only, and the sums run over all sensors.
//  * Weights: each point residual carries a weight (the caller gives it the
//    number of full-resolution pixels a decimated point stands for), so the
//    sums equal the thesis' full-resolution sums whatever the decimation;
//    w_s multiplies the anchors' squared distances in the same units.
//  * The linear system is centred on the centroid of the source points
//    (rotation about the centroid, then translation), which leaves the
//    optimum unchanged and conditions the system better than rotating about
//    the world origin; the solved (omega, t) is composed with an exact
//    rotation (angle-axis of omega), so dT stays orthonormal without a
//    separate re-orthonormalisation. Eq. 3.9's (alpha, beta, gamma) are
//    (alpha, beta, gamma) = (-omega_z, -omega_x, -omega_y).
#pragma once

#include <vector>

#include <Eigen/Core>

#include "absl/status/status.h"
#include "common/geometry/transforms.h"
#include "server/recon/carving/sensor_frame.h"

namespace reenact::recon::carving {

// One point of the part at n-1 (world frame, metres).
struct SourcePoint {
  Eigen::Vector3f point_in_world_m = Eigen::Vector3f::Zero();
  Eigen::Vector3f normal_in_world = Eigen::Vector3f::UnitZ();  // Unit, toward its sensor.
  int view = 0;         // Index into the views of RegisterPart.
  float weight = 1.0f;  // Full-resolution pixels it stands for.
  bool has_flow_target = false;
  // The point of D_n the optical flow leads to (world, metres).
  Eigen::Vector3f flow_target_in_world_m = Eigen::Vector3f::Zero();
};

// One sensor at instant n: its depth camera and the surface of D_n.
struct RegistrationView {
  const PosedCamera* camera = nullptr;
  const SurfaceMap* surface = nullptr;
};

// A skeleton anchor: a point of the part placed by T_{b,n-1}, and where the
// skeleton's transform T*_{b,n} puts the same part point (world, metres).
struct SkeletonAnchor {
  Eigen::Vector3d point_in_world_m = Eigen::Vector3d::Zero();
  Eigen::Vector3d target_in_world_m = Eigen::Vector3d::Zero();
  double weight = 1.0;  // Relative weight of this anchor (times w_s).
};

struct PartRegistrationOptions {
  // Eq. 3.8 weights: w_o of the point-to-point (optical flow) term, relative
  // to the point-to-plane term; w_s of the skeleton term, per anchor, in
  // units of one full-resolution point residual.
  double w_o = 1.0;
  double w_s = 1000.0;
  // Pairs farther apart than this are rejected (metres), in both ICP terms.
  double max_pair_distance_m = 0.05;
  // Point-to-plane pairs whose normals differ by more than this are rejected.
  double max_normal_angle_deg = 45.0;
  // Stop when the update rotates less than this and moves less than this.
  double min_update_deg = 0.01;
  double min_update_mm = 0.01;
  int max_iterations = 20;

  // InvalidArgument naming the first bad field.
  absl::Status Validate() const;
};

struct PartRegistrationSummary {
  Rigid3d delta;  // dT of Eq. 3.7 (world frame): T_{b,n} = dT T_{b,n-1}.
  int iterations = 0;
  bool converged = false;  // The last update was below the thresholds.
  int plane_pairs = 0;     // Pairs of the last iteration.
  int flow_pairs = 0;
  // Root mean square residuals at the last linearisation, metres (0 when
  // the term had no pairs): point-to-plane distance, point-to-point
  // distance, anchor distance.
  double plane_rms_m = 0.0;
  double flow_rms_m = 0.0;
  double skeleton_rms_m = 0.0;
  // False when the system was singular (too few pairs and no anchors); delta
  // is then the initial one.
  bool solved = true;
};

// Minimises Eq. 3.8 over dT, starting from `initial_delta` (e.g. the
// skeleton's motion). `views` are indexed by SourcePoint::view; a point with
// an out-of-range view is ignored. InvalidArgument for bad options.
absl::StatusOr<PartRegistrationSummary> RegisterPart(const std::vector<SourcePoint>& sources,
                                                     const std::vector<RegistrationView>& views,
                                                     const std::vector<SkeletonAnchor>& anchors,
                                                     const PartRegistrationOptions& options,
                                                     const Rigid3d& initial_delta = Rigid3d());

}  // namespace reenact::recon::carving
