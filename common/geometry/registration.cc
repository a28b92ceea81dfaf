#include "common/geometry/registration.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>

#include "absl/strings/str_cat.h"
#include "common/base/status_macros.h"

namespace reenact {
namespace {

constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();

// A z-buffer over the colour grid holding the nearest depth (m) per pixel.
class ZBuffer {
 public:
  ZBuffer(int width, int height)
      : width_(width),
        height_(height),
        z_m_(static_cast<size_t>(width) * height, std::numeric_limits<float>::infinity()) {}

  void Splat(int x, int y, float z_m) {
    float& slot = z_m_[static_cast<size_t>(y) * width_ + x];
    slot = std::min(slot, z_m);
  }

  bool IsEmpty(int x, int y) const { return std::isinf(z_m_[static_cast<size_t>(y) * width_ + x]); }

  // Rasterises the triangle (a, b, c) with pixel centres at integer
  // coordinates, interpolating 1/z barycentrically.
  void FillTriangle(const Eigen::Vector2f& a, const Eigen::Vector2f& b, const Eigen::Vector2f& c,
                    float za_m, float zb_m, float zc_m, int max_extent_px) {
    const float min_x = std::min({a.x(), b.x(), c.x()});
    const float max_x = std::max({a.x(), b.x(), c.x()});
    const float min_y = std::min({a.y(), b.y(), c.y()});
    const float max_y = std::max({a.y(), b.y(), c.y()});
    if (max_x - min_x > max_extent_px || max_y - min_y > max_extent_px) return;
    const int x0 = std::max(0, static_cast<int>(std::ceil(min_x)));
    const int x1 = std::min(width_ - 1, static_cast<int>(std::floor(max_x)));
    const int y0 = std::max(0, static_cast<int>(std::ceil(min_y)));
    const int y1 = std::min(height_ - 1, static_cast<int>(std::floor(max_y)));
    const float area = Cross(b - a, c - a);
    if (std::abs(area) < 1e-9f) return;
    const float inverse_area = 1.0f / area;
    constexpr float kEdgeTolerance = -1e-5f;
    for (int y = y0; y <= y1; ++y) {
      for (int x = x0; x <= x1; ++x) {
        const Eigen::Vector2f p(static_cast<float>(x), static_cast<float>(y));
        const float wa = Cross(c - b, p - b) * inverse_area;
        const float wb = Cross(a - c, p - c) * inverse_area;
        const float wc = 1.0f - wa - wb;
        if (wa < kEdgeTolerance || wb < kEdgeTolerance || wc < kEdgeTolerance) continue;
        const float inverse_z = wa / za_m + wb / zb_m + wc / zc_m;
        Splat(x, y, 1.0f / inverse_z);
      }
    }
  }

  DepthImageMm ToDepthImage() const {
    DepthImageMm depth_mm(width_, height_, 0);
    for (size_t i = 0; i < z_m_.size(); ++i) {
      if (!std::isfinite(z_m_[i])) continue;
      const float value_mm = std::round(z_m_[i] * 1000.0f);
      depth_mm.data[i] = static_cast<uint16_t>(std::clamp(value_mm, 1.0f, 65535.0f));
    }
    return depth_mm;
  }

 private:
  static float Cross(const Eigen::Vector2f& u, const Eigen::Vector2f& v) {
    return u.x() * v.y() - u.y() * v.x();
  }

