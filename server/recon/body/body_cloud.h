// The merged point cloud of one instant of a take (thesis 4.3, Fig. 4.3a):
// every sensor's actor depth pixels on a decimated grid, unprojected into
// the world frame with the take's calibration, with normals from the
// neighbouring depth pixels (carving/sensor_frame.h BuildSurfaceMap).
#pragma once

#include <memory>
#include <vector>

#include "absl/status/statusor.h"
#include "common/bodyfit/body_fit.h"
#include "server/recon/carving/sensor_frame.h"
#include "server/recon/take_frames.h"

namespace reenact::recon {

struct CloudOptions {
  int step = 2;             // Depth pixel decimation (>= 1).
  int edge_filter_mm = 30;  // Flying-pixel filter (sensor_frame.h RemoveDepthEdges); 0: off.
  absl::Status Validate() const;
};

class CloudBuilder {
 public:
  // InvalidArgument when a sensor's calibration does not make a camera.
  static absl::StatusOr<std::unique_ptr<CloudBuilder>> Create(const TakeFrames& take,
                                                              const CloudOptions& options = {});
  // The merged cloud of `instant` (sensors without a frame add nothing).
  // Errors of the take's decoders (DataLoss for corrupt frames).
  absl::StatusOr<bodyfit::PointCloud> Build(int instant) const;

 private:
  CloudBuilder(const TakeFrames& take, const CloudOptions& options)
      : take_(take), options_(options) {}
  const TakeFrames& take_;
  CloudOptions options_;
  std::vector<carving::PosedCamera> cameras_;
};

}  // namespace reenact::recon
