// JPEG encoding of colour frames through libturbojpeg. Colour is the one
// lossy stream of a take; the quality is stored beside the bytes.
#pragma once

#include <string>
#include <string_view>

#include "absl/status/statusor.h"
#include "common/base/image.h"

namespace reenact {

// Encodes `image` (sRGB, R G B) as a baseline JPEG with 4:2:0 chroma
// subsampling at `quality` (1..100). InvalidArgument for an empty image or a
// quality outside 1..100.
absl::StatusOr<std::string> EncodeJpeg(const RgbImage& image, int quality);

// Decodes a JPEG into an sRGB image. InvalidArgument naming the failure when
// `jpeg` is not a decodable JPEG.
absl::StatusOr<RgbImage> DecodeJpeg(std::string_view jpeg);

}  // namespace reenact
