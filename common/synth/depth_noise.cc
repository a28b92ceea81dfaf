#include "common/synth/depth_noise.h"

#include <algorithm>
#include <cmath>
#include <random>

#include <Eigen/Core>

namespace reenact::synth {
namespace {

constexpr double kHalfPi = 1.5707963267948966;

// Back-projected point of pixel (x, y) with depth z (camera frame, metres);
// OpenCV convention: pixel (x, y) is centred on the integer coordinates.
Eigen::Vector3d PointAt(const CameraIntrinsics& k, int x, int y, double z) {
  return {(x - k.cx) / k.fx * z, (y - k.cy) / k.fy * z, z};
}

// Incidence angle at (x, y) from the depth image's local surface normal;
// returns a negative value where the neighbourhood is incomplete.
double IncidenceAngle(const FloatImage& depth, const CameraIntrinsics& k, int x, int y) {
  if (x <= 0 || y <= 0 || x >= depth.width - 1 || y >= depth.height - 1) return -1.0;
  const double z = depth.at(x, y);
  const double zr = depth.at(x + 1, y), zl = depth.at(x - 1, y);
  const double zd = depth.at(x, y + 1), zu = depth.at(x, y - 1);
  if (zr <= 0 || zl <= 0 || zd <= 0 || zu <= 0) return -1.0;
  // Central differences, falling back to one side across discontinuities.
  const double jump = 0.05;
  const int xa = std::abs(zr - z) < jump ? x + 1 : x, xb = std::abs(zl - z) < jump ? x - 1 : x;
  const int ya = std::abs(zd - z) < jump ? y + 1 : y, yb = std::abs(zu - z) < jump ? y - 1 : y;
  // Steps on both sides in the same direction are a surface seen almost
  // edge-on (depth changes faster than a pixel per pixel), not a silhouette.
  const bool steep_x = xa == xb && (zr - z) * (z - zl) > 0;
  const bool steep_y = ya == yb && (zd - z) * (z - zu) > 0;
  if (steep_x || steep_y) return kHalfPi;
  if (xa == xb || ya == yb) return -1.0;
  const Eigen::Vector3d dx =
      PointAt(k, xa, y, depth.at(xa, y)) - PointAt(k, xb, y, depth.at(xb, y));
  const Eigen::Vector3d dy =
      PointAt(k, x, ya, depth.at(x, ya)) - PointAt(k, x, yb, depth.at(x, yb));
  const Eigen::Vector3d n = dx.cross(dy);
  const Eigen::Vector3d ray = PointAt(k, x, y, z);
  if (n.norm() < 1e-12) return -1.0;
  const double c = std::abs(n.dot(ray)) / (n.norm() * ray.norm());
  return std::acos(std::clamp(c, 0.0, 1.0));
}

uint16_t ToMm(double z_m, const DepthNoiseOptions& options) {
  if (!(z_m >= options.min_range_m && z_m <= options.max_range_m)) return 0;
  return static_cast<uint16_t>(std::lround(z_m * 1000.0));
}

}  // namespace

absl::Status DepthNoiseOptions::Validate() const {
  if (!(min_range_m > 0 && max_range_m > min_range_m && max_range_m < 65.0)) {
    return absl::InvalidArgumentError("depth noise: need 0 < min_range_m < max_range_m < 65");
  }
  if (!(max_incidence_deg > 0 && max_incidence_deg <= 90)) {
    return absl::InvalidArgumentError("depth noise: max_incidence_deg must be in (0, 90]");
  }
  if (sigma_lateral_px < 0 || edge_jump_m <= 0 || axial_noise_scale < 0 ||
      flying_pixel_probability < 0 || flying_pixel_probability > 1) {
    return absl::InvalidArgumentError("depth noise: negative sigma or probability out of [0,1]");
  }
  return absl::OkStatus();
}

double KinectV2AxialSigmaMm(double z_m, double theta_rad) {
  const double theta = std::clamp(theta_rad, 0.0, kHalfPi - 1e-3);
  const double grazing = theta * theta / ((kHalfPi - theta) * (kHalfPi - theta));
  // Fankhauser et al. 2015, axial noise model (mm, z in m).
  return 1.5 - 0.5 * z_m + 0.3 * z_m * z_m + 0.1 * std::pow(z_m, 1.5) * grazing;
}

DepthImageMm QuantizeDepth(const FloatImage& ideal_depth_m, const DepthNoiseOptions& options) {
  DepthImageMm out(ideal_depth_m.width, ideal_depth_m.height);
  for (size_t i = 0; i < ideal_depth_m.data.size(); ++i) {
    out.data[i] = ToMm(ideal_depth_m.data[i], options);
  }
  return out;
}

DepthImageMm ApplyKinectV2DepthNoise(const FloatImage& ideal, const CameraIntrinsics& k,
                                     const DepthNoiseOptions& options, uint64_t seed) {
  if (!options.enabled) return QuantizeDepth(ideal, options);
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> normal(0.0, 1.0);
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  const double max_theta = options.max_incidence_deg * M_PI / 180.0;
  DepthImageMm out(ideal.width, ideal.height);
  for (int y = 0; y < ideal.height; ++y) {
    for (int x = 0; x < ideal.width; ++x) {
      // Lateral noise: sample the scene at a jittered position.
      const int sx =
          std::clamp(x + static_cast<int>(std::lround(normal(rng) * options.sigma_lateral_px)), 0,
                     ideal.width - 1);
      const int sy =
          std::clamp(y + static_cast<int>(std::lround(normal(rng) * options.sigma_lateral_px)), 0,
                     ideal.height - 1);
      double z = ideal.at(sx, sy);
      if (z <= 0) continue;
      // Flying pixels: mix with the farthest 4-neighbour across a discontinuity.
      double z_far = z;
      const int nx[4] = {sx + 1, sx - 1, sx, sx};
      const int ny[4] = {sy, sy, sy + 1, sy - 1};
      for (int n = 0; n < 4; ++n) {
        if (nx[n] < 0 || ny[n] < 0 || nx[n] >= ideal.width || ny[n] >= ideal.height) continue;
        const double zn = ideal.at(nx[n], ny[n]);
        if (zn > z_far) z_far = zn;
      }
      if (z_far - z > options.edge_jump_m && uniform(rng) < options.flying_pixel_probability) {
        z = z + uniform(rng) * (z_far - z);
        out.at(x, y) = ToMm(z, options);
        continue;
      }
      const double theta = IncidenceAngle(ideal, k, sx, sy);
      if (theta > max_theta) continue;  // Grazing incidence: no valid return.
      const double sigma_mm =
          options.axial_noise_scale * KinectV2AxialSigmaMm(z, theta < 0 ? 0.0 : theta);
      z += normal(rng) * sigma_mm * 1e-3;
      out.at(x, y) = ToMm(z, options);
    }
  }
  return out;
}

}  // namespace reenact::synth
