// The intrinsics file parser (ParseIntrinsicsJson, what LoadIntrinsicsFile
// runs on a file's text) on arbitrary bytes. What parses must format and
// parse back.
#include <cstddef>
#include <cstdint>

#include "common/board/intrinsics_file.h"
#include "fuzz/fuzz_util.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  absl::StatusOr<reenact::CameraIntrinsics> intrinsics = reenact::board::ParseIntrinsicsJson(
      absl::string_view(reinterpret_cast<const char*>(data), size));
  if (!intrinsics.ok()) return 0;
  absl::StatusOr<reenact::CameraIntrinsics> again =
      reenact::board::ParseIntrinsicsJson(reenact::board::FormatIntrinsicsJson(*intrinsics));
  if (!again.ok() || again->width != intrinsics->width || again->height != intrinsics->height ||
      again->fx != intrinsics->fx || again->k1 != intrinsics->k1) {
    reenact::fuzz::Fail("formatted intrinsics do not parse back");
  }
  return 0;
}
