// The live job as the server lists it: for the page's title, for the
// 401/403/404 answers a WebSocket cannot give, and for the link to its
// reenactment once the preview is over.

import { apiJson } from '../api.js';
import { jobState } from '../lib/format.js';
import { jobIsActive } from '../lib/live-record.js';
import { h } from '../ui.js';

// Looks up job `jobId`; titles the page by it when listed. Resolves the
// job or null.
export async function lookUpJob(jobId, { title, subtitle }) {
  const jobs = await apiJson('/api/v1/jobs');
  const job = Array.isArray(jobs) ? jobs.find((j) => j.id === jobId) : null;
  if (job) {
    title.textContent = `Live: ${job.take_id}`;
    subtitle.textContent = `${job.method} · ${jobState(job)}`;
  }
  return job;
}

// After the preview: a link to the job's reenactment, or while it goes on
// what it does (asked again every 3 s).
export async function showAfterwards(lookUp, afterwards) {
  try {
    const job = await lookUp();
    if (job && job.reenactment_id) {
      afterwards.replaceChildren(
        'The reenactment: ',
        h('a', { class: 'btn', href: `?reenactment=${encodeURIComponent(job.reenactment_id)}` }, 'Open'),
      );
      afterwards.hidden = false;
    } else if (job) {
      afterwards.textContent = `The job goes on (${jobState(job, ', ')}); its reenactment will be in the library.`;
      afterwards.hidden = false;
      if (jobIsActive(job.state)) setTimeout(() => showAfterwards(lookUp, afterwards), 3000);
    }
  } catch {
    // The page already says the preview ended.
  }
}
