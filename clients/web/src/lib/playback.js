// The player's state: where it is on the timeline, whether it plays, at
// what speed, and the A-B loop. Only state: the page draws it.

import {
  advanceTime,
  clampSpeed,
  loopFromLink,
  loopWithEnd,
  loopWithStart,
  nearestFrame,
  stepFrameIndex,
} from './timeline.js';

export class Playback {
  constructor() {
    this.time = 0;
    this.playing = false;
    this.speed = 1;
    // The A-B loop's ends (seconds; null: the timeline's).
    this.a = null;
    this.b = null;
    this.frame = 0;
    this.frames = 0;
    this.times = new Float64Array(0);
    // The timeline runs from the first frame's instant to the last's
    // (duration); the reenactment lasts frames / fps (length, as on its
    // library card).
    this.duration = 0;
    this.length = 0;
  }

  // The loaded model's frame `times`, `duration` and `length` (seconds).
  setTimeline({ times, duration, length }) {
    this.times = times;
    this.frames = times.length;
    this.duration = duration;
    this.length = length;
  }

  // Puts the clock at `time` (within the timeline) and finds its frame.
  seek(time) {
    this.time = Math.min(Math.max(time, 0), this.duration);
    this.frame = nearestFrame(this.times, this.time);
  }

  // Moves the clock on by `dt` seconds of wall time while playing; whether
  // it moved.
  advance(dt) {
    if (!this.playing) return false;
    this.seek(advanceTime(this.time, dt, this.speed, this.a, this.b, this.duration));
    return true;
  }

  // Plays (when there is something to play) or pauses; whether it plays.
  setPlaying(on) {
    this.playing = !!on && this.duration > 0;
    return this.playing;
  }

  // The play button: pauses, or plays on (from the start when paused at
  // the end without a loop).
  togglePlaying() {
    if (!this.playing && this.a === null && this.time >= this.duration) this.time = 0;
    return this.setPlaying(!this.playing);
  }

  // Sets the speed within its bounds; returns it.
  setSpeed(speed) {
    this.speed = clampSpeed(speed);
    return this.speed;
  }

  // The instant `delta` frames from the current one.
  frameTimeAfter(delta) {
    return this.times[stepFrameIndex(this.frame, delta, this.frames)];
  }

  markLoopStart() {
    Object.assign(this, loopWithStart(this, this.time));
  }

  markLoopEnd() {
    Object.assign(this, loopWithEnd(this, this.time));
  }

  clearLoop() {
    this.a = null;
    this.b = null;
  }

  // The deep link's loop (&a, &b: null when absent).
  setLoopFromLink(a, b) {
    Object.assign(this, loopFromLink(a, b, this.duration));
  }

  // Where a deep link without &t starts: at the loop's start, else 0.
  startTime(t) {
    if (t !== null) return t;
    return this.a !== null ? this.a : 0;
  }
}
