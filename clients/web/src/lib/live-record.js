// What the live preview has received: frames, their latencies and its
// parts, reconnects and how it ended (window.reenactLive()). Times in
// milliseconds; instants in Unix nanoseconds as the server sends them.

// Error codes after which the live preview stops for good: asking again
// gives the same answer.
export const FINAL_CODES = new Set([
  'NOT_FOUND',
  'INVALID_ARGUMENT',
  'PERMISSION_DENIED',
  'UNAUTHENTICATED',
  'FAILED_PRECONDITION',
]);

export function createLiveRecord() {
  return {
    frames_received: 0,
    first_frame_index: null,
    last_frame_index: null,
    latencies_ms: [],
    // Its parts: on the server (FrameSet arrived -> fitted frame published)
    // and from the server's send to this page's handler.
    server_ms: [],
    delivery_ms: [],
    fit_ms: [],
    reconnects: 0,
    ended: false,
    end: null,
  };
}

// `x` rounded to a tenth.
export function roundTenth(x) {
  return Math.round(x * 10) / 10;
}

// A frame message `m` ({frame_index, arrived_unix_ns, published_unix_ns,
// sent_unix_ns, fit_ms}) received at `nowMs` (Unix milliseconds): adds it
// to `record`, sets m.latency_ms (capture to now) and returns it.
export function recordFrame(record, m, nowMs) {
  const latency = nowMs - Number(m.arrived_unix_ns) / 1e6;
  m.latency_ms = latency;
  record.frames_received += 1;
  if (record.first_frame_index === null) record.first_frame_index = m.frame_index;
  record.last_frame_index = m.frame_index;
  record.latencies_ms.push(roundTenth(latency));
  record.server_ms.push(Math.round((Number(m.published_unix_ns) - Number(m.arrived_unix_ns)) / 1e5) / 10);
  record.fit_ms.push(roundTenth(Number(m.fit_ms)));
  record.delivery_ms.push(roundTenth(nowMs - Number(m.sent_unix_ns) / 1e6));
  return latency;
}

// A copy of `record` whose arrays the caller may keep.
export function snapshotRecord(record) {
  return {
    ...record,
    latencies_ms: [...record.latencies_ms],
    server_ms: [...record.server_ms],
    delivery_ms: [...record.delivery_ms],
    fit_ms: [...record.fit_ms],
  };
}

// The `p`-th percentile (nearest rank) of `values`; null for none.
export function percentile(values, p) {
  if (!values.length) return null;
  const sorted = [...values].sort((a, b) => a - b);
  const i = Math.min(sorted.length - 1, Math.max(0, Math.ceil((p / 100) * sorted.length) - 1));
  return sorted[i];
}

// The wait before reconnect attempt `failures` (1, 2, ...): 0.5 s doubling
// to at most 10 s.
export function reconnectDelayMs(failures) {
  return Math.min(10000, 500 * 2 ** Math.min(failures - 1, 5));
}

// Whether a job in `state` may still send frames.
export function jobIsActive(state) {
  return state === 'running' || state === 'queued';
}

// The line shown when the preview ends: why, the server's message and the
// frames shown.
export function endText(m, framesReceived) {
  const why = m.reason === 'take_complete' ? 'The take is complete' : `The live preview ended (${m.reason})`;
  return `${why}${m.message ? `: ${m.message}` : ''}. ${framesReceived} frames shown here.`;
}

// The line shown when the WebSocket closes: how, with its close code.
export function closeText(opened, code, reason) {
  return opened
    ? `The connection dropped (code ${code}${reason ? `, ${reason}` : ''}).`
    : 'The live connection could not be opened.';
}

// The frame readout: the latest index, frames received and reconnects.
export function framesReadout(frameIndex, record) {
  const reconnects = record.reconnects ? ` · ${record.reconnects} reconnects` : '';
  return `frame ${frameIndex} · ${record.frames_received} received${reconnects}`;
}
