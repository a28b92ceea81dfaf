import assert from 'node:assert/strict';
import { test } from 'node:test';
import {
  FINAL_CODES,
  closeText,
  createLiveRecord,
  endText,
  framesReadout,
  jobIsActive,
  percentile,
  reconnectDelayMs,
  recordFrame,
  snapshotRecord,
} from '../src/lib/live-record.js';
import { assertNear } from '../testing/near.mjs';

// A frame captured at `arrivedMs` (Unix ms), published 12.34 ms later and
// sent 0.5 ms after that.
function frame(index, arrivedMs) {
  const ns = (ms) => String(BigInt(Math.round(ms * 1e6)));
  return {
    frame_index: index,
    arrived_unix_ns: ns(arrivedMs),
    published_unix_ns: ns(arrivedMs + 12.34),
    sent_unix_ns: ns(arrivedMs + 12.84),
    fit_ms: 9.87,
  };
}

test('recordFrame measures capture to screen and its parts', () => {
  const record = createLiveRecord();
  const t0 = 1714723200000;
  const m = frame(7, t0);
  const latency = recordFrame(record, m, t0 + 40.04);
  assertNear(latency, 40.04, 1e-3, 'latency (ms)');
  assertNear(m.latency_ms, 40.04, 1e-3, 'latency on the message (ms)');
  assert.equal(record.frames_received, 1);
  assert.equal(record.first_frame_index, 7);
  assert.equal(record.last_frame_index, 7);
  assertNear(record.latencies_ms[0], 40, 1e-9, 'recorded latency, to 0.1 ms');
  assertNear(record.server_ms[0], 12.3, 1e-9, 'server part, to 0.1 ms');
  assertNear(record.fit_ms[0], 9.9, 1e-9, 'fit, to 0.1 ms');
  assertNear(record.delivery_ms[0], 27.2, 1e-9, 'delivery, to 0.1 ms');
  recordFrame(record, frame(8, t0 + 33), t0 + 70);
  assert.equal(record.first_frame_index, 7);
  assert.equal(record.last_frame_index, 8);
  assert.equal(record.frames_received, 2);
});

test('snapshotRecord copies the arrays', () => {
  const record = createLiveRecord();
  recordFrame(record, frame(1, 1000), 1010);
  const snap = snapshotRecord(record);
  recordFrame(record, frame(2, 1000), 1020);
  assert.equal(snap.latencies_ms.length, 1);
  assert.equal(snap.frames_received, 1);
  assert.equal(record.latencies_ms.length, 2);
});

test('percentile takes the nearest rank', () => {
  assert.equal(percentile([], 50), null);
  assert.equal(percentile([5], 50), 5);
  assert.equal(percentile([4, 1, 3, 2], 50), 2);
  assert.equal(percentile([1, 2, 3, 4, 5, 6, 7, 8, 9, 10], 90), 9);
  assert.equal(percentile([3, 1, 2], 100), 3);
  assert.equal(percentile([3, 1, 2], 0), 1);
});

test('reconnects back off from 0.5 s, doubling to at most 10 s', () => {
  assert.deepEqual([1, 2, 3, 4, 5, 6, 7, 20].map(reconnectDelayMs), [500, 1000, 2000, 4000, 8000, 10000, 10000, 10000]);
});

test('the live lines', () => {
  assert.equal(endText({ reason: 'take_complete', message: '' }, 90), 'The take is complete. 90 frames shown here.');
  assert.equal(
    endText({ reason: 'job_failed', message: 'no skin' }, 3),
    'The live preview ended (job_failed): no skin. 3 frames shown here.',
  );
  assert.equal(closeText(true, 1006, ''), 'The connection dropped (code 1006).');
  assert.equal(closeText(true, 1011, 'overloaded'), 'The connection dropped (code 1011, overloaded).');
  assert.equal(closeText(false, 1006, ''), 'The live connection could not be opened.');
  assert.equal(framesReadout(42, { frames_received: 40, reconnects: 0 }), 'frame 42 · 40 received');
  assert.equal(framesReadout(42, { frames_received: 40, reconnects: 2 }), 'frame 42 · 40 received · 2 reconnects');
});

test('jobs that may still send frames, and codes that end the preview', () => {
  assert.equal(jobIsActive('running'), true);
  assert.equal(jobIsActive('queued'), true);
  assert.equal(jobIsActive('succeeded'), false);
  assert.equal(FINAL_CODES.has('NOT_FOUND'), true);
  assert.equal(FINAL_CODES.has('UNAVAILABLE'), false);
});
