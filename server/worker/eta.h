// The time a job has left, from the rate of its progress fraction: the rate
// between the oldest sample of a sliding window and the newest, and
// (1 - fraction) / rate to go.
#pragma once

#include <cstdint>
#include <deque>
#include <utility>

namespace reenact::server {

class EtaEstimator {
 public:
  // `window_s`: how far back the rate is measured, seconds (> 0).
  explicit EtaEstimator(double window_s);

  // Notes `fraction` (0..1) at steady time `now_ns` and returns the ETA,
  // seconds: 0 once the fraction is 1, -1 (unknown) while the rate over the
  // window is not positive (a first sample, or no progress).
  double Update(int64_t now_ns, double fraction);

 private:
  const int64_t window_ns_;
  // (steady ns, fraction), oldest first. Of the samples more than a window
  // before the newest only the newest is kept, so that the rate spans the
  // whole window; at least two are kept.
  std::deque<std::pair<int64_t, double>> samples_;
};

}  // namespace reenact::server
