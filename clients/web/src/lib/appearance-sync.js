// The arithmetic that keeps the per-frame appearance video on the
// animation: which video time shows which frame, whether a video fits the
// animation, and how far ahead to aim it while both play. Times in
// seconds; frames are indices of instants at `fps`.

// The video time that shows instant `frame` (its frames are 1/fps long and
// start at frame / fps): the middle of the frame, clear of rounding.
export function videoTimeOfFrame(frame, fps) {
  return (frame + 0.5) / fps;
}

// The video frame shown at media time `seconds` (a frame's start time).
export function frameOfVideoTime(seconds, fps) {
  return Math.max(0, Math.round(seconds * fps));
}

// Why a video of `duration` seconds cannot be the appearance of `frames`
// instants at `fps`, or '' when it can (within half a frame).
export function lengthMismatch(duration, frames, fps) {
  if (!(fps > 0) || !(frames > 0)) return 'the animation has no frame rate';
  if (!Number.isFinite(duration) || duration <= 0) return 'the video has no length';
  const videoFrames = duration * fps;
  if (Math.abs(videoFrames - frames) <= 0.5) return '';
  return `the video has ${Math.round(videoFrames)} frames for the animation's ${frames}`;
}

// The signed offset of the video frame `shown` from the animation's `frame`
// on a loop of `frames` (the shorter way round).
export function loopOffset(shown, frame, frames) {
  let d = shown - frame;
  if (d > frames / 2) d -= frames;
  if (d < -frames / 2) d += frames;
  return d;
}

// The lead (media seconds the video is aimed ahead of the animation) after
// one tick that saw the drawn frame `offset` frames from the animation's:
// it moves a twentieth of a frame against the offset, within
// [0, 0.5 x speed].
export function nextLead(lead, offset, speed, fps) {
  const step = Math.min(1, Math.max(-1, -offset));
  return Math.min(0.5 * speed, Math.max(0, lead + (0.05 * step) / fps));
}

// Whether the video, `error` seconds behind where it should be, is too far
// off to catch up by its rate (a loop, a seek, a stall): then it seeks.
export function needsSeek(error, speed) {
  return Math.abs(error) > 0.1 + 0.25 * speed;
}

// The frame to seek to for video time `wanted`, aimed ahead by the last
// seek's duration `seekMs` (at most 0.25 s) at `speed`; at most the last
// of `frames`.
export function seekFrameAhead(wanted, seekMs, speed, fps, frames) {
  const ahead = Math.min(0.25, seekMs / 1000) * speed;
  return Math.min(frames - 1, Math.round((wanted + ahead) * fps - 0.5));
}

// The playback rate that closes a small drift of `error` seconds: the
// speed scaled by 1 + 2 x error, within [0.5, 1.5] of it.
export function catchUpRate(speed, error) {
  return speed * Math.min(1.5, Math.max(0.5, 1 + 2 * error));
}
