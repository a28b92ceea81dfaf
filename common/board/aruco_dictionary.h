// Internal to reenact_board: OpenCV's predefined ArUco dictionaries by name.
// Not installed with the public headers; only the .cc files include it.
#pragma once

#include <opencv2/aruco.hpp>

#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"

namespace reenact::board::internal {

// The predefined dictionary called `name` (case-insensitive), e.g.
// "DICT_4X4_50". InvalidArgument for an unknown name.
absl::StatusOr<cv::Ptr<cv::aruco::Dictionary>> GetArucoDictionary(absl::string_view name);

}  // namespace reenact::board::internal
