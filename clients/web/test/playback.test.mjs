import assert from 'node:assert/strict';
import { test } from 'node:test';
import { Playback } from '../src/lib/playback.js';
import { assertNear } from '../testing/near.mjs';

// A playback of `frames` instants at `fps`.
function loaded(frames = 31, fps = 10) {
  const p = new Playback();
  const times = Float64Array.from({ length: frames }, (_, i) => i / fps);
  p.setTimeline({ times, duration: (frames - 1) / fps, length: frames / fps });
  return p;
}

test('a new playback is paused at 0 with nothing to play', () => {
  const p = new Playback();
  assert.equal(p.time, 0);
  assert.equal(p.frames, 0);
  assert.equal(p.speed, 1);
  assert.equal(p.setPlaying(true), false);
});

test('seek clamps to the timeline and finds the nearest frame', () => {
  const p = loaded();
  p.seek(1.23);
  assertNear(p.time, 1.23, 1e-12, 'time (s)');
  assert.equal(p.frame, 12);
  p.seek(-5);
  assert.equal(p.time, 0);
  assert.equal(p.frame, 0);
  p.seek(99);
  assertNear(p.time, 3, 1e-12, 'time at the end (s)');
  assert.equal(p.frame, 30);
});

test('advance moves the clock only while playing, at its speed', () => {
  const p = loaded();
  assert.equal(p.advance(0.5), false);
  assert.equal(p.time, 0);
  p.setPlaying(true);
  p.setSpeed(0.5);
  assert.equal(p.advance(0.5), true);
  assertNear(p.time, 0.25, 1e-12, 'time (s)');
  assert.equal(p.frame, 2);
});

test('advance wraps within the A-B loop', () => {
  const p = loaded();
  p.seek(1);
  p.markLoopStart();
  p.seek(2);
  p.markLoopEnd();
  p.setPlaying(true);
  p.advance(0.3);
  assertNear(p.time, 1.3, 1e-9, 'time after wrapping (s)');
});

test('the play button restarts from 0 when paused at the end without a loop', () => {
  const p = loaded();
  p.seek(3);
  assert.equal(p.togglePlaying(), true);
  assert.equal(p.time, 0);
  assert.equal(p.togglePlaying(), false);
  p.seek(3);
  p.a = 1;
  p.togglePlaying();
  assertNear(p.time, 3, 1e-12, 'time with a loop set (s)');
});

test('setSpeed clamps to 0.25x-2x', () => {
  const p = loaded();
  assert.equal(p.setSpeed(5), 2);
  assert.equal(p.setSpeed(0), 0.25);
  assert.equal(p.setSpeed(1.5), 1.5);
});

test('frameTimeAfter steps a frame within the timeline', () => {
  const p = loaded();
  p.seek(1.04);
  assertNear(p.frameTimeAfter(1), 1.1, 1e-12, 'next frame (s)');
  assertNear(p.frameTimeAfter(-1), 0.9, 1e-12, 'previous frame (s)');
  p.seek(0);
  assert.equal(p.frameTimeAfter(-1), 0);
});

test('loop marks drop an end on the wrong side; clearLoop drops both', () => {
  const p = loaded();
  p.seek(2);
  p.markLoopEnd();
  p.seek(2.5);
  p.markLoopStart();
  assert.equal(p.a, 2.5);
  assert.equal(p.b, null);
  p.clearLoop();
  assert.equal(p.a, null);
});

test('a deep link starts at &t, else at the loop start, else at 0', () => {
  const p = loaded();
  p.setLoopFromLink(1.5, 9);
  assert.equal(p.a, 1.5);
  assertNear(p.b, 3, 1e-12, 'B clamped to the duration (s)');
  assert.equal(p.startTime(null), 1.5);
  assert.equal(p.startTime(0.5), 0.5);
  p.clearLoop();
  assert.equal(p.startTime(null), 0);
});
