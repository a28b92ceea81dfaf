#include "clients/sdk/follow_stats.h"

#include <algorithm>
#include <cmath>
#include <numeric>

namespace reenact::client {
namespace {

double NsToMs(int64_t ns) { return static_cast<double>(ns) / 1e6; }

// The nearest-rank percentile of sorted values, `fraction` in [0, 1].
double Rank(const std::vector<double>& sorted, double fraction) {
  const auto n = static_cast<double>(sorted.size());
  const auto rank = static_cast<size_t>(std::max(1.0, std::ceil(fraction * n)));
  return sorted[std::min(rank, sorted.size()) - 1];
}

}  // namespace

double LatencyMs(const v1::FollowEvent& frame) {
  return NsToMs(frame.published_unix_ns() - frame.arrived_unix_ns());
}

double ReceiveDelayMs(const v1::FollowEvent& frame, int64_t received_unix_ns) {
  return NsToMs(received_unix_ns - frame.arrived_unix_ns());
}

Distribution Distribute(std::vector<double> values_ms) {
  Distribution d;
  if (values_ms.empty()) return d;
  std::sort(values_ms.begin(), values_ms.end());
  d.count = static_cast<int64_t>(values_ms.size());
  d.p50_ms = Rank(values_ms, 0.5);
  d.p95_ms = Rank(values_ms, 0.95);
  d.max_ms = values_ms.back();
  d.mean_ms = std::accumulate(values_ms.begin(), values_ms.end(), 0.0) /
              static_cast<double>(values_ms.size());
  return d;
}

void FollowStats::Add(const v1::FollowEvent& event, int64_t received_unix_ns) {
  if (!event.has_frame()) return;
  latency_ms_.push_back(LatencyMs(event));
  receive_ms_.push_back(ReceiveDelayMs(event, received_unix_ns));
  fit_ms_.push_back(event.fit_ms());
}

int64_t FollowStats::FramesWithin(double limit_ms) const {
  return std::count_if(latency_ms_.begin(), latency_ms_.end(),
                       [&](double ms) { return ms <= limit_ms; });
}

}  // namespace reenact::client
