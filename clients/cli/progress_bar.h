// A terminal progress bar for long commands: turns the library's Progress
// callbacks into one redrawn line on stderr.
#pragma once

#include <iosfwd>
#include <string>

#include "common/base/progress.h"

namespace reenact::cli {

class ProgressBar {
 public:
  // `enabled` false prints nothing (e.g. with --json or --quiet).
  ProgressBar(std::ostream& err, bool enabled);
  // Redraws the line; returns true (never cancels).
  bool Update(const Progress& progress);
  // Ends the line.
  void Finish();
  ProgressCallback AsCallback();

 private:
  std::ostream& err_;
  bool enabled_;
  int64_t start_ns_;
  int last_permille_ = -1;
  bool drawn_ = false;
};

}  // namespace reenact::cli
