// The library's listings: whether the reenactments changed, and which jobs
// to offer for watching.

import { jobIsActive } from './live-record.js';

// Whether `list` (reenactments, each with an id) holds exactly the ids
// that `shown` (a Map or Set keyed by id) does, in any order.
export function sameIds(list, shown) {
  return list.length === shown.size && list.every((r) => shown.has(r.id));
}

// The live jobs one can watch: running or queued.
export function watchableJobs(jobs) {
  return jobs.filter((j) => j.live && jobIsActive(j.state));
}
