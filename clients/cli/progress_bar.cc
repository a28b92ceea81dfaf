#include "clients/cli/progress_bar.h"

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <iostream>
#include <ostream>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "common/base/time.h"

namespace reenact::cli {
namespace {

// Plain lines: a new one after this much progress or this long.
constexpr double kPlainFractionStep = 0.1;
constexpr int64_t kPlainPeriodNs = int64_t{5} * 1'000'000'000;

}  // namespace

ProgressLine::ProgressLine(std::ostream& err, bool enabled, bool terminal)
    : err_(err), enabled_(enabled), terminal_(terminal) {}

bool ProgressLine::IsTerminal(const std::ostream& err) {
  return &err == &std::cerr && ::isatty(STDERR_FILENO) == 1;
}

void ProgressLine::Show(const std::string& stage, double fraction, const std::string& text) {
  if (!enabled_ || text == last_text_) return;
  if (terminal_) {
    // Pad over a longer previous line.
    std::string padded = text;
    padded.resize(std::max(text.size(), last_text_.size()), ' ');
    err_ << "\r" << padded << std::flush;
    drawn_ = true;
    last_text_ = text;
    return;
  }
  const int64_t now = SteadyNowNs();
  const bool due = stage != last_stage_ || fraction >= 1.0 ||
                   fraction - last_fraction_ >= kPlainFractionStep - 1e-9 ||
                   now - last_line_ns_ >= kPlainPeriodNs;
  if (!due) return;
  err_ << text << "\n" << std::flush;
  last_text_ = text;
  last_stage_ = stage;
  last_fraction_ = fraction;
  last_line_ns_ = now;
}

void ProgressLine::EndLine() {
  if (enabled_ && drawn_) err_ << "\n";
  drawn_ = false;
  last_text_.clear();
}

std::string BarText(double fraction, int width) {
  const int filled = static_cast<int>(std::lround(std::clamp(fraction, 0.0, 1.0) * width));
  return absl::StrCat("[", std::string(filled, '#'), std::string(width - filled, '.'), "]");
}

ProgressBar::ProgressBar(std::ostream& err, bool enabled)
    : line_(err, enabled, ProgressLine::IsTerminal(err)), start_ns_(SteadyNowNs()) {}

bool ProgressBar::Update(const Progress& progress) {
  const int permille = static_cast<int>(progress.fraction * 1000.0);
  if (permille == last_permille_) return true;
  last_permille_ = permille;
  const double elapsed_s = NsToSeconds(SteadyNowNs() - start_ns_);
  const double eta_s =
      progress.fraction > 0 ? elapsed_s * (1 - progress.fraction) / progress.fraction : 0;
  line_.Show(progress.stage, progress.fraction,
             absl::StrFormat("%-12s %s %5.1f%%  %d/%d  %.0fs elapsed, ETA %.0fs", progress.stage,
                             BarText(progress.fraction), progress.fraction * 100.0,
                             progress.items_done, progress.items_total, elapsed_s, eta_s));
  return true;
}

void ProgressBar::Finish() { line_.EndLine(); }

ProgressCallback ProgressBar::AsCallback() {
  return [this](const Progress& p) { return Update(p); };
}

}  // namespace reenact::cli
