// Joint sets and the tables that map them onto the canonical skeleton.
//
// The canonical skeleton of Reenact is the Kinect v2 body: 25 joints, ids and
// names as in the Kinect for Windows SDK 2.0 (JointType_SpineBase = 0 ...
// JointType_ThumbRight = 24). "Left" is the person's own left. Every other
// joint set (Kinect v1, CMU BVH in both namings, ASF/AMC, MakeHuman's default
// skeleton, Daz/Poser, Mixamo, Blender Rigify) maps onto it by a name table,
// and a user's joint map (ParseJointMap) can name what no table knows.
#pragma once

#include <array>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <Eigen/Core>

#include "absl/status/statusor.h"

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
  kDazPoser,       // Daz Studio / Poser figures and CMU's Daz-friendly BVH (hip, abdomen,
                   // chest, lShldr, lThigh...; Genesis lShldrBend, chestUpper, neckUpper...).
  kMixamo,         // Mixamo (Hips, Spine1, LeftArm, LeftUpLeg..., "mixamorig:" optional).
  kRigify,         // Blender Rigify metarig or generated rig (spine.00N or hips/chest,
                   // upper_arm.L, thigh.L...; "DEF-" deform bones preferred).
  kUserMap,        // No recognised naming: a user's joint map alone.
};

// One row of a mapping table. A table may hold several rows for one
// canonical joint (one per naming variant, e.g. Genesis "lShldrBend" before
// Poser "lShldr"); the first row whose joints a skeleton has wins.
struct JointMapping {
  std::string source_name;  // Joint name in the source set.
  KinectV2Joint target;     // The canonical joint it stands for.
  // Empty: the canonical joint sits on the source joint (the head of its
  // bone). Otherwise the name of a child of the source joint, and the
  // canonical joint sits `fraction` of the way from the source joint to it
  // (e.g. the middle of a single neck bone).
  std::string toward = {};
  double fraction = 0.0;
};

// The mapping table of `set` (at least one row per canonical joint the set
// covers; none for kUserMap).
const std::vector<JointMapping>& JointMappingTable(JointSetId set);

// Guesses the joint set from the names a file declares; nullopt when no table
// covers at least the core joints (hips, spine, shoulders, elbows, knees).
// A name may carry a namespace prefix ("mixamorig:Hips" matches "Hips").
std::optional<JointSetId> DetectJointSet(const std::vector<std::string>& source_names);

std::string_view JointSetName(JointSetId set);

// Where one canonical joint lies in a source skeleton: at joint `joint`, or
// `fraction` of the way from it to its child `toward`.
struct CanonicalSource {
  int joint = -1;   // Index of the source joint; -1: the skeleton has none.
  int toward = -1;  // -1, or the index of a child of `joint`.
  double fraction = 0.0;
};
using CanonicalSources = std::array<CanonicalSource, kNumKinectV2Joints>;

// Resolves `user_map` rows, then `set`'s table, against a skeleton given by
// its joint names and parent indices (-1 for a root), in that priority.
CanonicalSources ResolveJointSet(JointSetId set, const std::vector<JointMapping>& user_map,
                                 const std::vector<std::string>& names,
                                 const std::vector<int>& parents);

// The naming of one skeleton and where its canonical joints lie.
struct JointSetMatch {
  JointSetId set = JointSetId::kUserMap;  // The recognised naming, or kUserMap.
  CanonicalSources sources;
  int covered = 0;  // Canonical joints found.
};

// Picks the naming that, after the rows of `user_map` (may be empty), covers
// the most canonical joints of a skeleton (names and parent indices as for
// ResolveJointSet). InvalidArgument when no choice covers the core joints;
// the message (prefixed with `what`, e.g. the file) lists the missing core
// joints of the closest naming, the user map's names the skeleton lacks, and
// the joint names seen (the first 40 of a longer list).
absl::StatusOr<JointSetMatch> MatchJointSet(const std::vector<std::string>& names,
                                            const std::vector<int>& parents,
                                            const std::vector<JointMapping>& user_map,
                                            const std::string& what);

// Largest joint map file ReadJointMap reads, bytes.
inline constexpr size_t kMaxJointMapBytes = 1 << 20;

// Parses a user's joint map: a JSON object of "their joint name": "Kinect v2
// joint name" (KinectV2JointName, e.g. {"Pelvis": "SpineBase"}).
// InvalidArgument (message prefixed with `what`) for bad JSON, anything but
// a non-empty object of strings, an unknown Kinect v2 name, an empty source
// name, or two names mapped to one Kinect joint.
absl::StatusOr<std::vector<JointMapping>> ParseJointMap(std::string_view json_text,
                                                        const std::string& what);

// Reads and parses the joint map file at `path` (at most kMaxJointMapBytes).
absl::StatusOr<std::vector<JointMapping>> ReadJointMap(const std::string& path);

}  // namespace reenact::body
