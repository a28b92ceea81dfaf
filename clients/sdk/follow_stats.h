// Latency figures of a Follow stream (ReenactmentsClient::Follow), gathered
// frame event by frame event: what `reenact reenactments follow` and the
// live benchmark (bench/live_e2e.cc) report.
#pragma once

#include <cstdint>
#include <vector>

#include "reenact/v1/reenactments_service.pb.h"

namespace reenact::client {

// A distribution of one figure, milliseconds (zeros when empty).
struct Distribution {
  int64_t count = 0;
  double p50_ms = 0.0;
  double p95_ms = 0.0;
  double max_ms = 0.0;
  double mean_ms = 0.0;
};

// The frame's server-side latency: published - arrived, milliseconds.
double LatencyMs(const v1::FollowEvent& frame);
// The client-side delay: `received_unix_ns` (client clock) - arrived
// (server clock), milliseconds; meaningful when both clocks agree (one
// machine, or synchronised clocks).
double ReceiveDelayMs(const v1::FollowEvent& frame, int64_t received_unix_ns);

// p50/p95 by the nearest rank, max and mean of `values_ms`.
Distribution Distribute(std::vector<double> values_ms);

class FollowStats {
 public:
  // Records a frame event received at `received_unix_ns`; other events are
  // ignored.
  void Add(const v1::FollowEvent& event, int64_t received_unix_ns);

  int64_t frames() const { return static_cast<int64_t>(latency_ms_.size()); }
  Distribution latency() const { return Distribute(latency_ms_); }
  Distribution receive_delay() const { return Distribute(receive_ms_); }
  Distribution fit() const { return Distribute(fit_ms_); }
  // Frames whose latency (published - arrived) is at most `limit_ms`.
  int64_t FramesWithin(double limit_ms) const;

 private:
  std::vector<double> latency_ms_;
  std::vector<double> receive_ms_;
  std::vector<double> fit_ms_;
};

}  // namespace reenact::client
