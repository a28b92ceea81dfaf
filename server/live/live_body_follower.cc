#include "server/live/live_body_follower.h"

#include <memory>
#include <utility>

#include "server/recon/body/live_body.h"

namespace reenact::server {
namespace {

class BodyFollower final : public LiveFollower {
 public:
  explicit BodyFollower(std::unique_ptr<recon::LiveBodyFollower> follower)
      : follower_(std::move(follower)) {}

  absl::StatusOr<LiveFit> Push(const v1::FrameSet& set) override {
    absl::StatusOr<recon::LiveUpdate> update = follower_->Push(set);
    if (!update.ok()) return update.status();
    LiveFit fit;
    fit.mesh = std::move(update->mesh);
    fit.frame = std::move(update->frame);
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
    absl::StatusOr<std::unique_ptr<recon::LiveBodyFollower>> follower =
        recon::LiveBodyFollower::Create(info, sensors, options, asset_roots);
    if (!follower.ok()) return follower.status();
    return std::make_unique<BodyFollower>(std::move(*follower));
  };
}

}  // namespace reenact::server
