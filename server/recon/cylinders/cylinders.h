// Method "rigid-cylinders": rough shape-based reenactment (thesis 3.3).
//
// 1. Representative frame (Eq. 3.3-3.5): among all instants and sensors, the
//    skeleton (in that sensor's depth-camera frame) that maximises
//      E(n) = theta^L a^L + theta^R a^R + lambda g(phi^R, phi^L).
// 2. In that frame's depth image and actor mask, a rectangle per body part:
//    the width of the actor across the projected bone, measured along the
//    middle of the bone; the cylinder radius r is half of it, stored as the
//    radius rate r / l (l: the bone length in that frame).
// 3. Mesh per part: a capped cylinder in the part frame (body_parts.h) along
//    +Y from 0 to a reference length l_ref with radius r_rate * l_ref; per
//    instant the part pose comes from the fused skeleton and scales by
//    l_n / l_ref, so the radius stays r/l of the bone length (3.3.1).
// 4. Texture keyframes and baked textures (rigid_texturing.h).
//
// Departures from the thesis, and choices it leaves open:
//  - Several sensors: E is evaluated per (instant, sensor), each in that
//    sensor's depth-camera frame (the thesis has one sensor); the best pair
//    wins, among those whose skeleton is complete and projects inside the
//    depth image. The skeleton used is the instant's fused world skeleton
//    moved into that depth frame (less jitter than one sensor's).
//  - Eq. 3.4 signs: the thesis does not say which way the arm vectors point,
//    and with any fixed choice one of the outstretched arms gets a negative
//    x-component; we use |a^L| and |a^R| (arms parallel to the image x axis
//    score, either way). theta^{L/R} is the angle between the torso vector
//    (SpineShoulder -> SpineBase, pointing down) and the arm vector (Shoulder
//    -> Wrist), in radians; phi^{L/R} the angle between the camera's +x axis
//    (OpenCV: image right) and the leg vector (Hip -> Ankle). For a person
//    facing the camera the person's right leg lies at image left, so
//    g = 1 (Eq. 3.3, phi^R > phi^L) means uncrossed legs seen from the front.
//  - Rectangle fit: instead of fitting a rectangle to the region, the width
//    is measured on lines perpendicular to the projected bone at evenly
//    spaced points of its middle part (a per-part range of the bone, e.g.
//    25-75 %), walking out from the bone through actor pixels whose depth
//    lies near the bone's (so that a part in front of or behind another
//    does not merge with it); the edge points are unprojected at the bone's
//    depth and their distance is the width in metres. The median over the
//    lines is the rectangle's width. The head is measured around the Head
//    joint (70-140 % of Neck -> Head) since the skull, not the neck, is what
//    the cylinder should match.
//  - A part whose projected bone is too short (pointing at the camera) or
//    whose measurement finds too few lines falls back to a default radius
//    rate from adult proportions (Winter, "Biomechanics and Motor Control of
//    Human Movement", segment dimensions); the figures say which parts did.
//  - The head cylinder extends past the Head joint (the centre of the head)
//    by head_top_extension x the bone length, to cover the skull.
//  - l_ref is the median bone length over the take's valid instants.
#pragma once

#include <array>
#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "common/base/image.h"
#include "common/geometry/camera.h"
#include "common/model/reenactment.h"
#include "server/recon/body_parts.h"
#include "server/recon/method_util.h"
#include "server/recon/reconstruction_method.h"
#include "server/recon/rigid_texturing.h"
#include "server/recon/take_frames.h"
#include "server/recon/texturing.h"

namespace reenact::recon {

struct CylinderOptions {
  // Weight of the leg-crossing term of Eq. 3.4 (option "lambda").
  double lambda = 0.5;
  // Force the representative frame: instant index and sensor index (options
  // "representative_instant", "representative_sensor"); -1: Eq. 3.5.
  int representative_instant = -1;
  int representative_sensor = -1;
  // Depth window around the bone: actor pixels count toward a part's width
  // when their depth is at most (expected radius + depth_window_m) in front
  // of the bone axis and at most depth_window_m behind it, metres
  // ("depth_window_m").
  double depth_window_m = 0.08;
  // Cylinder tessellation: segments round, rings along ("segments", "rings").
  int segments = 24;
  int rings = 8;
  // Head cylinder length past the Head joint, in bone lengths
  // ("head_top_extension").
  double head_top_extension = 0.8;
  // Texture keyframes and baking.
  RigidTexturingOptions texturing;

