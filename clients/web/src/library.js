// The library (/): the server's reenactments, newest first, each with a
// still drawn here when its card scrolls into view, and the live jobs one
// can watch. Refreshes itself; when the server is away it says so and keeps
// trying.

import { ApiError, apiJson, apiJsonAllPages } from './api.js';
import { CardGrid } from './library/cards.js';
import { createLibraryLayout, liveJobItem } from './library/view.js';
import { isAccessError } from './lib/errors.js';
import { serverLine } from './lib/format.js';
import { watchableJobs } from './lib/listing.js';
import { backgroundFromParams } from './lib/params.js';
import { clearError, setState, setStatus, showError } from './ui.js';

const REFRESH_MS = 5000;
const RETRY_MS = 3000;

// Why the live jobs cannot be listed, for the answers that leave the rest
// of the library usable; '' for others.
function jobsUnavailable(e) {
  if (!(e instanceof ApiError)) return '';
  if (e.status === 403) return "This token's role may not list jobs.";
  if (e.status === 404) return 'This server lists no jobs.';
  return '';
}

// The server's info, or null when it answers but will not say.
function serverInfo() {
  return apiJson('/api/v1/info').catch((e) => {
    if (e instanceof ApiError && e.status !== 0) return null;
    throw e;
  });
}

// The live jobs in the Live section.
async function showLiveJobs(c) {
  let jobs;
  try {
    jobs = await apiJson('/api/v1/jobs?live=1');
  } catch (e) {
    const why = jobsUnavailable(e);
    if (!why) throw e;
    c.liveNote.textContent = why;
    return;
  }
  const running = watchableJobs(jobs);
  c.liveNote.textContent = running.length ? '' : 'No live jobs right now.';
  c.liveList.replaceChildren(...running.map(liveJobItem));
}

// Fills the page from the server every REFRESH_MS; while it cannot be
// reached, says so and tries every RETRY_MS.
class LibraryRefresh {
  constructor(c) {
    this.c = c;
    this.cards = new CardGrid(c.grid, c.emptyNote);
    this.timer = 0;
    this.failures = 0;
    this.refresh = this.refresh.bind(this);
  }

  async refresh() {
    clearTimeout(this.timer);
    try {
      await this.load();
      if (this.failures > 0) setStatus('The server is back.');
      this.failures = 0;
      clearError();
      setState('ready');
      this.timer = setTimeout(this.refresh, REFRESH_MS);
    } catch (e) {
      this.failed(e);
    }
  }

  async load() {
    const [info, list] = await Promise.all([serverInfo(), apiJsonAllPages('/api/v1/reenactments', { page_size: 50 })]);
    if (info) this.c.serverLine.textContent = serverLine(info);
    this.cards.show(list);
    await showLiveJobs(this.c);
  }

  // Says why; retries unless the server refused this token.
  failed(e) {
    ++this.failures;
    showError(e, { retry: this.refresh, retryLabel: 'Retry now' });
    if (isAccessError(e)) return;
    setStatus(`Retrying every ${RETRY_MS / 1000} s (attempt ${this.failures}).`);
    this.timer = setTimeout(this.refresh, RETRY_MS);
  }
}

export function startLibrary(params) {
  document.body.classList.add('page-library');
  const bg = backgroundFromParams(params, '');
  if (bg) document.body.style.background = bg;
  setState('loading');
  const c = createLibraryLayout();
  window.reenactStats = () => ({ fps: 0, frame: 0, frames: 0, latency_ms: null });
  new LibraryRefresh(c).refresh();
}
