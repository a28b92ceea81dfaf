// Motion: a source skeleton (BVH or ASF/AMC) with per-frame joint rotations,
// forward kinematics, explicit length units, and the canonical (Kinect v2)
// view of it.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "absl/status/statusor.h"
#include "common/body/joint_set.h"

namespace reenact::body {

// One joint of the source skeleton. Offsets are in metres (already scaled).
struct MotionJoint {
  std::string name;
  int parent = -1;                    // Index into Motion::joints(), -1 for the root.
  Eigen::Vector3d offset_m{0, 0, 0};  // Rest offset from the parent, parent frame.
};

// How the file's length unit was established.
enum class UnitSource { kGiven, kAsfHeader, kDetectedFromStature };

// Short name of `source` for reports: "given", "asf_header" or
// "detected_from_stature".
std::string_view UnitSourceName(UnitSource source);

// Stature (metres) that a BVH rest pose is scaled to when the file's length
// unit is not given: the height of a standing adult.
inline constexpr double kAssumedStatureM = 1.7;

struct MotionInfo {
  std::string path;
  std::string format;  // "bvh" or "asf/amc".
  int num_frames = 0;
  double fps = 0.0;
  double metres_per_unit = 1.0;  // Scale applied to file lengths.
  UnitSource unit_source = UnitSource::kGiven;
  JointSetId joint_set = JointSetId::kCmuBvhCgspeed;
  // A user's joint map (ReadJointMap), whose rows come before joint_set's
  // table when the canonical joints are found.
  std::vector<JointMapping> joint_map;
  // The file was Z-up (Blender, MakeHuman exports): its lengths and
  // rotations were turned by -90 degrees about X, file (x, y, z) -> (x, z,
  // -y), so that +Y is up and a figure facing -Y faces +Z.
  bool turned_from_z_up = false;
};

class Motion {
 public:
  const MotionInfo& info() const { return info_; }
  const std::vector<MotionJoint>& joints() const { return joints_; }
  int num_frames() const { return info_.num_frames; }
  double fps() const { return info_.fps; }

  // Local rotation of every joint relative to its parent's frame at `frame`
  // (parent_from_joint rotation), and the root's translation in metres (BVH:
  // the root's OFFSET plus its position channels).
  const std::vector<Eigen::Quaterniond>& local_rotations(int frame) const;
  const Eigen::Vector3d& root_translation_m(int frame) const;

  // Forward kinematics: world_from_joint of every source joint at `frame`,
  // metres, in the file's world frame (+Y up for CMU data). frame in range.
  std::vector<Eigen::Isometry3d> WorldFromJoints(int frame) const;

  // World rest pose (all local rotations identity, root at the origin).
  std::vector<Eigen::Isometry3d> RestWorldFromJoints() const;

  // Source joint index of each canonical joint, -1 where the set has none:
  // the joint whose frame carries it (it may sit part of the way along that
  // joint's bone, see JointMapping::toward).
  const std::array<int, kNumKinectV2Joints>& canonical_to_source() const {
    return canonical_to_source_;
  }

  // Where each canonical joint sits in its source joint's frame, metres
  // (zero: on the joint itself).
  const std::array<Eigen::Vector3d, kNumKinectV2Joints>& canonical_in_source_m() const {
    return canonical_in_source_m_;
  }

  // Canonical joint positions at `frame` (metres, file's world frame).
  SkeletonPose CanonicalPose(int frame) const;

  // Canonical joint positions given every source joint's world_from_joint
  // (as WorldFromJoints or RestWorldFromJoints return them).
  SkeletonPose CanonicalPoseFrom(const std::vector<Eigen::Isometry3d>& world_from_joint) const;

  // Construction, used by the readers.
  Motion(MotionInfo info, std::vector<MotionJoint> joints,
         std::vector<std::vector<Eigen::Quaterniond>> local_rotations,
         std::vector<Eigen::Vector3d> root_translations_m);