  // Reads every key above and the texturing keys from `reader`.
  absl::Status Read(OptionReader& reader);
  // InvalidArgument naming the first bad field.
  absl::Status Validate() const;
  // The method's own share of a job's memory (memory_estimate.h): the
  // representative frame's decode, the cylinders and their texturing.
  int64_t MemoryBytes(const TakeSize& take) const;
};

// The terms of Eq. 3.3-3.4 for one skeleton.
struct RepresentativeScore {
  double theta_left_rad = 0.0;   // Angle torso / left arm.
  double theta_right_rad = 0.0;  // Angle torso / right arm.
  double a_left = 0.0;           // |x| of the unit left arm vector.
  double a_right = 0.0;
  double phi_left_rad = 0.0;  // Angle +x / left leg.
  double phi_right_rad = 0.0;
  double g = 0.0;      // Eq. 3.3: 1 when phi^R > phi^L.
  double e = 0.0;      // Eq. 3.4.
  bool valid = false;  // False when a joint the terms need is missing.
};

// Eq. 3.3-3.4 on a skeleton in a depth-camera frame (OpenCV axes, metres).
RepresentativeScore ScoreRepresentative(const JointArray& joints_in_camera_m, double lambda);

struct RepresentativeFrame {
  int instant = -1;
  int sensor = -1;
  RepresentativeScore score;
};

// Eq. 3.5 over every valid (instant, sensor) of the take (or the forced
// pair of `options`). InvalidArgument when no instant qualifies or the
// forced pair is out of range / invalid.
absl::StatusOr<RepresentativeFrame> FindRepresentativeFrame(const TakeFrames& take,
                                                            const CylinderOptions& options);

// The fitted rectangle of one part.
struct PartRadius {
  double radius_m = 0.0;     // r.
  double length_m = 0.0;     // l: bone length in the representative frame.
  double radius_rate = 0.0;  // r / l.
  int lines = 0;             // Measurement lines that found the part.
  bool fitted = false;       // False: the default rate was used.
};

// Default radius rate r / l of `part` (adult proportions), used when a part
// cannot be measured.
double DefaultRadiusRate(BodyPart part);

// Fits the 15 rectangles in one depth image (see the file comment).
// `joints_in_depth_m`: the skeleton in that depth camera's frame; `actor`:
// 1 actor / 0 not, depth pixels. InvalidArgument when image sizes disagree
// with the intrinsics.
absl::StatusOr<std::array<PartRadius, kNumBodyParts>> FitPartRadii(
    const JointArray& joints_in_depth_m, const DepthImageMm& depth_mm, const MaskImage& actor,
    const CameraIntrinsics& depth_intrinsics, const CylinderOptions& options);

// A capped cylinder along +Y from y0 to y1 (metres) of `radius_m`:
// `segments` round, `rings` along; side vertices have radial normals, caps
// their own vertices with normals -Y / +Y; triangles counter-clockwise seen
// from outside.
PartMesh MakeCylinderGeometry(double radius_m, double y0_m, double y1_m, int segments, int rings);

// `geometry` as the mesh of `part` (id, name, radius rate and reference
// length; no texture yet).
PartMesh ToPartMesh(BodyPart part, PartMesh geometry, float radius_rate, float reference_length_m);

// The shape model of a take: representative frame, radii, reference lengths.
struct CylinderModel {
  RepresentativeFrame representative;
  std::array<PartRadius, kNumBodyParts> radii;
  std::array<double, kNumBodyParts> reference_length_m{};  // l_ref per part.
};

// Steps 1-2 of the file comment. InvalidArgument when the take has no valid
// instant; DataLoss when the representative frame does not decode.
absl::StatusOr<CylinderModel> FitCylinderModel(const TakeFrames& take,
                                               const CylinderOptions& options);

// The whole method on a loaded take; same contract as RunRigidCarved
// (carving/rigid_carved.h): returns parts, frames, keyframes and info
// (frame_count, fps, part_names, figures); RunMethod fills the rest.
// InvalidArgument for options that fail Validate(). Progress stages
// "shape", "pose", "texture".
absl::StatusOr<Reenactment> RunRigidCylinders(const TakeFrames& take,
                                              const CylinderOptions& options = {},
                                              const MethodContext& context = {});

// One take split across several workers (ReconstructionMethod::Prepare):
// the prepare phase fits the cylinders and poses every instant (it decodes
// the representative frame's depth and mask alone: Eq. 3.5 chooses that
// frame by its skeleton) and packs the untextured reenactment
// (rigid_texturing.h PackUntexturedRigid); the segments make their
// instants' keyframes, the stitch bakes, as rigid_texturing.h says. The
// stitched reenactment equals RunRigidCylinders' but for the texturing's
// timing and the figure "segments".
absl::StatusOr<std::string> PrepareRigidCylinders(const TakeFrames& take,
                                                  const CylinderOptions& options,
                                                  const MethodContext& context = {});

// The method "rigid-cylinders" for the registry (registry.cc).
const ReconstructionMethod& RigidCylindersMethod();

}  // namespace reenact::recon
