// Small helpers for the figures reenactd reports: percentiles over samples
// and a bounded sample store, so that a daemon running for days keeps a
// fixed amount of memory for its statistics.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

namespace reenact {

// The `q`-quantile (0..1) of `samples` by the nearest-rank method; 0 when
// there are none. Takes a copy because it reorders.
inline int64_t Percentile(std::vector<int64_t> samples, double q) {
  if (samples.empty()) return 0;
  q = std::clamp(q, 0.0, 1.0);
  const size_t rank =
      static_cast<size_t>(std::llround(q * static_cast<double>(samples.size() - 1)));
  std::nth_element(samples.begin(), samples.begin() + static_cast<std::ptrdiff_t>(rank),
                   samples.end());
  return samples[rank];
}

// Keeps at most `capacity` samples: every sample until full, then a uniform
// random subset (reservoir sampling, Vitter's algorithm R). The maximum is
// tracked exactly.
class SampleReservoir {
 public:
  explicit SampleReservoir(size_t capacity = size_t{1} << 18) : capacity_(capacity) {}

  void Add(int64_t value) {
    ++count_;
    max_ = count_ == 1 ? value : std::max(max_, value);
    if (samples_.size() < capacity_) {
      samples_.push_back(value);
      return;
    }
    std::uniform_int_distribution<uint64_t> pick(0, count_ - 1);
    const uint64_t slot = pick(rng_);
    if (slot < capacity_) samples_[slot] = value;
  }
  uint64_t count() const { return count_; }
  int64_t max() const { return count_ == 0 ? 0 : max_; }
  int64_t Quantile(double q) const { return Percentile(samples_, q); }

 private:
  size_t capacity_;
  uint64_t count_ = 0;
  int64_t max_ = 0;
  std::vector<int64_t> samples_;
  std::mt19937_64 rng_{12345};
};

}  // namespace reenact
