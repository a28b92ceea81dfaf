#include "server/live/live_method_follower.h"

#include <memory>
#include <utility>

#include "absl/strings/str_cat.h"
#include "common/io/reenactment_convert.h"
#include "common/io/take_convert.h"
#include "server/recon/registry.h"

namespace reenact::server {
namespace {

// A method's recon::LiveFollower in the hub's protos.
class MethodFollower final : public LiveFollower {
 public:
  explicit MethodFollower(std::unique_ptr<recon::LiveFollower> follower)
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
  std::unique_ptr<recon::LiveFollower> follower_;
};

}  // namespace

LiveFollowerFactory MakeLiveMethodFollowerFactory(std::vector<std::string> asset_roots) {
  return [asset_roots = std::move(asset_roots)](const std::string& method_name,
                                                const v1::TakeInfo& info,
                                                const std::vector<v1::SensorCalibration>& sensors,
                                                const std::map<std::string, std::string>& options)
             -> absl::StatusOr<std::unique_ptr<LiveFollower>> {
    const recon::ReconstructionMethod* method = recon::FindMethod(method_name);
    if (method == nullptr) {
      return absl::InvalidArgumentError(absl::StrCat("no method ", method_name));
    }
    std::vector<SensorCalibration> calibrations;
    calibrations.reserve(sensors.size());
    for (const v1::SensorCalibration& sensor : sensors) {
      absl::StatusOr<SensorCalibration> calibration = SensorCalibrationFromProto(sensor);
      if (!calibration.ok()) return calibration.status();
      calibrations.push_back(*std::move(calibration));
    }
    absl::StatusOr<std::unique_ptr<recon::LiveFollower>> follower =
        method->MakeLiveFollower(TakeInfoFromProto(info), calibrations, options, asset_roots);
    if (!follower.ok()) return follower.status();
    return std::make_unique<MethodFollower>(std::move(*follower));
  };
}

}  // namespace reenact::server