  int width_;
  int height_;
  std::vector<float> z_m_;
};

}  // namespace

absl::Status RegistrationOptions::Validate() const {
  if (color_width < 0 || color_height < 0 || ((color_width == 0) != (color_height == 0))) {
    return absl::InvalidArgumentError(
        absl::StrCat("RegistrationOptions: colour size must be both 0 or both positive, got ",
                     color_width, "x", color_height));
  }
  if (max_depth_step_mm <= 0 || max_triangle_extent_px <= 0) {
    return absl::InvalidArgumentError(
        "RegistrationOptions: max_depth_step_mm and max_triangle_extent_px must be positive");
  }
  return absl::OkStatus();
}

absl::StatusOr<DepthToColorRegistration> DepthToColorRegistration::Create(
    const CameraIntrinsics& depth_intrinsics, const CameraIntrinsics& color_intrinsics,
    const Rigid3d& color_from_depth, const RegistrationOptions& options) {
  RETURN_IF_ERROR(options.Validate());
  RETURN_IF_ERROR(depth_intrinsics.Validate());
  RETURN_IF_ERROR(color_intrinsics.Validate());
  if (!color_from_depth.translation.allFinite() ||
      !color_from_depth.rotation.coeffs().allFinite()) {
    return absl::InvalidArgumentError("DepthToColorRegistration: non-finite colour_from_depth");
  }
  DepthToColorRegistration registration;
  registration.depth_intrinsics_ = depth_intrinsics;
  registration.color_intrinsics_ = color_intrinsics;
  if (options.color_width > 0) {
    ASSIGN_OR_RETURN(registration.color_intrinsics_,
                     ScaledIntrinsics(color_intrinsics, options.color_width, options.color_height));
  }
  registration.color_from_depth_ = color_from_depth;
  registration.options_ = options;
  registration.rays_.resize(static_cast<size_t>(depth_intrinsics.width) * depth_intrinsics.height);
  for (int y = 0; y < depth_intrinsics.height; ++y) {
    for (int x = 0; x < depth_intrinsics.width; ++x) {
      const std::optional<Eigen::Vector3d> ray =
          depth_intrinsics.Unproject(Eigen::Vector2d(x, y), 1.0);
      if (!ray) {
        return absl::InvalidArgumentError(absl::StrCat(
            "DepthToColorRegistration: cannot undistort depth pixel (", x, ", ", y, ")"));
      }
      registration.rays_[static_cast<size_t>(y) * depth_intrinsics.width + x] =
          ray->head<2>().cast<float>();
    }
  }
  return registration;
}

absl::Status DepthToColorRegistration::CheckSize(const DepthImageMm& depth_mm) const {
  if (depth_mm.width != depth_intrinsics_.width || depth_mm.height != depth_intrinsics_.height ||
      depth_mm.data.size() != depth_mm.num_pixels()) {
    return absl::InvalidArgumentError(
        absl::StrCat("registration: depth image is ", depth_mm.width, "x", depth_mm.height, " (",
                     depth_mm.data.size(), " values) but the depth intrinsics are ",
                     depth_intrinsics_.width, "x", depth_intrinsics_.height));
  }
  return absl::OkStatus();
}

void DepthToColorRegistration::ProjectAll(const DepthImageMm& depth_mm,
                                          std::vector<Eigen::Vector2f>* pixels,
                                          std::vector<float>* z_m) const {
  pixels->assign(rays_.size(), Eigen::Vector2f(kNaN, kNaN));
  z_m->assign(rays_.size(), kNaN);
  for (size_t i = 0; i < rays_.size(); ++i) {
    if (depth_mm.data[i] == 0) continue;
    const double depth_m = depth_mm.data[i] * 1e-3;
    const Eigen::Vector3d point_in_depth(rays_[i].x() * depth_m, rays_[i].y() * depth_m, depth_m);
    const Eigen::Vector3d point_in_color = color_from_depth_ * point_in_depth;
    const std::optional<Eigen::Vector2d> pixel = color_intrinsics_.Project(point_in_color);
    if (!pixel) continue;
    (*pixels)[i] = pixel->cast<float>();
    (*z_m)[i] = static_cast<float>(point_in_color.z());
  }
}

absl::StatusOr<DepthImageMm> DepthToColorRegistration::Register(
    const DepthImageMm& depth_mm) const {
  RETURN_IF_ERROR(CheckSize(depth_mm));
  std::vector<Eigen::Vector2f> pixels;
  std::vector<float> z_m;
  ProjectAll(depth_mm, &pixels, &z_m);
  ZBuffer z_buffer(color_intrinsics_.width, color_intrinsics_.height);
  if (options_.fill_footprint) {
    // Two triangles per 2x2 block of valid depth pixels: (a, b, c) and
    // (b, d, c) with a = (x, y), b = (x + 1, y), c = (x, y + 1), d = (x + 1, y + 1).
    const int width = depth_mm.width;
    const auto fill = [&](size_t ia, size_t ib, size_t ic) {
      if (std::isnan(z_m[ia]) || std::isnan(z_m[ib]) || std::isnan(z_m[ic])) return;
      const int low = std::min({depth_mm.data[ia], depth_mm.data[ib], depth_mm.data[ic]});
      const int high = std::max({depth_mm.data[ia], depth_mm.data[ib], depth_mm.data[ic]});
      if (high - low > options_.max_depth_step_mm) return;
      z_buffer.FillTriangle(pixels[ia], pixels[ib], pixels[ic], z_m[ia], z_m[ib], z_m[ic],
                            options_.max_triangle_extent_px);
    };
    for (int y = 0; y + 1 < depth_mm.height; ++y) {
      for (int x = 0; x + 1 < width; ++x) {
        const size_t a = static_cast<size_t>(y) * width + x;
        fill(a, a + 1, a + width);
        fill(a + 1, a + width + 1, a + width);
      }
    }
  }
  // Nearest splat of every valid depth pixel. With triangles, only into
  // pixels they left empty (isolated samples, surface borders), so that the
  // exact interpolated values are not undercut by a neighbour's sample.
  const bool only_empty = options_.fill_footprint;
  for (size_t i = 0; i < pixels.size(); ++i) {
    if (std::isnan(z_m[i])) continue;
    const Eigen::Vector2d pixel = pixels[i].cast<double>();
    if (!color_intrinsics_.IsInside(pixel)) continue;
    const int x = static_cast<int>(std::floor(pixel.x() + 0.5));
    const int y = static_cast<int>(std::floor(pixel.y() + 0.5));
    if (only_empty && !z_buffer.IsEmpty(x, y)) continue;
    z_buffer.Splat(x, y, z_m[i]);
  }
  return z_buffer.ToDepthImage();
}

absl::StatusOr<ColorPixelMap> DepthToColorRegistration::MapDepthPixels(
    const DepthImageMm& depth_mm) const {
  RETURN_IF_ERROR(CheckSize(depth_mm));
  std::vector<Eigen::Vector2f> pixels;
  std::vector<float> z_m;
  ProjectAll(depth_mm, &pixels, &z_m);
  ColorPixelMap map(depth_mm.width, depth_mm.height, kNaN);
  for (size_t i = 0; i < pixels.size(); ++i) {
    if (std::isnan(z_m[i]) || !color_intrinsics_.IsInside(pixels[i].cast<double>())) continue;
    map.data[2 * i] = pixels[i].x();
    map.data[2 * i + 1] = pixels[i].y();
  }
  return map;
}

absl::StatusOr<DepthImageMm> RegisterDepthToColor(const DepthImageMm& depth_mm,
                                                  const CameraIntrinsics& depth_intrinsics,
                                                  const CameraIntrinsics& color_intrinsics,
                                                  const Rigid3d& color_from_depth,
                                                  const RegistrationOptions& options) {
  ASSIGN_OR_RETURN(const DepthToColorRegistration registration,
                   DepthToColorRegistration::Create(depth_intrinsics, color_intrinsics,
                                                    color_from_depth, options));
  return registration.Register(depth_mm);
}

absl::StatusOr<ColorPixelMap> MapDepthPixelsToColor(const DepthImageMm& depth_mm,
                                                    const CameraIntrinsics& depth_intrinsics,
                                                    const CameraIntrinsics& color_intrinsics,
                                                    const Rigid3d& color_from_depth,
                                                    const RegistrationOptions& options) {
  ASSIGN_OR_RETURN(const DepthToColorRegistration registration,
                   DepthToColorRegistration::Create(depth_intrinsics, color_intrinsics,
                                                    color_from_depth, options));
  return registration.MapDepthPixels(depth_mm);
}

}  // namespace reenact
