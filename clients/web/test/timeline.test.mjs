import assert from 'node:assert/strict';
import { test } from 'node:test';
import {
  advanceTime,
  clampSpeed,
  frameTimes,
  lengthSeconds,
  loopFromLink,
  loopWithEnd,
  loopWithStart,
  nearestFrame,
  reenactmentLength,
  stepFrameIndex,
  timelineOf,
} from '../src/lib/timeline.js';
import { assertNear } from '../testing/near.mjs';

const track = (times) => ({ times: Float32Array.from(times) });

test('frameTimes takes the track with exactly frame_count keys', () => {
  const clip = { tracks: [track([0, 0.5, 1, 1.5, 2]), track([0, 0.1, 0.2]), track([0, 1])] };
  const times = frameTimes(clip, { fps: 30, frame_count: 3 });
  assert.ok(times instanceof Float64Array);
  assert.equal(times.length, 3);
  assertNear(times[1], 0.1, 1e-7, 'second instant (s)');
  assertNear(times[2], 0.2, 1e-7, 'third instant (s)');
});

test('frameTimes without frame_count takes the densest track', () => {
  const clip = { tracks: [track([0, 1]), track([0, 0.25, 0.5, 0.75]), track([0])] };
  assert.deepEqual(Array.from(frameTimes(clip, { fps: 0, frame_count: 0 })), [0, 0.25, 0.5, 0.75]);
});

test('frameTimes falls back to frame_count instants at fps when no track has them', () => {
  const clip = { tracks: [track([0, 1])] };
  const times = frameTimes(clip, { fps: 4, frame_count: 5 });
  assert.deepEqual(Array.from(times), [0, 0.25, 0.5, 0.75, 1]);
});

test('frameTimes without a clip: frame_count instants at fps, 30 fps by default, one instant for nothing', () => {
  assert.deepEqual(Array.from(frameTimes(null, { fps: 10, frame_count: 3 })), [0, 0.1, 0.2]);
  const at30 = frameTimes(null, { fps: 0, frame_count: 4 });
  assertNear(at30[3], 0.1, 1e-12, 'fourth instant at 30 fps (s)');
  assert.deepEqual(Array.from(frameTimes(null, { fps: 0, frame_count: 0 })), [0]);
});

test('nearestFrame finds the nearest instant, the earlier on a tie, clamped at the ends', () => {
  const times = [0, 0.1, 0.2, 0.3];
  assert.equal(nearestFrame(times, -1), 0);
  assert.equal(nearestFrame(times, 0.04), 0);
  assert.equal(nearestFrame(times, 0.06), 1);
  assert.equal(nearestFrame(times, 0.25), 2);
  assert.equal(nearestFrame(times, 0.26), 3);
  assert.equal(nearestFrame(times, 9), 3);
  assert.equal(nearestFrame([], 1), 0);
  assert.equal(nearestFrame([0.5], 0), 0);
});

test('lengthSeconds is frames / fps, 0 when either is missing', () => {
  assertNear(lengthSeconds(90, 30), 3, 1e-12, 'length (s)');
  assertNear(lengthSeconds('45', '30'), 1.5, 1e-12, 'length from strings (s)');
  assert.equal(lengthSeconds(0, 30), 0);
  assert.equal(lengthSeconds(90, 0), 0);
  assert.equal(lengthSeconds(undefined, 30), 0);
});

test('reenactmentLength prefers frames / fps over duration_s', () => {
  assertNear(reenactmentLength({ frames: 60, fps: 30, duration_s: 1.9667 }), 2, 1e-12, 'length (s)');
  assertNear(reenactmentLength({ frames: 0, fps: 0, duration_s: '2.5' }), 2.5, 1e-12, 'duration_s (s)');
});

test('timelineOf: the duration ends at the last instant, the length is frames / fps', () => {
  const times = Float64Array.from({ length: 90 }, (_, i) => i / 30);
  const t = timelineOf(89 / 30, times, 30);
  assert.equal(t.frames, 90);
  assertNear(t.duration, 89 / 30, 1e-12, 'duration (s)');
  assertNear(t.length, 3, 1e-12, 'length (s)');
  assert.equal(t.appearanceFps, 30);
});

