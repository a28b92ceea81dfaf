// Long-running library calls report progress through this callback; the CLI
// turns it into a progress bar, the server into a job-progress stream.
#pragma once

#include <functional>
#include <string>

namespace reenact {

struct Progress {
  std::string stage;        // Short name of the current stage, e.g. "render".
  double fraction = 0.0;    // 0..1 over the whole call.
  int64_t items_done = 0;   // Frames (or other units) done so far.
  int64_t items_total = 0;  // Frames in all, 0 when unknown.
};

// Returns false to ask the callee to stop early (it then returns Cancelled).
using ProgressCallback = std::function<bool(const Progress&)>;

}  // namespace reenact
