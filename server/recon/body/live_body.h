// Following a take while it is recorded: the body fit of the method "body"
// (body_fit.h) applied to each FrameSet as it arrives, for a live preview.
//
// The first FrameSet makes the model's mesh with the mean shape; the shape
// is then fitted on `shape_frames` usable instants `shape_spacing` apart
// (the thesis's one shape, from the first seconds instead of the whole
// take) on a thread of its own, so that Push keeps its pace (frames are
// posed with the mean shape meanwhile); the first Push after it finishes
// takes the shape over and sends the mesh again. Every other FrameSet is fitted from
// the previous fit carried to its skeleton (FitFrame; step 2 off by default:
// the preview carries poses only). The preview has no atlas (texturing
// needs the whole take); the job that follows the take to its end runs the
// offline method for the stored reenactment. Encoded frames are dropped
// once fitted, so memory stays flat however long the take.
#pragma once

#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "common/body/body_model.h"
#include "common/bodyfit/body_fit.h"
#include "common/methods/option_reader.h"
#include "common/model/reenactment.h"
#include "common/model/sensor_calibration.h"
#include "common/model/take.h"
#include "server/recon/live_follower.h"

namespace reenact::recon {

// The options only a live follow reads, beside the method body's own
// (body_method.h); the worker that runs the method on the whole take never
// gets them.
struct LiveBodyOptions {
  int shape_spacing = 5;  // FrameSets between shape samples.
  absl::Status Read(methods::OptionReader& reader);
  absl::Status Validate() const { return absl::OkStatus(); }
};

// The fit a live follow runs: the method's defaults made lighter so that a
// FrameSet is fitted within 20 ms on one core (body_fit_bench
// BM_LiveFitNext): step 2 off (the preview carries poses only), fewer
// points per round, fewer rounds and iterations. Hypotheses stay on. A
// job's options still override each.
bodyfit::BodyFitOptions LiveFitOptions();

class LiveBodyFollower final : public LiveFollower {
 public:
  // `options`: the method body's options (body_method.h) and
  // LiveBodyOptions'; `asset_roots`: the server's --assets folders.
  // InvalidArgument for bad options or calibrations; the model's errors.
  static absl::StatusOr<std::unique_ptr<LiveBodyFollower>> Create(
      const TakeInfo& info, const std::vector<SensorCalibration>& sensors,
      const std::map<std::string, std::string>& options,
      const std::vector<std::string>& asset_roots = {});
  ~LiveBodyFollower() override;

  // Fits the next FrameSet (its encoded bytes are moved from). DataLoss for
  // frames that do not decode; frames of unknown sensors are skipped.
  absl::StatusOr<LiveUpdate> Push(FrameSet set) override;

  int frames_pushed() const;
  bool shape_settled() const;
  // Blocks until a shape fit under way in the background has finished (the
  // next Push then uses it and sends the mesh).
  void WaitForShape();

 private:
  LiveBodyFollower();
  struct State;
  std::unique_ptr<State> state_;
};

}  // namespace reenact::recon