test('timelineOf without fps derives it from the instants', () => {
  const times = Float64Array.from({ length: 11 }, (_, i) => i / 10);
  const t = timelineOf(1, times, 0);
  assertNear(t.length, 1.1, 1e-12, 'length at the derived 10 fps (s)');
  assertNear(t.appearanceFps, 10, 1e-12, 'appearance fps');
});

test('timelineOf without a clip has no duration; one frame lasts as long as its clip', () => {
  const none = timelineOf(null, Float64Array.from([0]), 0);
  assert.equal(none.duration, 0);
  assert.equal(none.length, 0);
  assert.equal(none.appearanceFps, 30);
  const single = timelineOf(0.5, Float64Array.from([0]), 0);
  assertNear(single.length, 0.5, 1e-12, 'length of one frame without fps (s)');
});

test('advanceTime moves at speed and wraps around the whole timeline', () => {
  assertNear(advanceTime(1, 0.1, 2, null, null, 3), 1.2, 1e-12, 'time (s)');
  assertNear(advanceTime(2.9, 0.2, 1, null, null, 3), 0.1, 1e-12, 'wrapped time (s)');
  assertNear(advanceTime(3, 0, 1, null, null, 3), 3, 1e-12, 'at the end (s)');
  assert.equal(advanceTime(0, 0.1, 1, null, null, 0), 0);
});

test('advanceTime stays within the A-B loop', () => {
  assertNear(advanceTime(1.95, 0.1, 1, 1, 2, 3), 1.05, 1e-9, 'wrapped past B (s)');
  assertNear(advanceTime(0.2, 0.1, 1, 1, 2, 3), 1, 1e-12, 'before A jumps to A (s)');
  assertNear(advanceTime(1.5, 0.1, 1, 1, null, 3), 1.6, 1e-12, 'A only: up to the end (s)');
  assertNear(advanceTime(2.95, 0.1, 1, 1, null, 3), 1.05, 1e-9, 'A only: wraps to A (s)');
  assertNear(advanceTime(0.95, 0.1, 1, null, 1, 3), 0.05, 1e-9, 'B only: wraps to 0 (s)');
});

test('advanceTime with an empty loop (A at B) wraps around the whole timeline', () => {
  assertNear(advanceTime(2.95, 0.1, 1, 2, 2, 3), 0.05, 1e-9, 'time (s)');
});

test('clampSpeed and stepFrameIndex keep to their bounds', () => {
  assert.equal(clampSpeed(0.1), 0.25);
  assert.equal(clampSpeed(1.3), 1.3);
  assert.equal(clampSpeed(4), 2);
  assert.equal(stepFrameIndex(0, -1, 10), 0);
  assert.equal(stepFrameIndex(4, 1, 10), 5);
  assert.equal(stepFrameIndex(9, 1, 10), 9);
});

test('setting a loop end drops the other end when it would be on the wrong side', () => {
  assert.deepEqual(loopWithStart({ a: null, b: 2 }, 1), { a: 1, b: 2 });
  assert.deepEqual(loopWithStart({ a: null, b: 2 }, 2), { a: 2, b: null });
  assert.deepEqual(loopWithEnd({ a: 1, b: null }, 2), { a: 1, b: 2 });
  assert.deepEqual(loopWithEnd({ a: 2, b: null }, 1.5), { a: null, b: 1.5 });
});

test('loopFromLink clamps A at 0 and B at the duration, and drops B before A', () => {
  assert.deepEqual(loopFromLink(-1, 9, 3), { a: 0, b: 3 });
  assert.deepEqual(loopFromLink(2, 1, 3), { a: 2, b: null });
  assert.deepEqual(loopFromLink(null, 1, 3), { a: null, b: 1 });
  assert.deepEqual(loopFromLink(null, null, 3), { a: null, b: null });
});