 private:
  MotionInfo info_;
  std::vector<MotionJoint> joints_;
  // Joint indices with every parent before its children (the readers emit
  // that order already; a motion built in another order, such as the Kinect
  // v2 joint order, gets it here). Joints on a parent cycle come last and
  // hang from the world.
  std::vector<int> parents_first_;
  std::vector<std::vector<Eigen::Quaterniond>> local_rotations_;  // [frame][joint]
  std::vector<Eigen::Vector3d> root_translations_m_;              // [frame]
  std::array<int, kNumKinectV2Joints> canonical_to_source_{};
  std::array<Eigen::Vector3d, kNumKinectV2Joints> canonical_in_source_m_{};
};

// Largest BVH, ASF or AMC file the readers read (a BVH's frames take about
// three times as much memory once parsed).
inline constexpr uint64_t kMaxBvhBytes = uint64_t{512} << 20;

// Most joint poses (frames times joints) a motion file may hold: the parsed
// rotations take about 40 bytes each, so this bounds a motion to about
// 700 MB whatever a file's frame count says (75 minutes of a 31-joint CMU
// skeleton at 120 Hz). ReadBvh and ReadAsfAmc refuse more before allocating.
inline constexpr uint64_t kMaxMotionJointFrames = uint64_t{1} << 24;

struct BvhOptions {
  // Metres per file unit; <= 0 means detect it from the stature of the rest
  // pose (a standing adult is taken to be 1.7 m tall).
  double metres_per_unit = 0.0;
  // A user's joint map (ReadJointMap): its rows come before the recognised
  // naming's table, and it alone may name a skeleton no table knows.
  std::vector<JointMapping> joint_map = {};
};

// Reads a BVH file. Errors name the file and line.
// Unit rule when options.metres_per_unit <= 0: the rest pose's vertical extent
// (highest joint or end site minus lowest) is taken as kAssumedStatureM.
// Up axis: when the rest pose's spine points along +Z (Blender, MakeHuman),
// the motion is turned to +Y up (MotionInfo::turned_from_z_up) before the
// unit is detected. End sites become joints named "<parent>_end". Position
// channels on joints other than the root add to the joint's OFFSET and must
// hold one value through the clip (MakeHuman writes zeros); bones that
// stretch are refused. Fails when the joint names, with options.joint_map,
// do not cover the core canonical joints (MatchJointSet: the error lists the
// missing joints and the names seen), or for a file over kMaxBvhBytes.
absl::StatusOr<Motion> ReadBvh(const std::string& path, const BvhOptions& options = {});

struct BvhWriteOptions {
  // Metres per file unit (0.01: centimetres, the common BVH unit). Read the
  // file back with the same value (ReadBvh's options.metres_per_unit).
  double metres_per_unit = 0.01;
  // Decimals of every written number, 1..12.
  int decimals = 6;
};

// Writes `motion` as BVH (bvh_writer.cc: one root with position channels,
// "Zrotation Xrotation Yrotation" everywhere, angles in degrees continuous
// from frame to frame, joints depth first), through a temporary file.
// ReadBvh reads it back: the same joints (End Sites included), frame rate,
// root translations and rotations, except that a leaf joint that was not an
// End Site gains a "<leaf>_end" joint half its bone onward (at least 2 cm),
// so that no bone has zero length. InvalidArgument for more or fewer than one
// root, a parent listed after its child, names with white space or braces,
// non-finite values, zero rotations or bad options.
absl::Status WriteBvh(const Motion& motion, const std::string& path,
                      const BvhWriteOptions& options = {});

// Reads a CMU ASF skeleton and an AMC motion. Length unit from the ASF
// ":units length" (CMU: length 0.45 -> 1 unit = 1/0.45 inch = 0.05644 m).
// Errors name the file and line.
absl::StatusOr<Motion> ReadAsfAmc(const std::string& asf_path, const std::string& amc_path);

struct AsfAmcOptions {
  // Frame rate of the AMC motion, which the files do not state (CMU: 120).
  double frames_per_second = 120.0;
  // Metres per file unit; <= 0 means the ASF header's unit.
  double metres_per_unit = 0.0;
  // A user's joint map (as BvhOptions::joint_map), for the bone names.
  std::vector<JointMapping> joint_map = {};
};

// As above, with options (the two-argument form uses the defaults).
absl::StatusOr<Motion> ReadAsfAmc(const std::string& asf_path, const std::string& amc_path,
                                  const AsfAmcOptions& options);

// Dispatches on the extension: .bvh, or .amc with `asf_path`.
absl::StatusOr<Motion> ReadMotion(const std::string& path, const std::string& asf_path = "");

// What ReadMotion passes on to the reader of either format.
struct MotionReadOptions {
  std::string asf_path;  // The ASF skeleton of an .amc motion.
  // Metres per file unit, overriding the ASF header or the BVH stature
  // detection; <= 0: the file's own. Finite.
  double metres_per_unit = 0.0;
  // A user's joint map (ReadJointMap), see BvhOptions::joint_map.
  std::vector<JointMapping> joint_map = {};

  // InvalidArgument unless metres_per_unit is 0 (or below) or within
  // (0, kMaxMetresPerUnit].
  absl::Status Validate() const;
};

// Largest length unit MotionReadOptions accepts, metres (a kilometre per
// unit is already absurd; it guards against typing errors).
inline constexpr double kMaxMetresPerUnit = 1000.0;

absl::StatusOr<Motion> ReadMotion(const std::string& path, const MotionReadOptions& options);

}  // namespace reenact::body
