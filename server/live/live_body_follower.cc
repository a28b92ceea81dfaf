#include "server/live/live_body_follower.h"

#include <memory>
#include <utility>

#include "common/io/reenactment_convert.h"
#include "common/io/take_convert.h"
#include "server/recon/body/live_body.h"

namespace reenact::server {
namespace {

class BodyFollower final : public LiveFollower {
 public:
  explicit BodyFollower(std::unique_ptr<recon::LiveBodyFollower> follower)
      : follower_(std::move(follower)) {}

  absl::StatusOr<LiveFit> Push(const v1::FrameSet& set) override {
    absl::StatusOr<recon::LiveUpdate> update = follower_->Push(FrameSetFromProto(set));
    if (!update.ok()) return update.status();
    LiveFit fit;
    if (update->mesh) fit.mesh = BodyMeshToProto(*update->mesh);
    if (update->frame) fit.frame = FrameToProto(*update->frame);
    fit.fit_ms = update->fit_ms;
    return fit;
  }

 private:
  std::unique_ptr<recon::LiveBodyFollower> follower_;
};

}  // namespace

LiveFollowerFactory MakeLiveBodyFollowerFactory(std::vector<std::string> asset_roots) {
  return [asset_roots = std::move(asset_roots)](const v1::TakeInfo& info,
                                                const std::vector<v1::SensorCalibration>& sensors,
                                                const std::map<std::string, std::string>& options)
             -> absl::StatusOr<std::unique_ptr<LiveFollower>> {
    std::vector<SensorCalibration> calibrations;
    calibrations.reserve(sensors.size());
    for (const v1::SensorCalibration& sensor : sensors) {
      absl::StatusOr<SensorCalibration> calibration = SensorCalibrationFromProto(sensor);
      if (!calibration.ok()) return calibration.status();
      calibrations.push_back(*std::move(calibration));
    }
    absl::StatusOr<std::unique_ptr<recon::LiveBodyFollower>> follower =
        recon::LiveBodyFollower::Create(TakeInfoFromProto(info), calibrations, options,
                                        asset_roots);
    if (!follower.ok()) return follower.status();
    return std::make_unique<BodyFollower>(std::move(*follower));
  };
}

}  // namespace reenact::server
