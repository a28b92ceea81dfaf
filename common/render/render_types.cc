#include "common/render/render_types.h"

#include <cmath>

#include "absl/strings/str_cat.h"

namespace reenact::render {

absl::Status RenderCamera::Validate() const {
  if (width <= 0 || height <= 0) {
    return absl::InvalidArgumentError(
        absl::StrCat("RenderCamera: size ", width, "x", height, " must be positive"));
  }
  if (!(fx > 0.0) || !(fy > 0.0) || !std::isfinite(fx) || !std::isfinite(fy) ||
      !std::isfinite(cx) || !std::isfinite(cy)) {
    return absl::InvalidArgumentError(
        absl::StrCat("RenderCamera: bad intrinsics fx=", fx, " fy=", fy, " cx=", cx, " cy=", cy));
  }
  if (!(near_m > 0.0) || !(far_m > near_m) || !std::isfinite(far_m)) {
    return absl::InvalidArgumentError(
        absl::StrCat("RenderCamera: need 0 < near_m < far_m, got ", near_m, " and ", far_m));
  }
  if (!world_from_camera.matrix().allFinite()) {
    return absl::InvalidArgumentError("RenderCamera: world_from_camera is not finite");
  }
  return absl::OkStatus();
}

Eigen::Matrix4d ClipFromCamera(const RenderCamera& camera) {
  const double w = camera.width, h = camera.height;
  const double n = camera.near_m, f = camera.far_m;
  Eigen::Matrix4d clip = Eigen::Matrix4d::Zero();
  // x_ndc = 2 x_pixel / width - 1 with x_pixel = fx X / Z + cx (and likewise
  // y), so NDC -1 is the left (top) edge of pixel 0 and +1 the right (bottom)
  // edge of the last pixel.
  clip(0, 0) = 2.0 * camera.fx / w;
  clip(0, 2) = 2.0 * camera.cx / w - 1.0;
  clip(1, 1) = 2.0 * camera.fy / h;
  clip(1, 2) = 2.0 * camera.cy / h - 1.0;
  clip(2, 2) = (f + n) / (f - n);
  clip(2, 3) = -2.0 * f * n / (f - n);
  clip(3, 2) = 1.0;
  return clip;
}

absl::Status ShadingOptions::Validate() const {
  if (!(ambient >= 0.0f) || !(diffuse >= 0.0f)) {
    return absl::InvalidArgumentError("ShadingOptions: ambient and diffuse must be >= 0");
  }
  if (!headlight && !(direction_to_light_in_world.norm() > 0.0)) {
    return absl::InvalidArgumentError("ShadingOptions: direction_to_light_in_world is zero");
  }
  if (!(background_srgb.array() >= 0.0f).all() || !(background_srgb.array() <= 1.0f).all()) {
    return absl::InvalidArgumentError("ShadingOptions: background_srgb outside [0,1]");
  }
  return absl::OkStatus();
}

absl::Status RendererOptions::Validate() const {
  constexpr int kMaxSize = 16384;
  if (max_width < 1 || max_height < 1 || max_width > kMaxSize || max_height > kMaxSize) {
    return absl::InvalidArgumentError(absl::StrCat("RendererOptions: size ", max_width, "x",
                                                   max_height, " outside [1, ", kMaxSize, "]"));
  }
  if (msaa_samples != 0 && msaa_samples != 2 && msaa_samples != 4 && msaa_samples != 8) {
    return absl::InvalidArgumentError(
        absl::StrCat("RendererOptions: msaa_samples ", msaa_samples, " is not 0, 2, 4 or 8"));
  }
  return absl::OkStatus();
}

}  // namespace reenact::render
