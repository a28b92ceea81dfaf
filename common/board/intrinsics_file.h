// Camera intrinsics for a video that is not from a capture sensor, e.g. the
// AR viewer's phone or webcam: a small JSON file, or a default derived from
// the field of view when no calibration is at hand.
//
// File format (pixels; distortion as in common/geometry/camera.h, all 0 when
// absent):
//   {"width": 1280, "height": 720, "fx": 1000, "fy": 1000, "cx": 639.5,
//    "cy": 359.5, "k1": 0, "k2": 0, "p1": 0, "p2": 0, "k3": 0}
// The distortion may instead be given in OpenCV's order as
//   "distortion": [k1, k2, p1, p2, k3]
// (the layout cv::calibrateCamera returns). Without fx, fy, cx and cy the
// file may give "horizontal_fov_deg" instead (IntrinsicsFromFieldOfView).
#pragma once

#include <string>

#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"
#include "common/geometry/camera.h"

namespace reenact::board {

// An ideal camera of `width` x `height` pixels whose image spans
// `horizontal_fov_deg` degrees: fx = fy = (width / 2) / tan(fov / 2), the
// principal point at the image centre ((width - 1) / 2, (height - 1) / 2 with
// pixel centres at integers), no distortion. Phones and webcams filming 16:9
// video see about 60-70 degrees across. InvalidArgument for non-positive sizes
// or a field of view outside (1, 179) degrees.
absl::StatusOr<CameraIntrinsics> IntrinsicsFromFieldOfView(int width, int height,
                                                           double horizontal_fov_deg);

// Parses the JSON form in the file comment. InvalidArgument naming the
// problem for malformed JSON, missing or non-numeric fields, or invalid
// intrinsics.
absl::StatusOr<CameraIntrinsics> ParseIntrinsicsJson(absl::string_view json);

// Reads and parses the file at `path`. NotFound when it does not exist.
absl::StatusOr<CameraIntrinsics> LoadIntrinsicsFile(const std::string& path);

// The JSON form (explicit fx, fy, cx, cy and the five named coefficients).
std::string FormatIntrinsicsJson(const CameraIntrinsics& intrinsics);

}  // namespace reenact::board
