#include "server/metrics/server_metrics.h"

#include <string>
#include <vector>

namespace reenact::server {
namespace {

constexpr char kLimitRefusals[] = "reenact_limit_refusals_total";
constexpr char kLimitRefusalsHelp[] =
    "Requests refused because they exceeded a limit (name or notes too long, a frame set that "
    "fails validation, every job slot busy), by limit.";

metrics::Counter& LimitCounter(absl::string_view limit) {
  return metrics::DefaultRegistry().GetCounter(kLimitRefusals, kLimitRefusalsHelp,
                                               {{"limit", std::string(limit)}});
}

}  // namespace

metrics::Counter& IngestFrameSetsCounter() {
  static metrics::Counter& counter = metrics::DefaultRegistry().GetCounter(
      "reenact_ingest_frame_sets_total", "Frame sets accepted by the Ingest service.");
  return counter;
}

metrics::Counter& IngestBytesCounter() {
  static metrics::Counter& counter = metrics::DefaultRegistry().GetCounter(
      "reenact_ingest_bytes_total", "Serialized bytes of the frame sets accepted by Ingest.");
  return counter;
}

metrics::Gauge& TakesOpenGauge() {
  static metrics::Gauge& gauge = metrics::DefaultRegistry().GetGauge(
      "reenact_takes_open", "Takes being recorded (open for ingest) now.");
  return gauge;
}

void LimitHit(absl::string_view limit, log::Fields fields, absl::string_view msg) {
  LimitCounter(limit).Increment();
  std::vector<log::Field> all;
  all.reserve(fields.size() + 1);
  all.push_back({"limit", limit});
  all.insert(all.end(), fields.begin(), fields.end());
  log::Warn("limit_hit", all, msg);
}

void RegisterServerCounters() {
  IngestFrameSetsCounter();
  IngestBytesCounter();
  TakesOpenGauge();
  for (const char* limit : {"name_bytes", "notes_bytes", "frame_set", "job_slots"}) {
    LimitCounter(limit);
  }
}

}  // namespace reenact::server
