import assert from 'node:assert/strict';
import { test } from 'node:test';
import {
  catchUpRate,
  frameOfVideoTime,
  lengthMismatch,
  loopOffset,
  needsSeek,
  nextLead,
  seekFrameAhead,
  videoTimeOfFrame,
} from '../src/lib/appearance-sync.js';
import { assertNear } from '../testing/near.mjs';

test('a frame seeks to its middle and reads back as itself', () => {
  assertNear(videoTimeOfFrame(0, 30), 1 / 60, 1e-12, 'video time (s)');
  assertNear(videoTimeOfFrame(10, 25), 0.42, 1e-12, 'video time (s)');
  for (const fps of [24, 25, 29.97, 30, 60]) {
    for (let frame = 0; frame < 200; frame += 7) {
      // A frame's presented media time is its start: frame / fps.
      assert.equal(frameOfVideoTime(frame / fps, fps), frame);
    }
  }
  assert.equal(frameOfVideoTime(-0.1, 30), 0);
});

test('lengthMismatch allows half a frame', () => {
  assert.equal(lengthMismatch(3, 90, 30), '');
  assert.equal(lengthMismatch(3 + 0.4 / 30, 90, 30), '');
  assert.equal(lengthMismatch(3.1, 90, 30), "the video has 93 frames for the animation's 90");
  assert.equal(lengthMismatch(3, 90, 0), 'the animation has no frame rate');
  assert.equal(lengthMismatch(NaN, 90, 30), 'the video has no length');
  assert.equal(lengthMismatch(0, 90, 30), 'the video has no length');
});

test('loopOffset goes the shorter way round the loop', () => {
  assert.equal(loopOffset(5, 3, 90), 2);
  assert.equal(loopOffset(3, 5, 90), -2);
  assert.equal(loopOffset(1, 89, 90), 2);
  assert.equal(loopOffset(89, 1, 90), -2);
});

test('nextLead moves a twentieth of a frame against the offset, within [0, speed / 2]', () => {
  assertNear(nextLead(0.1, 1, 1, 20), 0.1 - 0.05 / 20, 1e-12, 'lead (s)');
  assertNear(nextLead(0.1, -3, 1, 20), 0.1 + 0.05 / 20, 1e-12, 'lead (s)');
  assertNear(nextLead(0.1, 0, 1, 20), 0.1, 1e-12, 'lead (s)');
  assert.equal(nextLead(0, 2, 1, 30), 0);
  assert.equal(nextLead(0.25, -1, 0.5, 0.1), 0.25);
});

test('a large error seeks, aimed ahead by the last seek; a small one adjusts the rate', () => {
  assert.equal(needsSeek(0.3, 1), false);
  assert.equal(needsSeek(-0.36, 1), true);
  assert.equal(needsSeek(0.5, 2), false);
  // 1 s + 0.05 s ahead at 30 fps: the frame starting at 31/30 s.
  assert.equal(seekFrameAhead(1.0, 50, 1, 30, 90), 31);
  // Aimed at most 0.25 s ahead, times the speed: 1.01 + 0.5 s.
  assert.equal(seekFrameAhead(1.01, 1000, 2, 30, 90), 45);
  assert.equal(seekFrameAhead(5, 0, 1, 30, 90), 89);
  assertNear(catchUpRate(1, 0.1), 1.2, 1e-12, 'rate');
  assertNear(catchUpRate(2, -0.1), 1.6, 1e-12, 'rate');
  assertNear(catchUpRate(1, 1), 1.5, 1e-12, 'rate at the upper bound');
  assertNear(catchUpRate(1, -1), 0.5, 1e-12, 'rate at the lower bound');
});
