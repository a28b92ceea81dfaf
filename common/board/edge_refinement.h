// Internal to reenact_board: subpixel marker corners from the marker's four
// outer edges.
//
// Why not cv::cornerSubPix alone: on a blurred image (lens, demosaicing, a
// texture filter) the gradient-orthogonality fixed point of a convex corner
// moves toward the inside of the corner by a fraction of the blur width, so
// every marker comes out slightly small and the board slightly far (about 0.4
// px per corner, 8-15 mm at 1.5 m, on our rendered views). A blurred straight
// edge, by contrast, still crosses the mid level between its two sides at its
// true position when the blur is symmetric and the intensities are linear in
// light. So each side of the marker is sampled across at many points, the
// crossings are fitted with a line (in undistorted pixel coordinates, where
// the sides are straight), and the corners are the intersections of
// neighbouring lines.
#pragma once

#include <array>

#include <opencv2/core.hpp>

#include "common/geometry/camera.h"

namespace reenact::board::internal {

// The image converted for edge search: grey, linear light in [0, 1] (the
// sRGB transfer function undone), CV_32FC1.
cv::Mat LinearGrey(const cv::Mat& grey_srgb);

// Refines the corners of one marker (clockwise, pixels, origin at the centre
// of the top-left pixel) in place from its outer edges. `cells_per_side` is
// the marker's cells across, border included. False, leaving the corners
// unchanged, when a side has too few clear edge crossings (e.g. occluded,
// too small or at the image border).
bool RefineCornersFromEdges(const cv::Mat& linear_grey, const CameraIntrinsics& intrinsics,
                            int cells_per_side, std::array<cv::Point2f, 4>* corners);

}  // namespace reenact::board::internal
