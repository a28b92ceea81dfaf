// Progress of long commands on stderr: on a terminal one line redrawn in
// place ("\r"); piped or logged, plain lines instead (one per stage, then at
// most one per 10 % of progress or per 5 s, and the last), so that a log
// file holds readable lines and no carriage returns.
#pragma once

#include <cstdint>
#include <iosfwd>
#include <string>

#include "common/base/progress.h"

namespace reenact::cli {

// Writes progress lines to `err` as above.
class ProgressLine {
 public:
  // `enabled` false prints nothing (e.g. with --json or --quiet);
  // `terminal`: redraw one line (see IsTerminal).
  ProgressLine(std::ostream& err, bool enabled, bool terminal);
  // Whether `err` is the process's stderr and that is a terminal.
  static bool IsTerminal(const std::ostream& err);

  // Shows `text` for `stage` at `fraction` (0..1) of the work.
  void Show(const std::string& stage, double fraction, const std::string& text);
  // Ends a redrawn line (before other output, and at the end).
  void EndLine();

 private:
  std::ostream& err_;
  bool enabled_;
  bool terminal_;
  bool drawn_ = false;
  std::string last_text_;
  std::string last_stage_;
  double last_fraction_ = -1.0;
  int64_t last_line_ns_ = 0;
};

// The library's Progress callbacks as a bar: stage, bar, percentage, items,
// elapsed time and ETA.
class ProgressBar {
 public:
  // `enabled` false prints nothing (e.g. with --json or --quiet).
  ProgressBar(std::ostream& err, bool enabled);
  // Shows the progress; returns true (never cancels).
  bool Update(const Progress& progress);
  // Ends the line.
  void Finish();
  ProgressCallback AsCallback();

 private:
  ProgressLine line_;
  int64_t start_ns_;
  int last_permille_ = -1;
};

// "[#####.....]" of `width` characters for `fraction` (0..1).
std::string BarText(double fraction, int width = 30);

}  // namespace reenact::cli
