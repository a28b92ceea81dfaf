import assert from 'node:assert/strict';
import { test } from 'node:test';
import {
  cardTitle,
  formatDate,
  formatDegrees,
  formatSeconds,
  frameReadout,
  jobState,
  liveJobLine,
  loopReadout,
  methodLabel,
  reenactmentSummary,
  serverLine,
  timeReadout,
  uploadedFileName,
} from '../src/lib/format.js';

test('formatSeconds: two decimals, a dash for no number', () => {
  assert.equal(formatSeconds(1.005), '1.00');
  assert.equal(formatSeconds(2.999), '3.00');
  assert.equal(formatSeconds(0), '0.00');
  assert.equal(formatSeconds(NaN), '–');
  assert.equal(formatSeconds(Infinity), '–');
});

test('formatDate: nothing for no date', () => {
  assert.equal(formatDate(0), '');
  assert.equal(formatDate('x'), '');
  assert.equal(formatDate(-5), '');
  assert.match(formatDate('1714723200000000000'), /2024/);
});

test('methodLabel capitalises and spaces the method', () => {
  assert.equal(methodLabel('body'), 'Body');
  assert.equal(methodLabel('rigid-cylinders'), 'Rigid cylinders');
  assert.equal(methodLabel('skinned__mesh'), 'Skinned mesh');
  assert.equal(methodLabel(''), 'Reenactment');
  assert.equal(methodLabel(undefined), 'Reenactment');
});

test('uploadedFileName recognises names with a file extension', () => {
  assert.equal(uploadedFileName('ak.mcap'), 'ak.mcap');
  assert.equal(uploadedFileName(' /data/2024-05-03_squat.mkv '), '/data/2024-05-03_squat.mkv');
  assert.equal(uploadedFileName('front-kick'), '');
  assert.equal(uploadedFileName('take.v1.2'), '');
  assert.equal(uploadedFileName(null), '');
});

test('cardTitle: the method and the take, a file name without folder, extension or underscores', () => {
  assert.equal(cardTitle({ method: 'body', take_name: 'front-kick' }), 'Body · front-kick');
  assert.equal(cardTitle({ method: 'body', take_name: '/data/2024-05-03_squat.mkv' }), 'Body · 2024-05-03 squat');
  assert.equal(cardTitle({ method: 'rigid-cylinders', take_name: 'C:\\takes\\lunge.mcap' }), 'Rigid cylinders · lunge');
  assert.equal(cardTitle({ method: 'body', take_name: '', take_id: 't42' }), 'Body · take t42');
  assert.equal(cardTitle({ id: 'r9', method: '' }), 'Reenactment · r9');
});

test('the player readouts', () => {
  assert.equal(reenactmentSummary({ method: 'body', frames: 90 }, 3), 'body · 3.00 s · 90 frames');
  assert.equal(timeReadout(1.234, 3), '1.23 / 3.00 s');
  assert.equal(frameReadout(0, 90), 'frame 1 / 90');
  assert.equal(formatDegrees(-44.6), '-45°');
  assert.equal(loopReadout(null, null), '');
  assert.equal(loopReadout(1, null), 'Loop 1.00–… s');
  assert.equal(loopReadout(null, 2.5), 'Loop …–2.50 s');
  assert.equal(loopReadout(1, 2.5), 'Loop 1.00–2.50 s');
});

test('the library and live lines', () => {
  assert.equal(jobState({ state: 'running', stage: 'fitting' }), 'running · fitting');
  assert.equal(jobState({ state: 'running', stage: 'fitting' }, ', '), 'running, fitting');
  assert.equal(jobState({ state: 'queued', stage: '' }), 'queued');
  assert.equal(
    serverLine({ name: 'reenact-server', version: '0.3', tls: true, auth: false }),
    'reenact-server 0.3 · TLS',
  );
  assert.equal(serverLine({ name: 's', version: '1', tls: false, auth: true }), 's 1 · tokens');
  assert.equal(
    liveJobLine({ method: 'body', state: 'running', stage: '' }, 'today'),
    ' body · running · started today',
  );
});
