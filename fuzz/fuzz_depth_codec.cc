// The RVLD depth codec on arbitrary bytes: InspectDepth and DecodeDepth on
// the whole input, and the bare RVL decoder on all but its first two bytes,
// which give the pixel count. What decodes must encode and decode back to
// the same pixels.
#include <cstddef>
#include <cstdint>
#include <vector>

#include "absl/types/span.h"
#include "common/io/depth_codec.h"
#include "fuzz/fuzz_util.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string_view bytes = reenact::fuzz::AsView(data, size);
  (void)reenact::InspectDepth(bytes);
  absl::StatusOr<reenact::DepthImageMm> decoded = reenact::DecodeDepth(bytes);
  if (decoded.ok()) {
    absl::StatusOr<std::string> encoded =
        reenact::EncodeDepth(*decoded, reenact::DepthCodecOptions{.zstd = false});
    if (!encoded.ok()) reenact::fuzz::Fail("a decoded depth image does not encode");
    absl::StatusOr<reenact::DepthImageMm> again = reenact::DecodeDepth(*encoded);
    if (!again.ok() || again->width != decoded->width || again->height != decoded->height ||
        again->data != decoded->data) {
      reenact::fuzz::Fail("depth round trip differs");
    }
  }
  if (size < 2) return 0;
  std::vector<uint16_t> values(size_t{data[0]} | size_t{data[1]} << 8);
  if (reenact::RvlDecompress(bytes.substr(2), absl::MakeSpan(values)).ok()) {
    std::vector<uint16_t> again(values.size());
    if (!reenact::RvlDecompress(reenact::RvlCompress(values), absl::MakeSpan(again)).ok() ||
        again != values) {
      reenact::fuzz::Fail("RVL round trip differs");
    }
  }
  return 0;
}
