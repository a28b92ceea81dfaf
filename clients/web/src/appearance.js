// Per-frame appearance in the player: a body reenactment's texture video
// (GET /api/v1/reenactments/{id}/appearance.mp4; frame i is the atlas of
// instant i, in model.glb's texture layout) drawn on the body in place of
// the static atlas, on the animation's frame at every speed, on seek and
// while paused. Where there is none, where the browser cannot decode it, or
// where its length is not the animation's, the static atlas stays and the
// note says why.
//
// Sync: while the animation plays, the video plays at the same speed, aimed
// ahead by the browser's measured presentation delay; small drift is caught
// up by its playback rate, a jump (loop, seek) by a seek. While paused, each
// frame change seeks it. requestVideoFrameCallback says which frame is on
// screen (`shownFrame`).

import { LinearFilter, SRGBColorSpace, VideoTexture } from 'three';
import { apiFetch, describeError, getToken } from './api.js';
import {
  catchUpRate,
  frameOfVideoTime,
  lengthMismatch,
  loopOffset,
  needsSeek,
  nextLead,
  seekFrameAhead,
  videoTimeOfFrame,
} from './lib/appearance-sync.js';

// H.264 High profile in MP4: what the server's encoder writes.
export const APPEARANCE_TYPE = 'video/mp4; codecs="avc1.640028"';

// Meshes whose material shows the static atlas (the body's skinned mesh).
function atlasMaterials(model) {
  const materials = [];
  model.traverse((o) => {
    if (!o.isSkinnedMesh || !o.material) return;
    for (const m of Array.isArray(o.material) ? o.material : [o.material]) {
      if (m.map) materials.push(m);
    }
  });
  return materials;
}

export class Appearance {
  // `model`: the loaded glb scene; `frames`, `fps`: the animation's;
  // `onChange()`: called when the note or the drawn frame changes (the
  // stage redraws).
  constructor({ id, model, frames, fps, onChange }) {
    this.id = id;
    this.frames = frames;
    this.fps = fps;
    this.onChange = onChange || (() => {});
    this.materials = atlasMaterials(model);
    this.atlases = this.materials.map((m) => m.map);
    this.mode = 'atlas'; // 'loading' | 'video' | 'atlas'
    this.note = '';
    this.video = null;
    this.texture = null;
    this.shownFrame = -1;
    this.wantedFrame = 0;
    this.requestedFrame = -1;
    this.seekStartedMs = 0;
    this.seekMs = 0;
    this.seeks = 0;
    this.presented = 0;
    this.ticks = 0;
    this.inStep = 0;
    this.lead = 0;
    this.leadSpeed = 1;
    this.offsetSum = 0;
  }

  // Whether this model has a body atlas a video could replace.
  get applies() {
    return this.materials.length > 0;
  }

  // Fetches the video and swaps it in once its first frame is decoded;
  // resolves when it is drawn or the fallback is settled (never rejects).
  async load() {
    if (!this.applies) return;
    this.mode = 'loading';
    const path = `/api/v1/reenactments/${encodeURIComponent(this.id)}/appearance.mp4`;
    const unavailable = await this.unavailableReason(path);
    if (unavailable) {
      this.fallBack(unavailable);
      return;
    }
    const video = createVideo(path);
    this.video = video;
    try {
      await firstFrame(video);
    } catch (e) {
      this.fallBack(`the video does not play (${e.message})`);
      return;
    }
    const mismatch = lengthMismatch(video.duration, this.frames, this.fps);
    if (mismatch) {
      this.fallBack(mismatch);
      return;
    }
    this.watchVideo(video);
    this.useVideo(video);
  }

  // Why the video cannot be shown here (the browser cannot decode it, the
  // server has none), or '' when it can be tried.
  async unavailableReason(path) {
    const probe = document.createElement('video');
    if (!probe.canPlayType(APPEARANCE_TYPE)) return 'this browser cannot decode H.264 video';
    try {
      // Its existence and the server's reason when it has none, before the
      // media element (which reports no reasons) streams it.
      await apiFetch(path, { headers: { Range: 'bytes=0-0' } });
    } catch (e) {
      return e.status === 404 ? 'this reenactment has no appearance video' : describeError(e);
    }
    return '';
  }

  // Falls back when the video stops decoding; follows the animation after
  // a seek.
  watchVideo(video) {
    video.addEventListener('error', () => {
      const error = video.error;
      this.fallBack(`the video stopped decoding (${(error && error.message) || 'media error'})`);
    });
    video.addEventListener('seeked', () => {
      this.seekMs = performance.now() - this.seekStartedMs;
      // The animation moved on while it sought: follow it.
      if (video.paused && this.requestedFrame !== this.wantedFrame) this.seek(this.wantedFrame);
    });
  }

  // Draws `video` on the body in place of the static atlas.
  useVideo(video) {
    const texture = new VideoTexture(video);
    const atlas = this.atlases[0];
    texture.flipY = atlas.flipY;
    texture.colorSpace = SRGBColorSpace;
    texture.wrapS = atlas.wrapS;
    texture.wrapT = atlas.wrapT;
    texture.minFilter = LinearFilter;
    texture.magFilter = LinearFilter;
    texture.generateMipmaps = false;
    this.texture = texture;
    for (const m of this.materials) {
      m.map = texture;
      m.needsUpdate = true;
    }
    this.mode = 'video';
    this.note = '';
    this.watchFrames();
    this.seek(this.wantedFrame);
    this.onChange();
  }

