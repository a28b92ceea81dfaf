#include "server/recon/carving/tsdf.h"

#include <cmath>

#include "absl/strings/str_cat.h"

namespace reenact::recon::carving {

bool VolumeBox::Contains(const Eigen::Vector3d& point_in_part_m) const {
  const Eigen::Vector3d lo = min_corner_in_part_m - Eigen::Vector3d::Constant(0.5 * voxel_m);
  const Eigen::Vector3d hi = max_corner_in_part_m() + Eigen::Vector3d::Constant(0.5 * voxel_m);
  return (point_in_part_m.array() >= lo.array()).all() &&
         (point_in_part_m.array() <= hi.array()).all();
}

absl::Status VolumeBox::Validate() const {
  if (nx <= 0 || ny <= 0 || nz <= 0) {
    return absl::InvalidArgumentError(absl::StrCat("VolumeBox: size ", nx, "x", ny, "x", nz));
  }
  if (!(voxel_m > 0.0) || !std::isfinite(voxel_m) || !min_corner_in_part_m.allFinite()) {
    return absl::InvalidArgumentError(absl::StrCat("VolumeBox: voxel_m ", voxel_m));
  }
  if (num_voxels() > (int64_t{1} << 27)) {
    return absl::InvalidArgumentError(absl::StrCat("VolumeBox: ", num_voxels(), " voxels"));
  }
  return absl::OkStatus();
}

VolumeBox BoneBox(double y_min_m, double y_max_m, double radius_m, double voxel_m) {
  VolumeBox box;
  box.voxel_m = voxel_m;
  const int half_xz = static_cast<int>(std::ceil(radius_m / voxel_m));
  const int first_y = static_cast<int>(std::floor(y_min_m / voxel_m));
  const int last_y = static_cast<int>(std::ceil(y_max_m / voxel_m));
  box.nx = box.nz = 2 * half_xz + 1;
  box.ny = last_y - first_y + 1;
  box.min_corner_in_part_m =
      Eigen::Vector3d(-half_xz * voxel_m, first_y * voxel_m, -half_xz * voxel_m);
  return box;
}

absl::StatusOr<TsdfVolume> TsdfVolume::Create(const VolumeBox& box, double mu_m) {
  if (absl::Status status = box.Validate(); !status.ok()) return status;
  if (!(mu_m > 0.0) || !std::isfinite(mu_m)) {
    return absl::InvalidArgumentError(absl::StrCat("TsdfVolume: mu_m must be > 0, is ", mu_m));
  }
  return TsdfVolume(box, mu_m);
}

TsdfVolume::TsdfVolume(const VolumeBox& box, double mu_m)
    : box_(box),
      mu_m_(mu_m),
      sum_(static_cast<size_t>(box.num_voxels()), 0.0f),
      count_(static_cast<size_t>(box.num_voxels()), 0) {}

float TsdfVolume::value(int i, int j, int k) const {
  const size_t index = Index(i, j, k);
  return count_[index] > 0 ? sum_[index] / static_cast<float>(count_[index]) : 0.0f;
}

absl::Status TsdfVolume::Integrate(const PosedCamera& camera, const DepthImageMm& depth_mm,
                                   const Rigid3d& world_from_part,
                                   const SurfaceOwnership* ownership, float free_ray_max_m) {
  const int width = depth_mm.width;
  const int height = depth_mm.height;
  if (width != camera.width() || height != camera.height()) {
    return absl::InvalidArgumentError(absl::StrCat("TsdfVolume::Integrate: depth ", width, "x",
                                                   height, ", camera ", camera.width(), "x",
                                                   camera.height()));
  }
  if (ownership && ownership->labels) {
    const int step = ownership->step;
    if (step < 1 || ownership->labels->width < (width + step - 1) / step ||
        ownership->labels->height < (height + step - 1) / step) {
      return absl::InvalidArgumentError("TsdfVolume::Integrate: labels do not cover the depth");
    }
  } else {
    ownership = nullptr;
  }
  // camera_from_part, so that a voxel steps by a constant vector along x.
  const Rigid3d camera_from_world = camera.world_from_camera().Inverse();
  const Rigid3d camera_from_part = camera_from_world * world_from_part;
  const Eigen::Matrix3f rotation = camera_from_part.rotation.toRotationMatrix().cast<float>();
  const Eigen::Vector3f translation = camera_from_part.translation.cast<float>();
  const float voxel = static_cast<float>(box_.voxel_m);
  const Eigen::Vector3f step_x = rotation.col(0) * voxel;
  const Eigen::Vector3f origin = box_.min_corner_in_part_m.cast<float>();
  const float mu = static_cast<float>(mu_m_);
  for (int k = 0; k < box_.nz; ++k) {
    for (int j = 0; j < box_.ny; ++j) {
      Eigen::Vector3f in_camera =
          rotation * (origin + Eigen::Vector3f(0.0f, j * voxel, k * voxel)) + translation;
      size_t index = Index(0, j, k);
      for (int i = 0; i < box_.nx; ++i, ++index, in_camera += step_x) {
        Eigen::Vector2f pixel;
        if (!camera.ProjectCameraPoint(in_camera, &pixel)) continue;
        // Range-checked before the conversion: a voxel just in front of the
        // camera projects far beyond what an int holds.
        if (!(pixel.x() >= -0.5f && pixel.y() >= -0.5f && pixel.x() < width - 0.5f &&
              pixel.y() < height - 0.5f)) {
          continue;
        }
        // The nearest pixel, halves up: both are >= -0.5 here, where the
        // truncation is a floor (std::lround would take -0.5 to -1, off the
        // image).
        // NOLINTBEGIN(bugprone-incorrect-roundings)
        const int x = static_cast<int>(pixel.x() + 0.5f);
        const int y = static_cast<int>(pixel.y() + 0.5f);
        // NOLINTEND(bugprone-incorrect-roundings)
        const uint16_t observed_mm = depth_mm.at(x, y);
        if (observed_mm == 0) continue;
        if (observed_mm == kFreeRayMm) {
          if (in_camera.z() > free_ray_max_m) continue;  // Past the sensor's reach.
          sum_[index] += mu;
          ++count_[index];
          continue;
        }
        const float eta = observed_mm * 0.001f - in_camera.z();  // Projective distance.
        if (eta < -mu) continue;  // Eq. 3.11: behind the surface, ignored.
        float contribution = mu;
        if (eta < mu) {
          if (ownership) {
            const uint8_t label = ownership->labels->at(x / ownership->step, y / ownership->step);
            if (!ownership->accepted[label]) continue;
          }
          contribution = eta;
        }
        sum_[index] += contribution;  // Eq. 3.10 numerator,
        ++count_[index];              // and N*(v).
      }
    }
  }
  return absl::OkStatus();
}

SdfGrid TsdfVolume::ToSdfGrid() const {
  SdfGrid grid;
  grid.nx = box_.nx;
  grid.ny = box_.ny;
  grid.nz = box_.nz;
  grid.origin_m = box_.min_corner_in_part_m;
  grid.voxel_m = box_.voxel_m;
  grid.sdf.resize(sum_.size());
  grid.observed.resize(sum_.size());
  for (size_t index = 0; index < sum_.size(); ++index) {
    const bool seen = count_[index] > 0;
    grid.observed[index] = seen ? 1 : 0;
    grid.sdf[index] = seen ? sum_[index] / static_cast<float>(count_[index]) : 0.0f;  // Eq. 3.10.
  }
  return grid;
}

}  // namespace reenact::recon::carving
