// Helpers the reconstruction methods share: typed reading of option maps
// (unknown keys are errors), progress over several stages, and the
// reenact.v1 messages of part poses and frames.
#pragma once

#include <array>
#include <cstdint>
#include <map>
#include <set>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "common/base/progress.h"
#include "reenact/v1/reenactment.pb.h"
#include "server/recon/body_parts.h"
#include "server/recon/take_frames.h"

namespace reenact::recon {

// Reads typed values out of a method's string options and remembers which
// keys were read, so that Finish() can reject the rest:
//
//   OptionReader reader(options);
//   double lambda = 0.5;
//   RETURN_IF_ERROR(reader.Double("lambda", &lambda));
//   RETURN_IF_ERROR(reader.Finish());  // InvalidArgument for unknown keys.
//
// Each getter leaves `*value` unchanged when the key is absent, and returns
// InvalidArgument naming the key when the text does not parse as the type
// (or, for Int/Double with bounds, lies outside [min, max]).
class OptionReader {
 public:
  explicit OptionReader(const std::map<std::string, std::string>& options) : options_(options) {}

  absl::Status Int(const std::string& key, int* value, int min = INT32_MIN, int max = INT32_MAX);
  absl::Status Double(const std::string& key, double* value, double min = -1e300,
                      double max = 1e300);
  // "true"/"false"/"1"/"0"/"yes"/"no".
  absl::Status Bool(const std::string& key, bool* value);
  absl::Status String(const std::string& key, std::string* value);

  // InvalidArgument naming every key that no getter asked for, and listing
  // the keys the method knows.
  absl::Status Finish() const;

 private:
  const std::map<std::string, std::string>& options_;
  std::set<std::string> known_;
};

// Progress of a call made of several weighted stages, reported through one
// ProgressCallback with `fraction` over the whole call.
class StageProgress {
 public:
  // `stages`: (name, weight) in order; weights need not sum to 1.
  StageProgress(const ProgressCallback& callback,
                std::vector<std::pair<std::string, double>> stages);

  // Reports `done` of `total` items of `stage` (a name given above).
  // Cancelled when the callback returned false; OK without a callback.
  absl::Status Report(const std::string& stage, int64_t done, int64_t total) const;
  // A callback for a sub-call that reports its own fraction 0..1 of `stage`.
  ProgressCallback ForStage(const std::string& stage) const;

 private:
  double StageStart(const std::string& stage, double* weight) const;

  ProgressCallback callback_;
  std::vector<std::pair<std::string, double>> stages_;
  double total_weight_ = 0.0;
};

// reenact.v1.PartPose of `pose` with `scale` (1 for rigid meshes; cylinders:
// length / reference length). An invalid pose is written with the identity
// transform, scale 1 and valid false.
v1::PartPose PartPoseToProto(const PartPose& pose, double scale);

// One PartFrame: frame_index, stamp, the 15 poses with their scales (part-id
// order) and the 25 joints. The reenactment file holds finite numbers only:
// a missing (NaN) joint is written at its nearest present ancestor's
// position (Kinect v2 tree), and no joints at all are written when none is
// present. Readers take the poses' valid flags as truth.
v1::PartFrame MakePartFrame(int frame_index, int64_t stamp_ns, const PartPoses& poses,
                            const std::array<double, kNumBodyParts>& scales,
                            const JointArray& joints_in_world_m);

}  // namespace reenact::recon
