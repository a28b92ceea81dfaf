// Per-part pose error between a learner and a teacher, per-joint error for
// colouring a skeleton, and the error colour map.
//
// Thesis sec. 4.6.1 measures a learner by comparing body part orientations
// normalised to the spine; here each part's error is the angle between the
// learner's and the teacher's unit bone directions, both expressed in their
// own spine frames (body_parts.h). Because each skeleton is normalised to its
// own spine, the two poses may be in different frames (the learner in the
// sensor's OpenCV frame, the teacher in world), may stand anywhere, face any
// way and have different bone lengths. Both frames must be right-handed (the
// world and the OpenCV camera frame are): never pass a skeleton mirrored for
// display.
//
// Sides: the comparison is anatomical, left with left and right with right.
// The mirror shows the learner a mirror image of themself and a mirror image
// of the rendered teacher (the app flips both), so the learner's right hand
// and the teacher's right hand appear on the same side of the screen, and it
// is the learner's right forearm that is graded against the teacher's right
// forearm. Nothing here swaps sides.
#pragma once

#include <array>
#include <cstdint>
#include <optional>

#include "absl/status/status.h"
#include "clients/mirror/body_parts.h"
#include "common/body/joint_set.h"

namespace reenact::mirror {

// The error of one frame: learner against teacher.
struct PoseComparison {
  // Angle between the learner's and the teacher's part directions in their
  // spine frames, degrees in [0, 180]; nullopt where the part is missing in
  // either skeleton (joint not valid, not finite, or no spine frame).
  PerPart<double> part_error_deg;
  // Mean of the present part errors; nullopt when no part is present.
  std::optional<double> mean_error_deg;
  // How many parts were present in both skeletons.
  int num_parts_compared = 0;
};

// Compares two skeletons part by part (thesis sec. 4.6.1). Never fails: bad
// or missing joints make parts missing.
PoseComparison ComparePoses(const body::SkeletonPose& learner, const body::SkeletonPose& teacher);

// The same from directions already computed by PartDirectionsInSpine (for
// comparing many pairs, as time alignment does).
PoseComparison CompareDirections(const PerPart<Eigen::Vector3d>& learner,
                                 const PerPart<Eigen::Vector3d>& teacher);

// Angle between two unit vectors in degrees, [0, 180], stable near 0 and 180.
double AngleBetweenDeg(const Eigen::Vector3d& a, const Eigen::Vector3d& b);

// Per-joint error for colouring a skeleton, degrees, by this rule:
//  - a joint that some part touches (either end of its bone) takes the
//    largest error of the present parts touching it (an elbow shows the worse
//    of the upper and lower arm);
//  - a joint beyond the parts takes the error of the part it hangs from:
//    HandLeft, HandTipLeft and ThumbLeft take left_lower_arm (so do the right
//    ones with right_lower_arm), FootLeft takes left_lower_leg, FootRight
//    right_lower_leg;
//  - nullopt where none of those parts is present.
std::array<std::optional<double>, body::kNumKinectV2Joints> JointErrorsDeg(
    const PoseComparison& comparison);

// An 8-bit sRGB colour.
struct Srgb8 {
  uint8_t r = 0;
  uint8_t g = 0;
  uint8_t b = 0;
  bool operator==(const Srgb8&) const = default;
};

// The error colour map: green at 0, yellow at yellow_deg, red from red_deg
// on, linear in sRGB between them (thesis sec. 4.7 asks for "direct
// feedback ... highlighting differences in a different color").
struct ErrorColorOptions {
  // Error (degrees) shown in pure yellow_color; must be > 0.
  double yellow_deg = 15.0;
  // Error (degrees) from which the colour is red_color; must be > yellow_deg.
  double red_deg = 30.0;
  // Colour at 0 degrees.
  Srgb8 green_color{40, 200, 70};
  // Colour at yellow_deg.
  Srgb8 yellow_color{240, 210, 40};
  // Colour at and above red_deg.
  Srgb8 red_color{220, 40, 40};
  // Colour of a missing part or joint.
  Srgb8 missing_color{128, 128, 128};

  // InvalidArgument unless 0 < yellow_deg < red_deg, both finite.
  absl::Status Validate() const;
};

// Colour of an error in degrees (negative counts as 0, NaN as missing).
Srgb8 ErrorToSrgb(double error_deg, const ErrorColorOptions& options = {});
// Colour of an optional error: missing_color for nullopt.
Srgb8 ErrorToSrgb(const std::optional<double>& error_deg, const ErrorColorOptions& options = {});

}  // namespace reenact::mirror
