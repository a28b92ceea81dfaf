// The live preview's WebSocket (/api/v1/jobs/JOBID/follow): frames, meshes
// and the end as they come; reconnects with backoff while the job runs.

import { describeError, webSocketUrl } from '../api.js';
import { isAccessError } from '../lib/errors.js';
import { FINAL_CODES, closeText, jobIsActive, reconnectDelayMs } from '../lib/live-record.js';
import { setState, setStatus, showError } from '../ui.js';

export class LiveConnection {
  // `record`: the page's live record (reconnects, ended, end); `lookUp()`:
  // resolves the job or null; `on`: {frame(m), mesh(buffer), end(m),
  // over()} (over: the job finished while disconnected).
  constructor({ jobId, record, lookUp, on }) {
    Object.assign(this, { jobId, record, lookUp, on });
    this.socket = null;
    this.failures = 0;
    this.retryTimer = 0;
    this.meshBytes = null; // the mesh message announcing the next binary one
    this.messages = {
      frame: (m) => on.frame(m),
      mesh: (m) => {
        this.meshBytes = m.bytes;
      },
      end: (m) => on.end(m),
      error: (m) => this.serverError(m),
    };
  }

  connect() {
    clearTimeout(this.retryTimer);
    let ws;
    try {
      ws = new WebSocket(webSocketUrl(`/api/v1/jobs/${encodeURIComponent(this.jobId)}/follow`));
    } catch (e) {
      showError(`Cannot open the live connection: ${e.message || e}`);
      return;
    }
    this.socket = ws;
    ws.binaryType = 'arraybuffer';
    let opened = false;
    ws.addEventListener('open', () => {
      opened = true;
      this.failures = 0;
      setStatus(this.record.reconnects ? 'Reconnected; waiting for frames…' : 'Connected; waiting for frames…');
    });
    ws.addEventListener('message', (event) => this.receive(event.data));
    ws.addEventListener('close', (event) => {
      if (this.socket !== ws) return;
      this.socket = null;
      if (this.record.ended) return;
      this.scheduleReconnect(closeText(opened, event.code, event.reason));
    });
  }

  // Ends the preview for good (the server refused this token).
  stop() {
    if (this.socket) this.socket.close();
    this.record.ended = true;
  }

  // A message: binary, the mesh a mesh message announced; text, a JSON
  // message by its type (others are ignored).
  receive(data) {
    if (typeof data !== 'string') {
      if (this.meshBytes !== null) {
        this.meshBytes = null;
        this.on.mesh(data);
      }
      return;
    }
    let m;
    try {
      m = JSON.parse(data);
    } catch {
      return;
    }
    const handle = this.messages[m.type];
    if (handle) handle(m);
  }

  // The server's error message: final codes end the preview.
  serverError(m) {
    if (!FINAL_CODES.has(m.code)) {
      setStatus(`The server reports ${m.code}: ${m.message}`);
      return;
    }
    this.record.ended = true;
    this.record.end = m;
    showError(`${m.code}: ${m.message}`);
  }

  reconnect() {
    this.record.reconnects += 1;
    this.connect();
  }

  // After a drop (`what` says how): waits, asks whether the job still
  // runs, then connects again.
  scheduleReconnect(what) {
    ++this.failures;
    const delay = reconnectDelayMs(this.failures);
    setStatus(`${what} Reconnecting in ${(delay / 1000).toFixed(1)} s…`);
    this.retryTimer = setTimeout(() => this.retry(), delay);
  }

  async retry() {
    let job;
    try {
      job = await this.lookUp();
    } catch (e) {
      this.lookUpFailed(e);
      return;
    }
    if (job && !jobIsActive(job.state)) {
      this.record.ended = true;
      setStatus(`The job is ${job.state}; the live preview is over.`);
      setState('ready');
      this.on.over();
      return;
    }
    if (!job) {
      showError(`No job ${this.jobId} on this server.`);
      return;
    }
    this.reconnect();
  }

  // The job could not be looked up: a refused token ends it; otherwise it
  // keeps trying, with a button to try now.
  lookUpFailed(e) {
    if (isAccessError(e)) {
      showError(e);
      return;
    }
    showError(`The live connection is lost. ${describeError(e)} Retrying…`, {
      retry: () => {
        this.failures = 0;
        clearTimeout(this.retryTimer);
        this.reconnect();
      },
      retryLabel: 'Reconnect now',
    });
    this.scheduleReconnect('The server cannot be reached.');
  }
}
