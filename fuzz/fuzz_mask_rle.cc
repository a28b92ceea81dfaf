// The actor mask decoders on arbitrary bytes: DecodeMaskRle ("rle") and
// DecodeMask("rvl"). What decodes must encode and decode back unchanged.
#include <cstddef>
#include <cstdint>

#include "common/io/mask_codec.h"
#include "fuzz/fuzz_util.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string_view bytes = reenact::fuzz::AsView(data, size);
  absl::StatusOr<reenact::MaskImage> mask = reenact::DecodeMaskRle(bytes);
  if (mask.ok()) {
    absl::StatusOr<reenact::MaskImage> again =
        reenact::DecodeMaskRle(reenact::EncodeMaskRle(*mask));
    if (!again.ok() || again->width != mask->width || again->height != mask->height ||
        again->data != mask->data) {
      reenact::fuzz::Fail("mask RLE round trip differs");
    }
  }
  (void)reenact::DecodeMask("rvl", bytes);
  return 0;
}
