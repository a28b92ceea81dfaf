// Helpers the reconstruction methods share: progress over several stages, and the
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
#include "common/methods/option_reader.h"
#include "common/model/reenactment.h"
#include "server/recon/body_parts.h"
#include "server/recon/take_frames.h"

namespace reenact::recon {

// The option reader the methods parse their string options with
// (common/methods/option_reader.h).
using methods::OptionReader;

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

// The reenactment's pose of part `pose` with `scale` (1 for rigid meshes;
// cylinders: length / reference length). An invalid pose (or a non-finite
// one) becomes the identity transform, scale 1 and valid false.
reenact::PartPose ReenactmentPartPose(const PartPose& pose, double scale);

// One reenactment frame: frame_index, stamp, the 15 poses with their scales
// (part-id order) and the 25 joints. A reenactment holds finite numbers
// only: a missing (NaN) joint is written at its nearest present ancestor's
// position (Kinect v2 tree), and no joints at all are written when none is
// present. Readers take the poses' valid flags as truth.
ReenactmentFrame MakePartFrame(int frame_index, int64_t stamp_ns, const PartPoses& poses,
                               const std::array<double, kNumBodyParts>& scales,
                               const JointArray& joints_in_world_m);

}  // namespace reenact::recon
