// Joint sets and the tables that map them onto the canonical skeleton.
//
// The canonical skeleton of Reenact is the Kinect v2 body: 25 joints, ids and
// names as in the Kinect for Windows SDK 2.0 (JointType_SpineBase = 0 ...
// JointType_ThumbRight = 24). "Left" is the person's own left. Every other
// joint set (Kinect v1, CMU BVH in both namings, ASF/AMC, MakeHuman's default
// skeleton) maps onto it by a name table.
#pragma once

#include <array>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <Eigen/Core>

namespace reenact::body {

enum class KinectV2Joint : int {
  kSpineBase = 0,
  kSpineMid = 1,
  kNeck = 2,
  kHead = 3,
  kShoulderLeft = 4,
  kElbowLeft = 5,
  kWristLeft = 6,
  kHandLeft = 7,
  kShoulderRight = 8,
  kElbowRight = 9,
  kWristRight = 10,
  kHandRight = 11,
  kHipLeft = 12,
  kKneeLeft = 13,
  kAnkleLeft = 14,
  kFootLeft = 15,
  kHipRight = 16,
  kKneeRight = 17,
  kAnkleRight = 18,
  kFootRight = 19,
  kSpineShoulder = 20,
  kHandTipLeft = 21,
  kThumbLeft = 22,
  kHandTipRight = 23,
  kThumbRight = 24,
};
inline constexpr int kNumKinectV2Joints = 25;

inline constexpr int Index(KinectV2Joint j) { return static_cast<int>(j); }

// SDK names without the "JointType_" prefix: "SpineBase", ..., "ThumbRight".
std::string_view KinectV2JointName(KinectV2Joint joint);
std::optional<KinectV2Joint> KinectV2JointFromName(std::string_view name);

// Parent in the Kinect v2 tree (SpineBase is the root and has none).
std::optional<KinectV2Joint> KinectV2Parent(KinectV2Joint joint);

// Positions of the 25 canonical joints at one instant, metres, in the frame the
// producer states (world: +Y up, floor at y = 0). `valid[j]` is false where the
// source has no such joint or did not see it.
struct SkeletonPose {
  std::array<Eigen::Vector3d, kNumKinectV2Joints> position_m;
  std::array<bool, kNumKinectV2Joints> valid{};
};

// A source joint set and its map onto the canonical joints.
enum class JointSetId {
  kKinectV2,
  kKinectV1,       // Kinect for Windows SDK 1.x, 20 joints.
  kCmuBvhCgspeed,  // CMU BVH conversions by cgspeed (Hips, LHipJoint, LeftUpLeg...).
  kCmuBvh3dsMax,   // CMU BVH in 3dsMax naming (Hips, LeftHip, LeftKnee...).
  kCmuAsf,         // CMU ASF/AMC (root, lhipjoint, lfemur, ...).
  kMakeHuman,      // MakeHuman default skeleton (root, spine05, upperarm01.L, ...).
};

struct JointMapping {
  std::string source_name;  // Joint name in the source set.
  KinectV2Joint target;     // The canonical joint it stands for.
};

// The mapping table of `set` (one row per canonical joint the set covers).
const std::vector<JointMapping>& JointMappingTable(JointSetId set);

// Guesses the joint set from the names a file declares; nullopt when no table
// covers at least the core joints (hips, spine, shoulders, elbows, knees).
std::optional<JointSetId> DetectJointSet(const std::vector<std::string>& source_names);

std::string_view JointSetName(JointSetId set);

}  // namespace reenact::body
