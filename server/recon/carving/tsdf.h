// The voxel volume V_b of one body part and its truncated signed distance
// function (thesis 3.4.1, "Body part mesh reconstruction", after Newcombe et
// al. [45] and Malleson et al. [57]):
//
//   F(v)      = sum_n F_{D_n}(v) / N*(v)                            (Eq. 3.10)
//   F_{D_n}(v) = mu       if eta(v) >= mu
//              = eta(v)   if -mu <= eta(v) < mu                     (Eq. 3.11)
//              = ignored  if eta(v) < -mu  (not counted in N*(v))
//
// eta(v) is the projective signed distance of voxel v, placed in the world by
// the part's transform T_{b,n}: the observed depth at the pixel v projects to
// minus v's depth along the sensor's optical axis (positive in front of the
// surface, i.e. outside). Every valid depth pixel counts, background too: a
// voxel in front of the wall behind the actor is free space (eta >= mu) and
// is carved away. Pixels without depth (0) and voxels outside the image add
// nothing. Sums run over all instants and sensors.
//
// Departures from the thesis: the thesis writes the ignored case as
// F_{D_n} = 0 with N* excluding it, which is the same thing. Optionally,
// near-surface contributions (eta < mu) can be restricted to depth pixels
// whose ownership label the volume accepts (e.g. the pixels of this part):
// the volume of a part is a box that also holds pieces of neighbouring parts
// (the torso beside a hanging arm) and of the room (the floor under a foot),
// whose surfaces would otherwise be carved into this part's shape.
// Free-space contributions (eta >= mu) always count.
#pragma once

#include <array>
#include <cstdint>
#include <limits>
#include <vector>

#include <Eigen/Core>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "common/base/image.h"
#include "common/geometry/transforms.h"
#include "server/recon/carving/marching_cubes.h"
#include "server/recon/carving/sensor_frame.h"

namespace reenact::recon::carving {

// The box of V_b in the part frame: W_b x H_b x D_b = nx x ny x nz voxels of
// side voxel_m; voxel (i, j, k) is centred at min_corner + voxel_m (i, j, k).
struct VolumeBox {
  Eigen::Vector3d min_corner_in_part_m = Eigen::Vector3d::Zero();
  double voxel_m = 0.008;
  int nx = 0;
  int ny = 0;
  int nz = 0;

  int64_t num_voxels() const { return static_cast<int64_t>(nx) * ny * nz; }
  Eigen::Vector3d max_corner_in_part_m() const {
    return min_corner_in_part_m + voxel_m * Eigen::Vector3d(nx - 1, ny - 1, nz - 1);
  }
  // True when a part-frame point lies within the box (voxel centres' hull
  // grown by half a voxel).
  bool Contains(const Eigen::Vector3d& point_in_part_m) const;
  // InvalidArgument for non-positive sizes, a non-positive voxel, or more
  // than 2^27 voxels.
  absl::Status Validate() const;
};

// The box around a bone (part frame, +Y along the bone) from y = y_min to
// y_max with |x|, |z| <= radius, rounded out to whole voxels.
VolumeBox BoneBox(double y_min_m, double y_max_m, double radius_m, double voxel_m);

// Which depth pixels may add near-surface values to a volume: a label per
// depth pixel on the grid of every `step`-th pixel (pixel (x, y) reads label
// (x / step, y / step)), and the labels the volume accepts. Pixels with
// other labels add free-space values only.
// A depth value (mm) that marks a pixel whose ray is free space as far as
// the sensor reaches (no return, off the actor): Integrate counts every voxel
// on it up to its free_ray_max_m as free, and leaves those beyond unobserved
// (an actor past the sensor's range returns nothing either).
inline constexpr uint16_t kFreeRayMm = 65535;

struct SurfaceOwnership {
  const MaskImage* labels = nullptr;
  int step = 1;
  std::array<bool, 256> accepted{};  // accepted[label].
};

class TsdfVolume {
 public:
  // InvalidArgument for an invalid box or mu_m <= 0.
  static absl::StatusOr<TsdfVolume> Create(const VolumeBox& box, double mu_m);

  // Adds the contribution of one depth image (Eq. 3.11) for the part posed
  // at `world_from_part` (T_{b,n}). `ownership` may be null. InvalidArgument
  // when the depth size differs from the camera's or the labels' grid does
  // not cover it. `free_ray_max_m`: how far a kFreeRayMm pixel's ray counts
  // as free.
  absl::Status Integrate(const PosedCamera& camera, const DepthImageMm& depth_mm,
                         const Rigid3d& world_from_part,
                         const SurfaceOwnership* ownership = nullptr,
                         float free_ray_max_m = std::numeric_limits<float>::infinity());

  // F(v) of Eq. 3.10 per voxel with observed = (N*(v) > 0), in the part frame.
  SdfGrid ToSdfGrid() const;

  const VolumeBox& box() const { return box_; }
  double mu_m() const { return mu_m_; }
  // N*(v) of voxel (i, j, k).
  int32_t count(int i, int j, int k) const { return count_[Index(i, j, k)]; }
  // F(v) of voxel (i, j, k); 0 when N* = 0.
  float value(int i, int j, int k) const;

 private:
  TsdfVolume(const VolumeBox& box, double mu_m);
  size_t Index(int i, int j, int k) const {
    return static_cast<size_t>(i) +
           static_cast<size_t>(box_.nx) * (j + static_cast<size_t>(box_.ny) * k);
  }

  VolumeBox box_;
  double mu_m_ = 0.0;
  std::vector<float> sum_;      // Sum of F_{D_n}(v), metres.
  std::vector<int32_t> count_;  // N*(v).
};

}  // namespace reenact::recon::carving
