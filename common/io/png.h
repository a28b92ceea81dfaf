// PNG encoding of rendered and composed frames (8-bit RGB, or RGBA with an
// alpha channel taken from a mask), written with zlib alone after the PNG
// specification (ISO/IEC 15948): signature, IHDR, one IDAT of deflated
// scanlines each with the "Up" filter, IEND, every chunk with its CRC-32.
#pragma once

#include <string>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "common/base/image.h"

namespace reenact {

struct PngOptions {
  // zlib level 0..9: 1 (the default) is fast and still halves rendered
  // frames; 9 is for files kept for good.
  int compression_level = 1;
  // When set (same size as the image), the file is RGBA with alpha 255
  // where the mask is non-zero and 0 elsewhere.
  const MaskImage* alpha_mask = nullptr;
};

// The PNG file's bytes. InvalidArgument for an empty image, a level outside
// 0..9 or a mask of another size; Internal when zlib fails.
absl::StatusOr<std::string> EncodePng(const RgbImage& image, const PngOptions& options = {});

// EncodePng written to `path` (atomically: a temporary file renamed over it).
// The encoder's errors, or the error of writing the file.
absl::Status WritePng(const RgbImage& image, const std::string& path,
                      const PngOptions& options = {});

}  // namespace reenact