  watchFrames() {
    const video = this.video;
    if (!video || typeof video.requestVideoFrameCallback !== 'function') return;
    const onFrame = (now, metadata) => {
      if (this.video !== video) return;
      this.shownFrame = Math.min(this.frames - 1, frameOfVideoTime(metadata.mediaTime, this.fps));
      ++this.presented;
      this.onChange();
      video.requestVideoFrameCallback(onFrame);
    };
    video.requestVideoFrameCallback(onFrame);
  }

  seek(frame) {
    const video = this.video;
    if (!video) return;
    this.seekStartedMs = performance.now();
    ++this.seeks;
    this.requestedFrame = Math.min(Math.max(frame, 0), this.frames - 1);
    video.currentTime = videoTimeOfFrame(this.requestedFrame, this.fps);
  }

  // Keeps the video on the animation: `time` (s) and `frame` (its nearest
  // instant) now, `playing`, at `speed`.
  sync(time, frame, playing, speed) {
    this.wantedFrame = frame;
    const video = this.video;
    if (this.mode !== 'video' || !video) return;
    if (playing) this.follow(video, time, frame, speed);
    else this.hold(video, frame);
  }

  // Paused: the video paused on the animation's frame.
  hold(video, frame) {
    if (!video.paused) {
      video.pause();
      this.requestedFrame = -1;
    }
    if (!video.seeking && frame !== this.requestedFrame) this.seek(frame);
  }

  // Playing: the video plays along, its drift caught up by its rate, a
  // jump by a seek.
  follow(video, time, frame, speed) {
    // What is drawn now: the animation's frame and the video's last
    // presented one.
    ++this.ticks;
    const offset = this.shownFrame >= 0 ? loopOffset(this.shownFrame, frame, this.frames) : 0;
    if (this.shownFrame >= 0 && Math.abs(offset) <= 1) ++this.inStep;
    this.offsetSum += Math.abs(offset);
    if (video.paused) video.play().catch(() => {});
    if (video.seeking) return;
    this.updateLead(offset, speed);
    const wanted = time + 0.5 / this.fps + this.lead;
    const error = wanted - video.currentTime;
    if (needsSeek(error, speed)) {
      // A jump (a loop, a seek, a stall): seek, aimed ahead by the seek's
      // own time.
      this.seek(seekFrameAhead(wanted, this.seekMs, speed, this.fps, this.frames));
      return;
    }
    // Small drift: caught up by the rate, without a seek's stall.
    const rate = catchUpRate(speed, error);
    if (Math.abs(video.playbackRate - rate) > 0.01) video.playbackRate = rate;
  }

  // The frame on screen trails the video's clock by the browser's
  // presentation delay (media seconds: wall delay x speed), so the video is
  // aimed ahead of the animation by `lead`, which integrates the offset
  // between the frame drawn and the animation's until it averages zero.
  updateLead(offset, speed) {
    if (speed !== this.leadSpeed) {
      this.lead *= speed / this.leadSpeed;
      this.leadSpeed = speed;
    }
    if (this.shownFrame >= 0) this.lead = nextLead(this.lead, offset, speed, this.fps);
  }

  // The static atlas again, saying why.
  fallBack(why) {
    if (!this.applies) return;
    for (let i = 0; i < this.materials.length; ++i) {
      this.materials[i].map = this.atlases[i];
      this.materials[i].needsUpdate = true;
    }
    if (this.texture) this.texture.dispose();
    this.texture = null;
    this.release();
    this.mode = 'atlas';
    this.note = `Static texture: ${why}.`;
    this.onChange();
  }

  // What the tests read (window.reenactPlayer().appearance).
  stats() {
    return {
      mode: this.mode,
      note: this.note,
      shown_frame: this.shownFrame,
      wanted_frame: this.wantedFrame,
      presented: this.presented,
      ticks: this.ticks,
      in_step: this.inStep,
      offset_sum: this.offsetSum,
      lead_s: this.lead,
      seeks: this.seeks,
      seek_ms: this.seekMs,
    };
  }

  release() {
    if (this.video) {
      this.video.removeAttribute('src');
      this.video.load();
      this.video.remove();
    }
    this.video = null;
  }
}

// A hidden, muted video element for `path`, in the document (unseen), so
// that the browser presents its frames (requestVideoFrameCallback) as it
// does for a visible one.
function createVideo(path) {
  const video = document.createElement('video');
  video.muted = true;
  video.playsInline = true;
  video.preload = 'auto';
  video.crossOrigin = 'anonymous';
  video.className = 'appearance-video';
  video.setAttribute('aria-hidden', 'true');
  document.body.append(video);
  const token = getToken();
  // The media element cannot send headers: the token goes as
  // access_token (RFC 6750 2.3), as on the live preview's WebSocket.
  video.src = token ? `${path}?access_token=${encodeURIComponent(token)}` : path;
  return video;
}

// Resolves when `video` has decoded its first frame; rejects on a media
// error.
function firstFrame(video) {
  return new Promise((resolve, reject) => {
    video.addEventListener('loadeddata', resolve, { once: true });
    video.addEventListener(
      'error',
      () => reject(new Error(video.error ? video.error.message || `media error ${video.error.code}` : 'media error')),
      { once: true },
    );
  });
}
