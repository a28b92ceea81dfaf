// A take made for one reader (ReadTakeRequest.selection in
// proto/reenact/v1/work_service.proto): every message of the take a worker
// reads, with the image bytes of only the frames it needs. A phase of a
// take split across workers streams this instead of the whole take.
//
// The made take keeps /take/info, the calibrations, every skeleton, ingest
// record and sensor-lost record, and every depth, mask and colour message:
// a frame outside the selection keeps its message (stamps, frame_index,
// sizes, encoding) with `data` left empty, so that its frames group into
// the same instants as the whole take's (server/recon/take_frames.h). The
// ground truth is left out.
#pragma once

#include <cstdint>
#include <functional>
#include <string>

#include "absl/status/status.h"
#include "common/io/take.h"
#include "reenact/v1/take.pb.h"

namespace reenact {

// Most ranges a selection may hold (depth and colour together).
inline constexpr int kMaxSelectionRanges = 65536;

// InvalidArgument for more than kMaxSelectionRanges ranges, a range of a
// sensor the take does not have, or one with first < 0 or end < first.
absl::Status ValidateTakeSelection(const TakeReader& take, const v1::TakeSelection& selection);

// Writes the selected take to `path` (created or replaced). Errors of
// ValidateTakeSelection; InvalidArgument for a sensor channel that does not
// hold its message type; DataLoss for a message that does not parse;
// Cancelled once `cancelled` returns true (asked between messages);
// the writer's errors. On an error `path` may hold a partial file.
absl::Status WriteTakeSelection(const TakeReader& take, const v1::TakeSelection& selection,
                                const std::string& path,
                                const std::function<bool()>& cancelled = {});

}  // namespace reenact
