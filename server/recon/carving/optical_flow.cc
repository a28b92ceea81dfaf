#include "server/recon/carving/optical_flow.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/video/tracking.hpp>

#include "absl/strings/str_cat.h"

namespace reenact::recon::carving {

absl::Status FlowOptions::Validate() const {
  if (!(pyramid_scale > 0.0 && pyramid_scale < 1.0)) {
    return absl::InvalidArgumentError(
        absl::StrCat("FlowOptions: pyramid_scale must be in (0, 1), is ", pyramid_scale));
  }
  if (levels < 1 || window_px < 3 || iterations < 1 || (poly_n != 5 && poly_n != 7) ||
      !(poly_sigma > 0.0)) {
    return absl::InvalidArgumentError(absl::StrCat(
        "FlowOptions: levels ", levels, ", window_px ", window_px, ", iterations ", iterations,
        ", poly_n ", poly_n, " (5 or 7), poly_sigma ", poly_sigma, " out of range"));
  }
  return absl::OkStatus();
}

absl::StatusOr<GreyImage> GreyAtSize(const RgbImage& rgb, int width, int height) {
  if (rgb.empty() || rgb.width <= 0 || rgb.height <= 0) {
    return absl::InvalidArgumentError("GreyAtSize: empty image");
  }
  if (width <= 0 || height <= 0) {
    return absl::InvalidArgumentError(absl::StrCat("GreyAtSize: size ", width, "x", height));
  }
  const cv::Mat colour(rgb.height, rgb.width, CV_8UC3, const_cast<uint8_t*>(rgb.data.data()));
  cv::Mat grey;
  cv::cvtColor(colour, grey, cv::COLOR_RGB2GRAY);
  GreyImage result(width, height);
  cv::Mat out(height, width, CV_8UC1, result.data.data());
  if (width == rgb.width && height == rgb.height) {
    grey.copyTo(out);
  } else {
    cv::resize(grey, out, cv::Size(width, height), 0, 0, cv::INTER_AREA);
  }
  return result;
}

absl::StatusOr<FlowField> ComputeOpticalFlow(const GreyImage& earlier, const GreyImage& later,
                                             const FlowOptions& options, const PixelBox& region) {
  if (absl::Status status = options.Validate(); !status.ok()) return status;
  if (earlier.empty() || earlier.width != later.width || earlier.height != later.height) {
    return absl::InvalidArgumentError(absl::StrCat("ComputeOpticalFlow: images ", earlier.width,
                                                   "x", earlier.height, " and ", later.width, "x",
                                                   later.height));
  }
  PixelBox crop{0, 0, earlier.width, earlier.height};
  if (!region.empty()) {
    crop = {std::max(0, region.x0), std::max(0, region.y0), std::min(earlier.width, region.x1),
            std::min(earlier.height, region.y1)};
  }
  FlowField flow(earlier.width, earlier.height, std::numeric_limits<float>::quiet_NaN());
  if (crop.empty()) return flow;
  const cv::Rect rect(crop.x0, crop.y0, crop.x1 - crop.x0, crop.y1 - crop.y0);
  const cv::Mat a = cv::Mat(earlier.height, earlier.width, CV_8UC1,
                            const_cast<uint8_t*>(earlier.data.data()))(rect);
  const cv::Mat b =
      cv::Mat(later.height, later.width, CV_8UC1, const_cast<uint8_t*>(later.data.data()))(rect);
  cv::Mat out(earlier.height, earlier.width, CV_32FC2, flow.data.data());
  cv::Mat out_crop = out(rect);  // Writes into `flow` (a view with the full row stride).
  cv::Mat computed;
  cv::calcOpticalFlowFarneback(a, b, computed, options.pyramid_scale, options.levels,
                               options.window_px, options.iterations, options.poly_n,
                               options.poly_sigma, 0);
  computed.copyTo(out_crop);
  return flow;
}

PixelBox SurfaceBounds(const ColorLookup& lookup, int margin_px) {
  PixelBox box{lookup.width, lookup.height, 0, 0};
  for (int y = 0; y < lookup.height; ++y) {
    for (int x = 0; x < lookup.width; ++x) {
      if (lookup.cell[static_cast<size_t>(y) * lookup.width + x] < 0) continue;
      box.x0 = std::min(box.x0, x);
      box.y0 = std::min(box.y0, y);
      box.x1 = std::max(box.x1, x + 1);
      box.y1 = std::max(box.y1, y + 1);
    }
  }
  if (box.empty()) return PixelBox();
  return {std::max(0, box.x0 - margin_px), std::max(0, box.y0 - margin_px),
          std::min(lookup.width, box.x1 + margin_px), std::min(lookup.height, box.y1 + margin_px)};
}

absl::StatusOr<std::vector<int32_t>> FlowTargets(const SurfaceMap& surface_earlier,
                                                 const PosedCamera& color_camera,
                                                 const ColorLookup& lookup_earlier,
                                                 const FlowField& flow,
                                                 const ColorLookup& lookup_later,
                                                 double visibility_tolerance_m) {
  const int width = color_camera.width();
  const int height = color_camera.height();
  if (flow.width != width || flow.height != height || lookup_earlier.width != width ||
      lookup_earlier.height != height || lookup_later.width != width ||
      lookup_later.height != height) {
    return absl::InvalidArgumentError(absl::StrCat("FlowTargets: flow ", flow.width, "x",
                                                   flow.height, " and lookups must match the ",
                                                   width, "x", height, " colour grid"));
  }
  std::vector<int32_t> targets(surface_earlier.points_in_world_m.size(), -1);
  for (size_t cell = 0; cell < targets.size(); ++cell) {
    if (!surface_earlier.HasPoint(cell)) continue;
    const Eigen::Vector3f in_color = color_camera.ToCamera(surface_earlier.points_in_world_m[cell]);
    Eigen::Vector2f pixel;
    if (!color_camera.ProjectCameraPoint(in_color, &pixel)) continue;
    const int x = static_cast<int>(std::lround(pixel.x()));
    const int y = static_cast<int>(std::lround(pixel.y()));
    if (x < 0 || y < 0 || x >= width || y >= height) continue;
    const size_t at = static_cast<size_t>(y) * width + x;
    if (std::abs(lookup_earlier.z_m[at] - in_color.z()) > visibility_tolerance_m) continue;
    const float dx = flow.at(x, y, 0);
    const float dy = flow.at(x, y, 1);
    if (std::isnan(dx) || std::isnan(dy)) continue;
    const Eigen::Vector2f moved(pixel.x() + dx, pixel.y() + dy);
    const int mx = static_cast<int>(std::lround(moved.x()));
    const int my = static_cast<int>(std::lround(moved.y()));
    if (mx < 0 || my < 0 || mx >= width || my >= height) continue;
    targets[cell] = lookup_later.cell[static_cast<size_t>(my) * width + mx];
  }
  return targets;
}

}  // namespace reenact::recon::carving
