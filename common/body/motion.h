// Motion: a source skeleton (BVH or ASF/AMC) with per-frame joint rotations,
// forward kinematics, explicit length units, and the canonical (Kinect v2)
// view of it.
#pragma once

#include <array>
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

  // Source joint index of each canonical joint, -1 where the set has none.
  const std::array<int, kNumKinectV2Joints>& canonical_to_source() const {
    return canonical_to_source_;
  }

  // Canonical joint positions at `frame` (metres, file's world frame).
  SkeletonPose CanonicalPose(int frame) const;

  // Construction, used by the readers.
  Motion(MotionInfo info, std::vector<MotionJoint> joints,
         std::vector<std::vector<Eigen::Quaterniond>> local_rotations,
         std::vector<Eigen::Vector3d> root_translations_m);

 private:
  MotionInfo info_;
  std::vector<MotionJoint> joints_;
  std::vector<std::vector<Eigen::Quaterniond>> local_rotations_;  // [frame][joint]
  std::vector<Eigen::Vector3d> root_translations_m_;              // [frame]
  std::array<int, kNumKinectV2Joints> canonical_to_source_{};
};

struct BvhOptions {
  // Metres per file unit; <= 0 means detect it from the stature of the rest
  // pose (a standing adult is taken to be 1.7 m tall).
  double metres_per_unit = 0.0;
};

// Reads a BVH file. Errors name the file and line.
// Unit rule when options.metres_per_unit <= 0: the rest pose's vertical extent
// (highest joint or end site minus lowest) is taken as kAssumedStatureM.
// End sites become joints named "<parent>_end". Fails when the joint names
// match no known joint set (DetectJointSet).
absl::StatusOr<Motion> ReadBvh(const std::string& path, const BvhOptions& options = {});

struct BvhWriteOptions {
  // Metres per file unit (0.01: centimetres, the common BVH unit). Read the
  // file back with the same value (ReadBvh's options.metres_per_unit).
  double metres_per_unit = 0.01;
  // Decimals of every written number, 1..12.
  int decimals = 6;
};

// Writes `motion` as BVH (bvh_writer.cc: one root with position channels,
// "Zrotation Xrotation Yrotation" everywhere, angles in degrees, joints
// depth first), through a temporary file. ReadBvh reads it back: the same
// joints (End Sites included), frame rate, root translations and rotations,
// except that a leaf joint that was not an End Site gains a "<leaf>_end"
// joint at its own position. InvalidArgument for more or fewer than one
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
};

// As above, with options (the two-argument form uses the defaults).
absl::StatusOr<Motion> ReadAsfAmc(const std::string& asf_path, const std::string& amc_path,
                                  const AsfAmcOptions& options);

// Dispatches on the extension: .bvh, or .amc with `asf_path`.
absl::StatusOr<Motion> ReadMotion(const std::string& path, const std::string& asf_path = "");

}  // namespace reenact::body
