// ParseBoardSpec on arbitrary text. A spec that parses must format and parse
// back to the same board, and its markers must be listed.
#include <cstddef>
#include <cstdint>

#include "common/board/board_spec.h"
#include "fuzz/fuzz_util.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  absl::StatusOr<reenact::board::BoardSpec> spec =
      reenact::board::ParseBoardSpec(absl::string_view(reinterpret_cast<const char*>(data), size));
  if (!spec.ok()) return 0;
  const std::vector<reenact::board::BoardMarker> markers = reenact::board::BoardMarkers(*spec);
  if (static_cast<int>(markers.size()) != spec->num_markers()) {
    reenact::fuzz::Fail("BoardMarkers lists another number of markers");
  }
  absl::StatusOr<reenact::board::BoardSpec> again =
      reenact::board::ParseBoardSpec(reenact::board::FormatBoardSpec(*spec));
  if (!again.ok() || again->dictionary != spec->dictionary || again->columns != spec->columns ||
      again->rows != spec->rows || again->first_marker_id != spec->first_marker_id) {
    reenact::fuzz::Fail("a formatted board spec does not parse back");
  }
  return 0;
}
