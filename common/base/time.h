// Time in Reenact is int64 nanoseconds everywhere (`stamp_ns`).
#pragma once

#include <chrono>
#include <cstdint>
#include <ctime>
#include <string>

namespace reenact {

constexpr int64_t kNanosPerSecond = 1'000'000'000;

// Nanoseconds of the steady clock (for durations and pacing).
inline int64_t SteadyNowNs() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

// Nanoseconds since the Unix epoch (for host stamps).
inline int64_t WallNowNs() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

inline double NsToSeconds(int64_t ns) { return static_cast<double>(ns) * 1e-9; }
inline int64_t SecondsToNs(double s) {
  return static_cast<int64_t>(s * 1e9 + (s >= 0 ? 0.5 : -0.5));
}

// Now as "YYYY-MM-DD HH:MM:SSZ" (UTC), for logs people read.
inline std::string UtcNowText() {
  const std::time_t seconds = static_cast<std::time_t>(WallNowNs() / kNanosPerSecond);
  std::tm tm{};
  gmtime_r(&seconds, &tm);
  char buffer[32];
  std::strftime(buffer, sizeof(buffer), "%Y-%m-%d %H:%M:%SZ", &tm);
  return buffer;
}

}  // namespace reenact
