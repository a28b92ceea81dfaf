// Lossless run-length coding of actor masks (0 = background, > 0 = body
// index), the "rle" encoding of reenact.v1.ActorMask.
//
// Layout (little-endian): "RLM1", width (uint32), height (uint32), then runs
// in row-major order, each a value byte followed by the run length minus one
// as an unsigned LEB128 varint. Runs cross row ends.
#pragma once

#include <cstdint>
#include <string>
#include <string_view>

#include "absl/status/statusor.h"
#include "common/base/image.h"

namespace reenact {

// Encodes `mask`; an empty mask encodes as a 0x0 image.
std::string EncodeMaskRle(const MaskImage& mask);

// Decodes bytes from EncodeMaskRle. InvalidArgument naming the byte offset
// when the bytes are malformed, truncated, or cover more or fewer pixels than
// the stated size, or state more than `max_pixels` pixels (checked before
// anything is allocated; at most kMaxDecodedImagePixels whatever is asked).
absl::StatusOr<MaskImage> DecodeMaskRle(std::string_view bytes,
                                        uint64_t max_pixels = kMaxDecodedImagePixels);

// Decodes a mask in either encoding of reenact.v1.ActorMask: "rle" (above)
// or "rvl" (depth_codec.h; values above 255 saturate). InvalidArgument for
// malformed bytes or another encoding.
absl::StatusOr<MaskImage> DecodeMask(std::string_view encoding, std::string_view bytes,
                                     uint64_t max_pixels = kMaxDecodedImagePixels);

}  // namespace reenact
