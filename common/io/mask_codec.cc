#include "common/io/mask_codec.h"

#include <algorithm>

#include "absl/strings/str_cat.h"
#include "common/io/depth_codec.h"
#include "common/io/mcap_format.h"

namespace reenact {
namespace {

constexpr std::string_view kMaskMagic = "RLM1";
constexpr size_t kHeaderBytes = 12;
// Larger masks are rejected as malformed rather than allocated.

void PutVarint(std::string* out, uint64_t v) {
  while (v >= 0x80) {
    out->push_back(static_cast<char>((v & 0x7F) | 0x80));
    v >>= 7;
  }
  out->push_back(static_cast<char>(v));
}

absl::Status Malformed(size_t offset, std::string_view what) {
  return absl::InvalidArgumentError(
      absl::StrCat("mask RLE: byte offset ", offset, ": ", std::string(what)));
}

}  // namespace

std::string EncodeMaskRle(const MaskImage& mask) {
  std::string out(kMaskMagic);
  mcap_format::PutU32(&out, static_cast<uint32_t>(mask.width));
  mcap_format::PutU32(&out, static_cast<uint32_t>(mask.height));
  size_t i = 0;
  while (i < mask.data.size()) {
    size_t j = i + 1;
    while (j < mask.data.size() && mask.data[j] == mask.data[i]) ++j;
    out.push_back(static_cast<char>(mask.data[i]));
    PutVarint(&out, j - i - 1);
    i = j;
  }
  return out;
}

absl::StatusOr<MaskImage> DecodeMaskRle(std::string_view bytes, uint64_t max_pixels) {
  if (bytes.size() < kHeaderBytes || bytes.substr(0, 4) != kMaskMagic) {
    return Malformed(0, "missing \"RLM1\" header");
  }
  mcap_format::ByteCursor header(bytes.substr(4, 8));
  const uint32_t width = header.U32();
  const uint32_t height = header.U32();
  const uint64_t pixels = uint64_t{width} * height;
  const uint64_t allowed = std::min(max_pixels, kMaxDecodedImagePixels);
  if (width > (1u << 16) || height > (1u << 16) || pixels > allowed) {
    return Malformed(4, absl::StrCat("implausible size ", width, "x", height, " (at most ", allowed,
                                     " pixels)"));
  }
  MaskImage mask;
  mask.width = static_cast<int>(width);
  mask.height = static_cast<int>(height);
  mask.data.reserve(pixels);
  size_t pos = kHeaderBytes;
  while (pos < bytes.size()) {
    const size_t run_start = pos;
    const auto value = static_cast<uint8_t>(bytes[pos++]);
    uint64_t run = 0;
    for (int shift = 0;; shift += 7) {
      if (pos >= bytes.size()) return Malformed(run_start, "run ends inside its length");
      if (shift > 56) return Malformed(pos, "run length too long");
      const auto b = static_cast<uint8_t>(bytes[pos++]);
      run |= uint64_t{b & 0x7Fu} << shift;
      if ((b & 0x80) == 0) break;
    }
    if (run + 1 > pixels - mask.data.size()) {  // data.size() <= pixels holds here.
      return Malformed(run_start, "runs cover more pixels than the mask has");
    }
    mask.data.insert(mask.data.end(), run + 1, value);
  }
  if (mask.data.size() != pixels) {
    return Malformed(bytes.size(),
                     absl::StrCat("runs cover ", mask.data.size(), " of ", pixels, " pixels"));
  }
  return mask;
}

absl::StatusOr<MaskImage> DecodeMask(std::string_view encoding, std::string_view bytes,
                                     uint64_t max_pixels) {
  if (encoding == "rle") return DecodeMaskRle(bytes, max_pixels);
  if (encoding != "rvl") {
    return absl::InvalidArgumentError(
        absl::StrCat("mask encoding \"", std::string(encoding), "\" unknown (\"rle\" or \"rvl\")"));
  }
  auto decoded = DecodeDepth(bytes, max_pixels);
  if (!decoded.ok()) return absl::InvalidArgumentError(decoded.status().message());
  MaskImage mask(decoded->width, decoded->height);
  for (size_t i = 0; i < decoded->data.size(); ++i) {
    mask.data[i] = static_cast<uint8_t>(std::min<int>(decoded->data[i], 255));
  }
  return mask;
}

}  // namespace reenact
