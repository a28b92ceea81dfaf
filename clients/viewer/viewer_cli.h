// reenact-viewer's command line (the thin main calls RunViewer). Usage:
//
//   reenact-viewer (--server HOST:PORT | --in FILE.reen|DIR) [--reenactment ID]
//                  [--cache DIR] [--list]
//                  [--render-to DIR [--camera orbit|orbit:DEG|sensor:N|path:FILE]
//                   [--frames A:B] [--alpha] [--no-mp4] [--fps F]]
//                  [--width W] [--height H] [--mode vdtm|baked]
//                  [--speed X] [--no-loop] [--seconds S] [--json]
//
// Without --render-to it opens a window (orbit mode, viewer_app.h).
// Exit codes: 0 done, 1 failure (server, files, GL), 2 usage.
#pragma once

#include <iosfwd>
#include <string>
#include <vector>

#include "absl/status/statusor.h"

namespace reenact::viewer {

extern const char kViewerUsage[];

// Runs the viewer with `args` (argv without the program name); messages go
// to `err`, results (--json, --list) to `out`. Returns the exit code.
int RunViewer(const std::vector<std::string>& args, std::ostream& out, std::ostream& err);

// "A:B" (A..B-1), "A:" (A to the end), ":B", or "A" (one instant), clamped
// to `frame_count`; InvalidArgument for bad text or an empty selection.
absl::StatusOr<std::pair<int, int>> ParseFrameRange(const std::string& text, int frame_count);

}  // namespace reenact::viewer
