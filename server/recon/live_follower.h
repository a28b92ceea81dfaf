// A method's live follow of a take while it is recorded
// (ReconstructionMethod::MakeLiveFollower): each FrameSet is fitted as it
// arrives, for a preview; the stored reenactment is still the offline run
// on the whole take. server/live's hub drives one per live job, on a thread
// of its own.
#pragma once

#include <optional>

#include "absl/status/statusor.h"
#include "common/model/reenactment.h"
#include "common/model/take.h"

namespace reenact::recon {

// What one FrameSet produced.
struct LiveUpdate {
  // A new mesh (the first FrameSet's, and when the method has refined it).
  std::optional<BodyMesh> mesh;
  // The fitted instant (frame_index counts the FrameSets pushed, from 0);
  // unset when the FrameSet could not be fitted (no skeleton or no points
  // before the first fit).
  std::optional<ReenactmentFrame> frame;
  double fit_ms = 0.0;  // Decode, cloud and fit of this FrameSet.
};

class LiveFollower {
 public:
  virtual ~LiveFollower() = default;
  // Fits the next FrameSet (its encoded bytes are moved from). DataLoss for
  // frames that do not decode; the follow goes on after an error.
  virtual absl::StatusOr<LiveUpdate> Push(FrameSet set) = 0;
};

}  // namespace reenact::recon
