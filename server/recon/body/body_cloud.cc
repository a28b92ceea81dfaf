#include "server/recon/body/body_cloud.h"

#include "absl/strings/str_cat.h"
#include "common/base/status_macros.h"

namespace reenact::recon {

absl::Status CloudOptions::Validate() const {
  if (step < 1 || step > 16) {
    return absl::InvalidArgumentError(absl::StrCat("cloud step ", step, " outside [1, 16]"));
  }
  if (edge_filter_mm < 0) return absl::InvalidArgumentError("edge_filter_mm must be >= 0");
  return absl::OkStatus();
}

absl::StatusOr<std::unique_ptr<CloudBuilder>> CloudBuilder::Create(const TakeFrames& take,
                                                                   const CloudOptions& options) {
  RETURN_IF_ERROR(options.Validate());
  std::unique_ptr<CloudBuilder> builder(new CloudBuilder(take, options));
  for (const TakeSensor& sensor : take.sensors()) {
    ASSIGN_OR_RETURN(
        carving::PosedCamera camera,
        carving::PosedCamera::Create(sensor.depth_intrinsics, sensor.world_from_depth));
    builder->cameras_.push_back(std::move(camera));
  }
  return builder;
}

absl::StatusOr<bodyfit::PointCloud> CloudBuilder::Build(int instant) const {
  if (instant < 0 || instant >= take_.num_instants()) {
    return absl::InvalidArgumentError(absl::StrCat("instant ", instant, " out of range"));
  }
  bodyfit::PointCloud cloud;
  for (int s = 0; s < take_.num_sensors(); ++s) {
    if (!take_.instant(instant).views[s].present) continue;
    ASSIGN_OR_RETURN(DepthImageMm depth, take_.LoadDepth(instant, s));
    ASSIGN_OR_RETURN(const MaskImage actor, take_.LoadActorMask(instant, s));
    carving::RemoveDepthEdges(options_.edge_filter_mm, &depth);
    carving::SurfaceMapOptions surface_options;
    surface_options.step = options_.step;
    ASSIGN_OR_RETURN(const carving::SurfaceMap surface,
                     carving::BuildSurfaceMap(cameras_[s], depth, &actor, surface_options));
    const size_t begin = cloud.size();
    for (size_t i = 0; i < surface.points_in_world_m.size(); ++i) {
      if (!surface.HasPoint(i) || !surface.HasNormal(i)) continue;
      cloud.points_m.push_back(surface.points_in_world_m[i]);
      cloud.normals.push_back(surface.normals_in_world[i]);
    }
    cloud.sensor_ranges.push_back({s, begin, cloud.size()});
  }
  return cloud;
}

}  // namespace reenact::recon
