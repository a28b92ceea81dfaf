// The counters reenact-server keeps as events happen (in the process's
// metrics registry, common/metrics/metrics.h), named in one place so that
// every hook in the store, the RPC handlers and the job queue counts into the
// same series. The states an operator scrapes (jobs by state, disk free) are
// read at scrape time by the server itself (server.cc).
//
//   reenact_ingest_frame_sets_total   frame sets accepted by Ingest
//   reenact_ingest_bytes_total        their serialized bytes
//   reenact_takes_open                takes being recorded now
//   reenact_limit_refusals_total{limit}  requests refused by a limit
//     (limit: name_bytes, notes_bytes, frame_set, job_slots)
#pragma once

#include "absl/strings/string_view.h"
#include "common/log/log.h"
#include "common/metrics/metrics.h"

namespace reenact::server {

metrics::Counter& IngestFrameSetsCounter();
metrics::Counter& IngestBytesCounter();
metrics::Gauge& TakesOpenGauge();
// Counts one refusal by `limit` and logs it: event limit_hit (warn) with
// the field limit, then `fields`, and `msg` (the refusal's text).
void LimitHit(absl::string_view limit, log::Fields fields, absl::string_view msg);

// Makes every series above exist (at 0), so that a scrape before the first
// event shows them.
void RegisterServerCounters();

}  // namespace reenact::server
