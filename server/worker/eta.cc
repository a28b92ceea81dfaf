#include "server/worker/eta.h"

#include "common/base/time.h"

namespace reenact::server {

EtaEstimator::EtaEstimator(double window_s) : window_ns_(SecondsToNs(window_s)) {}

double EtaEstimator::Update(int64_t now_ns, double fraction) {
  samples_.emplace_back(now_ns, fraction);
  while (samples_.size() > 2 && samples_.back().first - samples_[1].first > window_ns_) {
    samples_.pop_front();
  }
  const auto& [t0, f0] = samples_.front();
  const auto& [t1, f1] = samples_.back();
  const double rate = t1 > t0 ? (f1 - f0) / NsToSeconds(t1 - t0) : 0.0;
  if (fraction >= 1.0) return 0;
  if (rate > 0) return (1.0 - fraction) / rate;
  return -1;
}

}  // namespace reenact::server
