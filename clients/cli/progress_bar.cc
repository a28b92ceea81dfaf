#include "clients/cli/progress_bar.h"

#include <cstdio>
#include <ostream>

#include "common/base/time.h"

namespace reenact::cli {

ProgressBar::ProgressBar(std::ostream& err, bool enabled)
    : err_(err), enabled_(enabled), start_ns_(SteadyNowNs()) {}

bool ProgressBar::Update(const Progress& progress) {
  if (!enabled_) return true;
  const int permille = static_cast<int>(progress.fraction * 1000.0);
  if (permille == last_permille_) return true;
  last_permille_ = permille;
  constexpr int kWidth = 30;
  const int filled = static_cast<int>(progress.fraction * kWidth + 0.5);
  const double elapsed_s = NsToSeconds(SteadyNowNs() - start_ns_);
  const double eta_s = progress.fraction > 0 ? elapsed_s * (1 - progress.fraction) / progress.fraction : 0;
  char line[160];
  std::snprintf(line, sizeof(line), "\r%-12s [%s%s] %5.1f%%  %lld/%lld  %.0fs elapsed, ETA %.0fs",
                progress.stage.c_str(), std::string(filled, '#').c_str(),
                std::string(kWidth - filled, '.').c_str(), progress.fraction * 100.0,
                static_cast<long long>(progress.items_done),
                static_cast<long long>(progress.items_total), elapsed_s, eta_s);
  err_ << line << std::flush;
  drawn_ = true;
  return true;
}

void ProgressBar::Finish() {
  if (enabled_ && drawn_) err_ << "\n";
  drawn_ = false;
}

ProgressCallback ProgressBar::AsCallback() {
  return [this](const Progress& p) { return Update(p); };
}

}  // namespace reenact::cli
