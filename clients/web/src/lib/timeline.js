// A reenactment's timeline: its frame instants, the nearest frame to a
// time, its length, and how the clock moves through it (speed, A-B loop).
// Times in seconds.

// Speeds the player offers; others given in the address are clamped to
// [SPEED_MIN, SPEED_MAX] and added to the list.
export const SPEEDS = [0.25, 0.5, 0.75, 1, 1.25, 1.5, 2];
export const SPEED_MIN = 0.25;
export const SPEED_MAX = 2;

// The frame instants: the input times of a track with exactly frame_count
// keys; without one, the densest track's, else frame_count instants at
// fps. `clip`: {tracks: [{times}]} or null; `info`: {fps, frame_count}.
export function frameTimes(clip, info) {
  const tracks = clip ? clip.tracks : [];
  let best = null;
  for (const t of tracks) {
    if (info.frame_count > 0 && t.times.length === info.frame_count) {
      best = t.times;
      break;
    }
  }
  if (!best) {
    for (const t of tracks) if (!best || t.times.length > best.length) best = t.times;
  }
  if (best && best.length > 0 && !(info.frame_count > 0 && best.length !== info.frame_count)) {
    return Float64Array.from(best);
  }
  const n = info.frame_count || (best ? best.length : 1);
  const fps = info.fps || 30;
  return Float64Array.from({ length: n }, (_, i) => i / fps);
}

// Index of the instant in sorted `times` nearest to `t` (the earlier on a
// tie).
export function nearestFrame(times, t) {
  const n = times.length;
  if (n === 0) return 0;
  let lo = 0;
  let hi = n - 1;
  if (t <= times[0]) return 0;
  if (t >= times[hi]) return hi;
  while (hi - lo > 1) {
    const mid = (lo + hi) >> 1;
    if (times[mid] <= t) lo = mid;
    else hi = mid;
  }
  return t - times[lo] <= times[hi] - t ? lo : hi;
}

// A reenactment's length: frames / fps, as the server's duration_s (each
// frame stands for 1/fps seconds; the last one starts at (frames - 1)/fps).
// 0 when either is missing. The library's cards and the player both show
// this.
export function lengthSeconds(frames, fps) {
  const n = Number(frames);
  const f = Number(fps);
  return n > 0 && f > 0 ? n / f : 0;
}

// A listed reenactment's length: frames / fps, else the server's
// duration_s.
export function reenactmentLength(r) {
  return lengthSeconds(r.frames, r.fps) || Number(r.duration_s);
}

// The player's timeline of a loaded model: `clipDuration` (the animation
// clip's, null without one), its frame `times` and the glb's `fps` (0 when
// unknown). {frames, duration: the last instant (the timeline's end),
// length: frames / fps (as the library card says), appearanceFps: the rate
// of the per-frame appearance video}.
export function timelineOf(clipDuration, times, fps) {
  const frames = times.length;
  const duration = clipDuration !== null ? Math.max(clipDuration, times[frames - 1] || 0) : 0;
  const rate = fps || (duration > 0 && frames > 1 ? (frames - 1) / duration : 0);
  const length = lengthSeconds(frames, rate) || duration;
  const appearanceFps = fps || (duration > 0 ? (frames - 1) / duration : 30);
  return { frames, duration, length, appearanceFps };
}

// The clock `dt` seconds on from `time` at `speed`: within the A-B loop
// [a, b] when it has length (null ends: the timeline's), else around the
// whole timeline [0, duration].
export function advanceTime(time, dt, speed, a, b, duration) {
  let t = time + dt * speed;
  const start = a !== null ? a : 0;
  const end = b !== null ? b : duration;
  if (end > start) {
    if (t > end) t = start + ((t - end) % (end - start));
    if (t < start) t = start;
  } else if (t > duration) {
    t = duration > 0 ? t % duration : 0;
  }
  return t;
}

// A speed within the player's bounds.
export function clampSpeed(speed) {
  return Math.min(SPEED_MAX, Math.max(SPEED_MIN, speed));
}

// The frame index `delta` frames from `frame`, within [0, frames - 1].
export function stepFrameIndex(frame, delta, frames) {
  return Math.min(frames - 1, Math.max(0, frame + delta));
}

// The loop after "Loop start" at `time`: a B at or before it is dropped.
export function loopWithStart({ b }, time) {
  return { a: time, b: b !== null && b <= time ? null : b };
}

// The loop after "Loop end" at `time`: an A at or after it is dropped.
export function loopWithEnd({ a }, time) {
  return { a: a !== null && a >= time ? null : a, b: time };
}

// The deep link's loop (&a, &b; null when absent): A at 0 or later, B kept
// only after A and at most `duration`.
export function loopFromLink(a, b, duration) {
  const start = a !== null ? Math.max(0, a) : null;
  const end = b !== null && (start === null || b > start) ? Math.min(duration, b) : null;
  return { a: start, b: end };
}
