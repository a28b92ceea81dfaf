// Dense optical flow between consecutive colour images of one sensor, and
// the point-to-point correspondences it gives the registration's E_o term
// (thesis 3.4.1, Eq. 3.8): depth point of D_{n-1} -> the colour pixel it is
// seen at in I_{n-1} -> along the flow -> the depth point of D_n seen at that
// colour pixel in I_n.
//
// The flow is Farneback's (G. Farneback, "Two-frame motion estimation based
// on polynomial expansion", SCIA 2003; cv::calcOpticalFlowFarneback) on grey
// images at a reduced resolution: the flow only proposes pairs, which the
// registration then filters by distance.
#pragma once

#include <cstdint>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "common/base/image.h"
#include "server/recon/carving/sensor_frame.h"

namespace reenact::recon::carving {

using GreyImage = Image<uint8_t, 1>;
// Per pixel of the earlier image, the displacement (dx, dy) in pixels to the
// matching pixel of the later image.
using FlowField = Image<float, 2>;

struct FlowOptions {
  double pyramid_scale = 0.5;  // Farneback: image scale between pyramid levels.
  int levels = 3;              // Pyramid levels.
  int window_px = 9;           // Averaging window.
  int iterations = 3;          // Iterations per level.
  int poly_n = 5;              // Pixel neighbourhood of the polynomial expansion.
  double poly_sigma = 1.1;     // Gaussian of the expansion.

  absl::Status Validate() const;
};

// `rgb` converted to grey (Rec. 601 luma) and resized to width x height with
// area averaging. InvalidArgument for an empty image or a non-positive size.
absl::StatusOr<GreyImage> GreyAtSize(const RgbImage& rgb, int width, int height);

// A pixel rectangle [x0, x1) x [y0, y1).
struct PixelBox {
  int x0 = 0;
  int y0 = 0;
  int x1 = 0;
  int y1 = 0;
  bool empty() const { return x1 <= x0 || y1 <= y0; }
};

// Dense flow from `earlier` to `later` (same size). With a non-empty
// `region`, the flow is computed on that crop of both images only (clamped
// to the image) and is NaN elsewhere. InvalidArgument for mismatched or
// empty images and bad options.
absl::StatusOr<FlowField> ComputeOpticalFlow(const GreyImage& earlier, const GreyImage& later,
                                             const FlowOptions& options = {},
                                             const PixelBox& region = {});

// The bounding box of the pixels of `lookup` that see a surface point, grown
// by `margin_px` and clamped to the grid; empty when there is none.
PixelBox SurfaceBounds(const ColorLookup& lookup, int margin_px);

// For every cell of `surface_earlier` (D_{n-1}'s surface), the cell of
// `surface_later` (D_n's) that the flow leads to, or -1: the cell's point is
// projected into the colour grid of `color_camera` (the flow's resolution);
// it must be the point the colour camera sees there (its depth within
// `visibility_tolerance_m` of `lookup_earlier`'s); the flow at that pixel
// moves it (no target where the flow is NaN); `lookup_later` names the D_n
// point seen at the end.
// InvalidArgument when the flow and lookups do not match the camera's size.
absl::StatusOr<std::vector<int32_t>> FlowTargets(const SurfaceMap& surface_earlier,
                                                 const PosedCamera& color_camera,
                                                 const ColorLookup& lookup_earlier,
                                                 const FlowField& flow,
                                                 const ColorLookup& lookup_later,
                                                 double visibility_tolerance_m = 0.03);

}  // namespace reenact::recon::carving
